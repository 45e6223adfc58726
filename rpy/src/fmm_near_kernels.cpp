// Near-field kernels of FmmRpy (fmm_near_kernels.hpp): portable loops that GCC vectorizes,
// compiled for AVX-512, AVX2 and the baseline and chosen by simd_level() (simd_dispatch). (An AVX-512 variant
// with 1/r from rsqrt14 + Newton steps instead of sqrt + division was measured only 6-8 % faster
// at N = 1e5: the loop is bound by its ~40 vector operations per 8 pairs, not by the divider.)
#include "fmm_near_kernels.hpp"

#include <cmath>

#include "pair_block_sum.hpp"
#include "rpy_pair_scalars.hpp"
#include "rpyfmm/core/simd_dispatch.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"

namespace rpyfmm::rpy::detail {

namespace {

// Separation d = x_i - x_q and pair scalars of gathered source q, in either radius mode.
template <bool kEqual>
[[gnu::always_inline]] inline void pair_at(std::size_t q, const double* sx, const double* sy, const double* sz,
                                           const double* sa, double xi, double yi, double zi, double ai, double& dx,
                                           double& dy, double& dz, double& f, double& gr) {
  dx = xi - sx[q];
  dy = yi - sy[q];
  dz = zi - sz[q];
  const double r2 = dx * dx + dy * dy + dz * dz;
  if constexpr (kEqual) {
    pair_scalars_equal(r2, ai, f, gr);
  } else {
    pair_scalars(r2, ai, sa[q], f, gr);
  }
}

// The fused single-rhs loop of near_pair_sum, one instance per radius mode.
template <bool kEqual>
[[gnu::always_inline]] inline void pair_sum_loop(std::size_t m, const double* sx, const double* sy, const double* sz,
                                                 const double* sa, const std::size_t* sid, const double* fx,
                                                 const double* fy, const double* fz, double xi, double yi, double zi,
                                                 double ai, std::size_t i, double u[3]) {
  double ux = 0.0, uy = 0.0, uz = 0.0;
#pragma omp simd reduction(+ : ux, uy, uz)
  for (std::size_t q = 0; q < m; ++q) {
    double dx, dy, dz, f, gr;
    pair_at<kEqual>(q, sx, sy, sz, sa, xi, yi, zi, ai, dx, dy, dz, f, gr);
    const bool self = sid[q] == i;
    f = self ? 0.0 : f;
    gr = self ? 0.0 : gr;
    const double df = gr * (dx * fx[q] + dy * fy[q] + dz * fz[q]);
    ux += f * fx[q] + df * dx;
    uy += f * fy[q] + df * dy;
    uz += f * fz[q] + df * dz;
  }
  u[0] = ux;
  u[1] = uy;
  u[2] = uz;
}

}  // namespace

// Sum over the gathered near-field sources q of M_iq f_q (times eta), the self pair
// (sid == i) excluded; equal radii ai when sa is null. Compiled for AVX-512, AVX2 and baseline
// x86-64, chosen at run time.
void near_pair_sum(std::size_t m, const double* sx, const double* sy, const double* sz, const double* sa,
                   const std::size_t* sid, const double* fx, const double* fy, const double* fz, double xi, double yi,
                   double zi, double ai, std::size_t i, double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    if (sa == nullptr) {
      pair_sum_loop<true>(m, sx, sy, sz, sa, sid, fx, fy, fz, xi, yi, zi, ai, i, u);
    } else {
      pair_sum_loop<false>(m, sx, sy, sz, sa, sid, fx, fy, fz, xi, yi, zi, ai, i, u);
    }
  });
}

