// rpyfmm — PSE on CUDA: the host-side plan of spreading and interpolation (the window's
// parameters, the bin grid, the choice of the bin edge). Plain C++ (no CUDA types), so that the
// rule is tested without a device (tests/pse/test_pse_bin_plan.cpp); the kernels are in
// cuda_window.cuh.
#pragma once

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstddef>
#include <cstdint>

#ifdef __CUDACC__
#define RPYFMM_WINDOW_HD __host__ __device__
#else
#define RPYFMM_WINDOW_HD
#endif

namespace rpyfmm::rpy::pse::cuda_window {

constexpr int kMaxSupport = 64;
constexpr unsigned kWarp = 32;
constexpr unsigned kParticleThreads = 128;  // per-particle kernels: threads per particle
constexpr unsigned kBinThreads = 512;       // bin kernels: threads per bin (16 warps, a particle each)

/// The grid and its Gaussian window (docs/theory/pse.md).
struct WindowParams {
  int n[3];        // grid points per axis
  int P[3];        // window support per axis
  double h[3];     // grid spacing
  double inv_2s2;  // 1 / (2 sigma^2)
  double c3;       // (2 pi sigma^2)^(-3/2)
  std::size_t ng;  // n0 n1 n2
};

/// Bins of B[d] grid points per axis (the last one along an axis may be shorter) and their
/// shared-memory subgrids of m[d] = B[d] + P[d] - 1 points.
struct BinGrid {
  int B[3];
  int nb[3];
  int m[3];
  int sub;          // m0 m1 m2 (points per component)
  int max_support;  // max P[d]: the stride of each warp's window weights in shared memory
  [[nodiscard]] std::size_t bins() const { return static_cast<std::size_t>(nb[0]) * nb[1] * nb[2]; }
  /// Shared memory of the bin kernels: each warp's weights and the three subgrids, of 8 bytes per
  /// point whatever the grid's precision (the spreading sums in 64-bit fixed point,
  /// cuda_window.cuh; the interpolation's float or double subgrids fit in the same).
  [[nodiscard]] std::size_t shared_bytes() const {
    return (kBinThreads / kWarp) * 3 * static_cast<std::size_t>(max_support) * sizeof(double) +
           3 * static_cast<std::size_t>(sub) * sizeof(std::uint64_t);
  }
};

/// The bin grid of edge B (clipped to the grid) for window w.
inline BinGrid make_bin_grid(const WindowParams& w, int B) {
  BinGrid g{};
  g.sub = 1;
  g.max_support = std::max({w.P[0], w.P[1], w.P[2]});
  for (int d = 0; d < 3; ++d) {
    g.B[d] = std::min(B, w.n[d]);
    g.nb[d] = (w.n[d] + g.B[d] - 1) / g.B[d];
    g.m[d] = g.B[d] + w.P[d] - 1;
    g.sub *= g.m[d];
  }
  return g;
}

/// The bin edge for np particles: `requested` > 0 as given (0 where its subgrid exceeds
/// `max_shared` bytes); `requested` == 0 (automatic): the largest B in 16, 14, ..., 4 whose
/// subgrids fit two blocks per multiprocessor (<= 100 KiB), that gives at least two bins per
/// multiprocessor, and whose subgrids hold at most half the points of the particles' windows
/// (else atomics per particle are as cheap: few particles per bin); 0 where none does (the
/// per-particle kernels). `requested` < 0: 0.
inline int choose_bin_edge(const WindowParams& w, std::size_t np, int requested, int multiprocessors,
                           std::size_t max_shared) {
  const auto bytes = [](const BinGrid& g) { return g.shared_bytes(); };
  if (requested > 0) return bytes(make_bin_grid(w, requested)) <= max_shared ? requested : 0;
  if (requested < 0) return 0;
  const double window_points = static_cast<double>(np) * w.P[0] * w.P[1] * w.P[2];
  for (int B = 16; B >= 4; B -= 2) {
    const BinGrid g = make_bin_grid(w, B);
    const std::size_t b = bytes(g);
    if (b > std::min<std::size_t>(100 * 1024, max_shared)) continue;
    if (g.bins() < 2 * static_cast<std::size_t>(multiprocessors)) continue;
    if (static_cast<double>(g.bins()) * g.sub > 0.5 * window_points) continue;
    return B;
  }
  return 0;
}

// Fixed-point spreading (cuda_window.cuh): the arithmetic, plain so that it is tested on the host.

/// The contributions one grid point can receive: one per particle, times the number of times a
/// window covers the point along each axis (ceil(P / n): more than once only where a window is
/// longer than the grid and wraps onto itself).
inline double contributions_per_point(const WindowParams& w, std::size_t np) {
  double c = static_cast<double>(np);
  for (int d = 0; d < 3; ++d) c *= static_cast<double>((w.P[d] + w.n[d] - 1) / w.n[d]);
  return c;
}

/// The shift s of the fixed-point sums: every contribution c3 w f has |.| <= |c3| max_abs (w is
/// a product of Gaussians <= 1), a grid point sums at most `contributions` of them, and
/// 2^s |c3| max_abs contributions < 2^62, so the rounded sums stay below 2^63 (ilogb(v) + 1 >
/// log2(v) for each factor: the bound holds without forming the product, which may overflow).
/// INT_MIN where max_abs is not finite (the grid is then NaN); 0 where it is 0 (all zero).
RPYFMM_WINDOW_HD inline int fixed_point_shift(double c3, double max_abs, double contributions) {
  if (!(max_abs <= 1.7976931348623157e308)) return INT_MIN;  // inf or NaN
  if (max_abs == 0.0 || contributions == 0.0) return 0;
  const int e = (::ilogb(::fabs(c3)) + 1) + (::ilogb(max_abs) + 1) + (::ilogb(contributions) + 1);
  return 62 - e;
}

/// One contribution v in fixed point: v 2^shift rounded to the nearest integer (ties to even), as
/// a two's-complement word (the unsigned type atomicAdd takes; sums wrap as signed ones would).
RPYFMM_WINDOW_HD inline unsigned long long to_fixed(double v, int shift) {
#ifdef __CUDA_ARCH__
  return static_cast<unsigned long long>(__double2ll_rn(::scalbn(v, shift)));
#else
  return static_cast<unsigned long long>(std::llrint(std::scalbn(v, shift)));
#endif
}

/// A fixed-point sum back in floating point: q 2^-shift (NaN for shift INT_MIN).
RPYFMM_WINDOW_HD inline double from_fixed(unsigned long long q, int shift) {
  if (shift == INT_MIN) return NAN;
  return ::scalbn(static_cast<double>(static_cast<long long>(q)), -shift);
}

}  // namespace rpyfmm::rpy::pse::cuda_window
