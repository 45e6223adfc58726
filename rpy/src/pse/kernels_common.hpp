// rpyfmm — PSE per-element kernels shared by the CPU (OpenMP) and CUDA paths.
// Everything here is a pure function compiled for host and device, so that
// both back ends compute the same window weights, the same per-mode scaling,
// the same wave-space noise and the same real-space 3x3 blocks.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "rpyfmm/rpy/random.hpp"  // normal3 (Philox4x32-10), RPYFMM_HOST_DEVICE

namespace rpyfmm::rpy::pse::detail {

/// Noise streams: 1 = real-space z1 (normal3, index = particle), 2 = wave-space z2
/// (normal6, index = canonical mode: its three real parts, then its three imaginary parts).
inline constexpr std::uint32_t kStreamReal = 1;
inline constexpr std::uint32_t kStreamWave = 2;
/// The common translation of OpenPseRpy's constant part (open_pse_rpy.hpp); streams 3-5 serve the BD engine.
inline constexpr std::uint32_t kStreamOpenOffset = 6;

/// First grid index of the P-point Gaussian support of coordinate x
/// (docs/theory/pse.md): every grid point closer than P h / 2 is covered.
RPYFMM_HOST_DEVICE inline long window_start(double x, double h, int P) {
  const double u = x / h;
  if (P % 2 == 0) return static_cast<long>(std::floor(u)) - P / 2 + 1;
  return static_cast<long>(std::floor(u + 0.5)) - (P - 1) / 2;
}

/// One-dimensional Gaussian weights exp(-(x_l - x)^2 / (2 sigma^2)) on the
/// support (unwrapped distances); returns the wrapped first index in [0, n).
RPYFMM_HOST_DEVICE inline int window_weights(double x, double h, int P, int n, double inv_2s2, double* w) {
  const long s = window_start(x, h, P);
  for (int l = 0; l < P; ++l) {
    const double d = static_cast<double>(s + l) * h - x;
    w[l] = std::exp(-d * d * inv_2s2);
  }
  long sw = s % n;
  if (sw < 0) sw += n;
  return static_cast<int>(sw);
}

/// s mod n in [0, n): one comparison for the starts of wrapped positions (-P < s < n + P),
/// the division only beyond.
inline int wrap_index(long s, int n) {
  long sw = s;
  if (sw < 0) {
    sw += n;
  } else if (sw >= n) {
    sw -= n;
  }
  if (sw < 0 || sw >= n) {
    sw = s % n;
    if (sw < 0) sw += n;
  }
  return static_cast<int>(sw);
}

/// The recurrence of window_weights_recurrence (below) from the offset d0 = x_s - x of the
/// window's first point: w[l] = exp(-(d0 + l h)^2 inv_2s2), l < P.
inline void window_weights_from_offset(double d0, double h, int P, double inv_2s2, const double* tail, double* w) {
  const double step = std::exp(-2.0 * d0 * h * inv_2s2);
  double g = std::exp(-d0 * d0 * inv_2s2);
  for (int l = 0; l < P; ++l) {
    w[l] = g * tail[l];
    g *= step;
  }
}

/// The recurrence's tail[l] = exp(-l^2 h^2 inv_2s2), l < P (the same for every particle).
inline std::vector<double> window_tail(double h, int P, double inv_2s2) {
  std::vector<double> tail(static_cast<std::size_t>(P));
  for (int l = 0; l < P; ++l) {
    const double lh = l * h;
    tail[static_cast<std::size_t>(l)] = std::exp(-lh * lh * inv_2s2);
  }
  return tail;
}

/// window_weights by the fast Gaussian gridding recurrence (Greengard & Lee, SIAM Rev. 46
/// (2004) 443, Sec. 3): with d_0 = x_s - x, exp(-(d_0 + l h)^2 a) = exp(-d_0^2 a)
/// exp(-2 d_0 h a)^l exp(-l^2 h^2 a), two exponentials per axis instead of P; `tail[l]` =
/// exp(-l^2 h^2 a) (the same for every particle). Relative difference from window_weights
/// ~P ulps (the powers by repeated products). Host only: the CUDA kernels keep window_weights.
/// WaveGrid::set_positions does the same three steps in two passes (starts and offsets in input
/// order, weights in tile order); this one-call form is what the tests compare.
inline int window_weights_recurrence(double x, double h, int P, int n, double inv_2s2, const double* tail, double* w) {
  const long s = window_start(x, h, P);
  window_weights_from_offset(static_cast<double>(s) * h - x, h, P, inv_2s2, tail, w);
  return wrap_index(s, n);
}

/// Geometry of the r2c half spectrum [ix][iy][iz], iz = 0..nz/2.
struct ModeGeometry {
  int n[3];                 ///< grid points per direction
  int nzh;                  ///< nz / 2 + 1
  double two_pi_L[3];       ///< 2 pi / L_d
  std::size_t modes;        ///< nx * ny * nzh
  std::size_t comp_stride;  ///< reals between components of the spectrum (2 * modes)
};

/// Signed wave number index of grid index i in a dimension of size n.
RPYFMM_HOST_DEVICE inline int signed_index(int i, int n) {
  return 2 * i < n ? i : i - n;
}

/// Full-grid linear index `lin` of mode (ix, iy, iz) and the representative `rep` of the
/// pair {k, -k}: the smaller of lin and the index of -k ((n - i) mod n per axis). The wave
/// noise of both modes is drawn under rep's key, so that z(-k) = conj(z(k)).
RPYFMM_HOST_DEVICE inline void mode_pair(int ix, int iy, int iz, const ModeGeometry& g, std::uint64_t& lin,
                                         std::uint64_t& rep) {
  const std::uint64_t nx = static_cast<std::uint64_t>(g.n[0]);
  const std::uint64_t ny = static_cast<std::uint64_t>(g.n[1]);
  const std::uint64_t nz = static_cast<std::uint64_t>(g.n[2]);
  lin = (static_cast<std::uint64_t>(ix) * ny + static_cast<std::uint64_t>(iy)) * nz + static_cast<std::uint64_t>(iz);
  const std::uint64_t px = ix == 0 ? 0 : nx - static_cast<std::uint64_t>(ix);
  const std::uint64_t py = iy == 0 ? 0 : ny - static_cast<std::uint64_t>(iy);
  const std::uint64_t pz = iz == 0 ? 0 : nz - static_cast<std::uint64_t>(iz);
  const std::uint64_t partner = (px * ny + py) * nz + pz;
  rep = lin < partner ? lin : partner;
}

/// Scales one half-spectrum mode (ix, iy, iz), linear index idx = (ix ny + iy) nzh + iz,
/// in place ([PSE] eqs. 19 and 21; docs/theory/pse.md):
///   Uh = c(k) P_k Fh + noise_factor sqrt(c(k)) P_k z(k),  noise_factor = noise_scale / sqrt(dV)
/// with c(k) = sg(k)/(eta Ng) (zero at k = 0 and on Nyquist planes), P_k = I - khat khat,
/// z(k) complex Gaussian with E[z z^H] = I and z(-k) = conj(z(k)). `z` (null: no noise) holds
/// normal6(seed, step, kStreamWave, rep) of the mode's pair (mode_pair): real parts z[0..2],
/// imaginary parts z[3..5], conjugated when the mode is not the representative. So r2c and
/// c2c layouts, CPU and GPU produce the same field. `spec` holds 3 complex components
/// (re, im interleaved) `comp_stride` reals apart; Real = float for single-precision wave grids
/// (PseOptions::wave_precision), the arithmetic is double either way. Noise = float holds
/// normal6f's values instead (the noise of single-precision grids).
template <class Real, class Noise>
RPYFMM_HOST_DEVICE inline void scale_mode_with(int ix, int iy, int iz, std::size_t idx, const ModeGeometry& g,
                                               const double* ck, Real* spec, bool deterministic, const Noise* z,
                                               bool representative, double noise_factor) {
  Real* s0 = spec + 2 * idx;
  Real* s1 = s0 + g.comp_stride;
  Real* s2 = s1 + g.comp_stride;
  const double c = ck[idx];
  if (c == 0.0) {
    s0[0] = s0[1] = s1[0] = s1[1] = s2[0] = s2[1] = Real(0);
    return;
  }
  const double k0 = g.two_pi_L[0] * signed_index(ix, g.n[0]);
  const double k1 = g.two_pi_L[1] * signed_index(iy, g.n[1]);
  const double k2 = g.two_pi_L[2] * iz;
  const double inv_k2 = 1.0 / (k0 * k0 + k1 * k1 + k2 * k2);
  double re[3] = {0.0, 0.0, 0.0};
  double im[3] = {0.0, 0.0, 0.0};
  if (deterministic) {
    re[0] = c * s0[0];
    re[1] = c * s1[0];
    re[2] = c * s2[0];
    im[0] = c * s0[1];
    im[1] = c * s1[1];
    im[2] = c * s2[1];
  }
  if (z != nullptr) {
    // z = (a + i b)/sqrt(2): E|z_c|^2 = 1 per component; conjugate off the representative.
    const double amp = noise_factor * std::sqrt(c) * 0.70710678118654752440;
    const double sgn = representative ? amp : -amp;
    for (int d = 0; d < 3; ++d) {
      re[d] += amp * z[d];
      im[d] += sgn * z[3 + d];
    }
  }
  // Projection I - k k^T / k^2, applied to the real and imaginary parts separately.
  const double pr = (k0 * re[0] + k1 * re[1] + k2 * re[2]) * inv_k2;
  const double pi = (k0 * im[0] + k1 * im[1] + k2 * im[2]) * inv_k2;
  s0[0] = static_cast<Real>(re[0] - k0 * pr);
  s0[1] = static_cast<Real>(im[0] - k0 * pi);
  s1[0] = static_cast<Real>(re[1] - k1 * pr);
  s1[1] = static_cast<Real>(im[1] - k1 * pi);
  s2[0] = static_cast<Real>(re[2] - k2 * pr);
  s2[1] = static_cast<Real>(im[2] - k2 * pi);
}

/// (ix, iy, iz) of linear half-spectrum index idx = (ix ny + iy) nzh + iz.
RPYFMM_HOST_DEVICE inline void half_spectrum_mode(std::size_t idx, const ModeGeometry& g, int& ix, int& iy, int& iz) {
  iz = static_cast<int>(idx % static_cast<std::size_t>(g.nzh));
  const std::size_t rest = idx / static_cast<std::size_t>(g.nzh);
  iy = static_cast<int>(rest % static_cast<std::size_t>(g.n[1]));
  ix = static_cast<int>(rest / static_cast<std::size_t>(g.n[1]));
}

/// The wave-space noise of mode (ix, iy, iz), drawn by one GPU thread per mode as the CPU draws
/// lines of modes with fill_normal6: normal6f (Real = float) or normal6 of the mode pair's
/// representative under (seed, step, kStreamWave). Returns whether the mode is its pair's
/// representative.
template <class Real>
RPYFMM_HOST_DEVICE inline bool draw_mode_noise(int ix, int iy, int iz, const ModeGeometry& g, std::uint64_t seed,
                                               std::uint64_t step, Real z[6]) {
  std::uint64_t lin, rep;
  mode_pair(ix, iy, iz, g, lin, rep);
  if constexpr (sizeof(Real) == sizeof(float)) {
    normal6f(seed, step, kStreamWave, rep, z);
  } else {
    normal6(seed, step, kStreamWave, rep, z);
  }
  return lin == rep;
}

/// scale_mode_with for linear half-spectrum index idx, drawing the mode's noise itself
/// (one GPU thread per mode; the CPU draws lines of modes at once with fill_normal6):
/// normal6f for single-precision grids (Real = float), normal6 for double ones.
template <class Real>
RPYFMM_HOST_DEVICE inline void scale_mode(std::size_t idx, const ModeGeometry& g, const double* ck, Real* spec,
                                          bool deterministic, bool noise, std::uint64_t seed, std::uint64_t step,
                                          double noise_factor) {
  int ix, iy, iz;
  half_spectrum_mode(idx, g, ix, iy, iz);
  Real z[6];
  const bool representative = noise ? draw_mode_noise(ix, iy, iz, g, seed, step, z) : true;
  scale_mode_with(ix, iy, iz, idx, g, ck, spec, deterministic, noise ? z : nullptr, representative, noise_factor);
}

/// Minimum-image displacement component (valid for |d| < 1.5 L). The nearest integer is
/// (y + 1.5 2^52) - 1.5 2^52 (round-half-even, as nearbyint in the default rounding mode,
/// exact for |y| < 2^51): inline on every target, where nearbyint is a libm call on
/// baseline x86-64 (no SSE4.1 round instruction).
RPYFMM_HOST_DEVICE inline double minimum_image(double d, double L, double inv_L) {
  const double round_magic = 6755399441055744.0;
  return d - L * ((d * inv_L + round_magic) - round_magic);
}

/// Linear table lookup: per cell j the tuple (F_j, G_j, F_{j+1}, G_{j+1}).
RPYFMM_HOST_DEVICE inline void table_fg(const double* table, double inv_dr, double r, double& f, double& g) {
  double t = r * inv_dr;
  const auto j = static_cast<std::size_t>(t);
  t -= static_cast<double>(j);
  const double* e = table + 4 * j;
  f = e[0] + t * (e[2] - e[0]);
  g = e[1] + t * (e[3] - e[1]);
}

/// u += [F (I - rhat rhat) + G rhat rhat] f for displacement d = (dx, dy, dz), r = |d| > 0.
RPYFMM_HOST_DEVICE inline void pair_block_add(double dx, double dy, double dz, double r, double F, double G,
                                              const double* f, double* u) {
  const double inv_r = 1.0 / r;
  const double ex = dx * inv_r;
  const double ey = dy * inv_r;
  const double ez = dz * inv_r;
  const double proj = (G - F) * (ex * f[0] + ey * f[1] + ez * f[2]);
  u[0] += F * f[0] + proj * ex;
  u[1] += F * f[1] + proj * ey;
  u[2] += F * f[2] + proj * ez;
}

}  // namespace rpyfmm::rpy::pse::detail