namespace {

// The fused loop of near_pair_sum_symmetric, one instance per radius mode: the pair scalars of
// each pair serve both directions (i <- q returned, q <- i accumulated per source).
template <bool kEqual>
[[gnu::always_inline]] inline void pair_sum_symmetric_loop(std::size_t m, const double* sx, const double* sy,
                                                           const double* sz, const double* sa, const double* fx,
                                                           const double* fy, const double* fz, double xi, double yi,
                                                           double zi, double ai, const double fi[3], double* ux_s,
                                                           double* uy_s, double* uz_s, double u[3]) {
  const double fxi = fi[0], fyi = fi[1], fzi = fi[2];
  double ux = 0.0, uy = 0.0, uz = 0.0;
#pragma omp simd reduction(+ : ux, uy, uz)
  for (std::size_t q = 0; q < m; ++q) {
    double dx, dy, dz, f, gr;
    pair_at<kEqual>(q, sx, sy, sz, sa, xi, yi, zi, ai, dx, dy, dz, f, gr);
    const double dfq = gr * (dx * fx[q] + dy * fy[q] + dz * fz[q]);
    ux += f * fx[q] + dfq * dx;
    uy += f * fy[q] + dfq * dy;
    uz += f * fz[q] + dfq * dz;
    const double dfi = gr * (dx * fxi + dy * fyi + dz * fzi);
    ux_s[q] += f * fxi + dfi * dx;
    uy_s[q] += f * fyi + dfi * dy;
    uz_s[q] += f * fzi + dfi * dz;
  }
  u[0] = ux;
  u[1] = uy;
  u[2] = uz;
}

}  // namespace

void near_pair_sum_symmetric(std::size_t m, const double* sx, const double* sy, const double* sz, const double* sa,
                             const double* fx, const double* fy, const double* fz, double xi, double yi, double zi,
                             double ai, const double fi[3], double* ux, double* uy, double* uz, double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    if (sa == nullptr) {
      pair_sum_symmetric_loop<true>(m, sx, sy, sz, sa, fx, fy, fz, xi, yi, zi, ai, fi, ux, uy, uz, u);
    } else {
      pair_sum_symmetric_loop<false>(m, sx, sy, sz, sa, fx, fy, fz, xi, yi, zi, ai, fi, ux, uy, uz, u);
    }
  });
}

void near_accumulate_symmetric(std::size_t m, const double* dx, const double* dy, const double* dz, const double* fs,
                               const double* gr, const double* fx, const double* fy, const double* fz,
                               const double fi[3], double* ux, double* uy, double* uz, double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    apply_pair_blocks<true>(m, dx, dy, dz, fs, gr, fx, fy, fz, fi, ux, uy, uz, u[0], u[1], u[2]);
  });
}

namespace {

// The loop of near_pair_scalars, one instance per radius mode (no branch inside the loop).
template <bool kEqual>
[[gnu::always_inline]] inline void pair_scalars_loop(std::size_t m, const double* sx, const double* sy,
                                                     const double* sz, const double* sa, const std::size_t* sid,
                                                     double xi, double yi, double zi, double ai, std::size_t i,
                                                     double* dx, double* dy, double* dz, double* fs, double* gr) {
#pragma omp simd
  for (std::size_t q = 0; q < m; ++q) {
    double ddx, ddy, ddz, f, g;
    pair_at<kEqual>(q, sx, sy, sz, sa, xi, yi, zi, ai, ddx, ddy, ddz, f, g);
    const bool self = sid[q] == i;
    fs[q] = self ? 0.0 : f;
    gr[q] = self ? 0.0 : g;
    dx[q] = ddx;
    dy[q] = ddy;
    dz[q] = ddz;
  }
}

}  // namespace

// Block products (nrhs >= 2): the same pair scalars stored once per target, then one
// accumulation per right-hand side (near_accumulate).
void near_pair_scalars(std::size_t m, const double* sx, const double* sy, const double* sz, const double* sa,
                       const std::size_t* sid, double xi, double yi, double zi, double ai, std::size_t i, double* dx,
                       double* dy, double* dz, double* fs, double* gr) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    if (sa == nullptr) {
      pair_scalars_loop<true>(m, sx, sy, sz, sa, sid, xi, yi, zi, ai, i, dx, dy, dz, fs, gr);
    } else {
      pair_scalars_loop<false>(m, sx, sy, sz, sa, sid, xi, yi, zi, ai, i, dx, dy, dz, fs, gr);
    }
  });
}

void near_accumulate(std::size_t m, const double* dx, const double* dy, const double* dz, const double* fs,
                     const double* gr, const double* fx, const double* fy, const double* fz, double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY { sum_pair_blocks(m, dx, dy, dz, fs, gr, fx, fy, fz, u[0], u[1], u[2]); });
}

}  // namespace rpyfmm::rpy::detail
