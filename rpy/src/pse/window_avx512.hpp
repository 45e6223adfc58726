// rpyfmm — PSE spreading and interpolation of one particle's window with AVX-512 masked
// vectors ([PSE] eq. 19: D and D^-1). Private.
//
// A window is P_x P_y lines of P_z <= 8 points along z, in at most two runs on the periodic
// grid ([z0, z0 + len0) and [0, P_z - len0)): each run of a line is one masked 8-lane load,
// FMA and (spreading) masked store per component (512-bit for double, 256-bit for float
// grids), instead of a scalar or 2-lane loop whose length is known only at run time. Masked-out lanes are neither read
// nor written, so the tile colouring of WaveSpace::spread still keeps threads apart. Results differ from the portable
// loops by rounding only (fused multiply-adds, another summation order).
#pragma once

#include <cstddef>

namespace rpyfmm::rpy::pse::detail {

/// True when the kernels below may run for a support of Pz points along z: compiled in (GCC,
/// x86-64), the CPU has AVX-512F and VL (the 256-bit runs of single-precision grids),
/// simd_level() is SimdLevel::avx512, and Pz <= 8.
bool avx512_window_kernels(int Pz) noexcept;

/// One particle's z runs: the first starts at grid index z0 and has len0 points (1 ... Pz);
/// the rest (Pz - len0 points) wrap to index 0 of the same line.
struct WindowZ {
  std::size_t z0;
  int len0;
  int Pz;
};

/// g_c[xline[a] + yline[b] + z] += wx[a] wy[b] wz[l] f[c] over the window, c = 0, 1, 2.
void spread_window_avx512(double* g0, double* g1, double* g2, const std::size_t* xline, const std::size_t* yline,
                          int Px, int Py, WindowZ z, const double* wx, const double* wy, const double* wz,
                          const double f[3]);

/// u[c] += sum_ab wx[a] wy[b] sum_l wz[l] g_c[xline[a] + yline[b] + z_l], c = 0, 1, 2.
void gather_window_avx512(const double* g0, const double* g1, const double* g2, const std::size_t* xline,
                          const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx, const double* wy,
                          const double* wz, double u[3]);

/// The same on single-precision grids (PseOptions::wave_precision): weights and sums in double,
/// grid values loaded and (spreading) stored as float; spreading adds wxy (wz f) in float.
void spread_window_avx512(float* g0, float* g1, float* g2, const std::size_t* xline, const std::size_t* yline, int Px,
                          int Py, WindowZ z, const double* wx, const double* wy, const double* wz, const double f[3]);
void gather_window_avx512(const float* g0, const float* g1, const float* g2, const std::size_t* xline,
                          const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx, const double* wy,
                          const double* wz, double u[3]);

}  // namespace rpyfmm::rpy::pse::detail
