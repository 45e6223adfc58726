// rpyfmm — PSE wave-space scaling of a whole line of modes (B of [PSE] eq. 19 and its square
// root for the noise, eq. 21): kernels_common.hpp's scale_mode_with for every iz of a line (ix, iy) at once,
// written as one branch-free loop over iz that the compiler vectorizes (AVX-512, AVX2 or
// portable, chosen at run time). The CPU wave space calls this; the GPU keeps one thread per
// mode (scale_mode). Private.
#pragma once

#include <cstddef>
#include <cstdint>

#include "kernels_common.hpp"

namespace rpyfmm::rpy::pse::detail {

/// One line's modes base ... base + nzh - 1, base = (ix n_y + iy) nzh, scaled in place in
/// `spec` (layout of scale_mode_with). With noise (z non-null): value c of the line's mode iz at
/// z[c * z_stride + iz] (normal6 for double grids, normal6f for float ones, as in
/// scale_mode_with), and sign[iz] = +1 when the mode is its pair's representative, -1 when its
/// noise is the conjugate (a Real array, not flags: a char array keeps GCC 12 from vectorizing
/// the loop).
template <class Real>
struct ModeLine {
  int ix = 0;
  int iy = 0;
  const double* ck = nullptr;  ///< the whole spectrum's c(k) table
  Real* spec = nullptr;        ///< the whole spectrum
  bool deterministic = false;  ///< scale the spectrum (false: overwrite it with noise only)
  const Real* z = nullptr;
  std::size_t z_stride = 0;
  const Real* sign = nullptr;
  double noise_factor = 0.0;
};

/// mode_pair for iz = 0 ... nzh - 1 of the line (ix, iy): rep[iz] = the key of the mode's noise
/// (its pair's representative), sign[iz] = +1 if the mode is the representative, else -1 (the
/// ModeLine's sign).
void line_noise_keys(const ModeGeometry& g, int ix, int iy, std::uint64_t* rep, double* sign);
void line_noise_keys(const ModeGeometry& g, int ix, int iy, std::uint64_t* rep, float* sign);

/// scale_mode_with(ix, iy, iz, ...) for iz = 0 ... nzh - 1: the same operations per mode (values
/// equal up to contraction into fused multiply-adds).
void scale_line(const ModeGeometry& g, const ModeLine<double>& line);
void scale_line(const ModeGeometry& g, const ModeLine<float>& line);

}  // namespace rpyfmm::rpy::pse::detail
