// rpyfmm — PSE spreading and interpolation of one particle's window with AVX2 masked vectors
// ([PSE] eq. 19: D and D^-1), for CPUs without AVX-512 (window_avx512.hpp there). Private.
//
// The same scheme as the AVX-512 kernels: each z run of a window line (at most 8 points, in at
// most two runs on the periodic grid) is a masked load, FMA and (spreading) masked store per
// component: two 4-lane halves on double grids, one 8-lane vector on float grids. Masked-out
// lanes are neither read nor written (vmaskmov), so tile colouring still keeps threads apart.
// Results differ from the portable loops by rounding only.
#pragma once

#include <cstddef>

#include "window_avx512.hpp"  // WindowZ

namespace rpyfmm::rpy::pse::detail {

/// True when the kernels below may run for a support of Pz points along z: compiled in (GCC,
/// x86-64), simd_level() is at least SimdLevel::avx2, and Pz <= 8. (WaveSpace prefers the
/// AVX-512 kernels where those run.) The same switch serves the AVX2 line scaling
/// (scale_line.hpp) and the AVX2 candidate filter of the real-space list build.
bool avx2_window_kernels(int Pz) noexcept;

/// g_c[xline[a] + yline[b] + z] += wx[a] wy[b] wz[l] f[c] over the window, c = 0, 1, 2.
void spread_window_avx2(double* g0, double* g1, double* g2, const std::size_t* xline, const std::size_t* yline, int Px,
                        int Py, WindowZ z, const double* wx, const double* wy, const double* wz, const double f[3]);
void spread_window_avx2(float* g0, float* g1, float* g2, const std::size_t* xline, const std::size_t* yline, int Px,
                        int Py, WindowZ z, const double* wx, const double* wy, const double* wz, const double f[3]);

/// u[c] += sum_ab wx[a] wy[b] sum_l wz[l] g_c[xline[a] + yline[b] + z_l], c = 0, 1, 2 (sums in double).
void gather_window_avx2(const double* g0, const double* g1, const double* g2, const std::size_t* xline,
                        const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx, const double* wy,
                        const double* wz, double u[3]);
void gather_window_avx2(const float* g0, const float* g1, const float* g2, const std::size_t* xline,
                        const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx, const double* wy,
                        const double* wz, double u[3]);

}  // namespace rpyfmm::rpy::pse::detail
