// Grand-mobility pair sums (rotation_pair_sums.hpp): portable loops that GCC vectorizes, compiled
// for AVX-512, AVX2 and the baseline and chosen by simd_level(). Every regime is evaluated
// branch-free and selected, as in fmm_near_kernels.cpp.
#include "rotation_pair_sums.hpp"

#include <cmath>

#include "rpy_pair_scalars.hpp"
#include "rpyfmm/core/simd_dispatch.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::rpy::detail {
namespace {

using rpy_detail::inv_8pi;

// The loop bodies below use plain double locals only. OpenMP simd loops privatize every local
// whose address is taken (out-parameters before inlining) into per-lane arrays; arrays of doubles
// vectorize, arrays of structs do not, and a single struct local (a pair's coefficients, a
// contribution) kept the whole loop scalar.
//
// Per pair, d = x_i - x_q, e = d / r (0 for coincident points), the translational block
// f I + gr d d^T and the rotational coefficients of rpy_rotation_scalars with the couplings
// divided by r, so that they multiply d rather than e:
//   U_i += ut (T_q x d),   W_i += wf (F_q x d) + (h I + k e e^T) T_q
// (k multiplies e, not d: k / r^2 would overflow for the smallest separations accepted, ~2^-299).
// Coincident points (r2 = 0) fall in the "one inside the other" regime: h = 1 / (8 pi max(a)^3),
// and the couplings multiply d = 0. Far field r > ai + aj, any radii: c_ut = 1 / (8 pi r^2),
// h = -1 / (16 pi r^3), k = 3 / (16 pi r^3); divided by r, the couplings are c = 1 / (8 pi r^3).

// The target's radius and, for equal radii, the loop invariants 1/a and 1/(8 pi a^3).
struct TargetRadius {
  double a, inv_a, c3;
  explicit TargetRadius(double radius) : a(radius), inv_a(1.0 / radius), c3(inv_8pi / (radius * radius * radius)) {}
};

// Equal radii a.
[[gnu::always_inline]] inline void rotation_equal(double r, double inv_r, double inv_r2, const TargetRadius& ra,
                                                  double& ut, double& wf, double& h, double& k) {
  const double c = inv_8pi * inv_r2 * inv_r;
  // r <= 2a (Wajnryb et al. 2013): c_ut = r (1 - 3r/(8a)) / (16 pi a^3),
  // h = (1 - 27r/(32a) + 5r^3/(64a^3)) / (8 pi a^3), k = (9r/(32a) - 3r^3/(64a^3)) / (8 pi a^3).
  const double t = r * ra.inv_a, t3 = t * t * t;
  const double ut_near = 0.5 * ra.c3 * (1.0 - 0.375 * t);
  const double h_near = ra.c3 * (1.0 - (27.0 / 32.0) * t + (5.0 / 64.0) * t3);
  const double k_near = ra.c3 * ((9.0 / 32.0) * t - (3.0 / 64.0) * t3);
  const bool is_far = r > 2.0 * ra.a;
  ut = is_far ? c : ut_near;
  wf = ut;
  h = is_far ? -0.5 * c : h_near;
  k = is_far ? 1.5 * c : k_near;
}

// Different radii ai (target), aj (source): far, partial overlap (rotation_overlap), one inside
// the other (the inner sphere turns with the outer one: c_ut / r = 1 / (8 pi a_outer^3) towards
// the inner sphere only, h = 1 / (8 pi a_outer^3), k = 0).
[[gnu::always_inline]] inline void rotation_different(double r, double inv_r, double inv_r2, double ai, double aj,
                                                      double& ut, double& wf, double& h, double& k) {
  const double c = inv_8pi * inv_r2 * inv_r;
  const RpyRotationScalars o = rpy_detail::rotation_overlap(r, ai, aj);
  const double outer = ai > aj ? ai : aj, c_outer = inv_8pi / (outer * outer * outer);
  const double diff = ai - aj;
  const bool is_far = r > ai + aj, is_inside = r <= (diff < 0.0 ? -diff : diff);
  const double ut_in = ai < aj ? c_outer : 0.0, wf_in = aj < ai ? c_outer : 0.0;
  ut = is_far ? c : (is_inside ? ut_in : o.ut * inv_r);
  wf = is_far ? c : (is_inside ? wf_in : o.wf * inv_r);
  h = is_far ? -0.5 * c : (is_inside ? c_outer : o.h);
  k = is_far ? 1.5 * c : (is_inside ? 0.0 : o.k);
}

// The sources' arrays copied out of GrandSources into restrict-qualified locals before a loop.
struct SourceArrays {
  const double* __restrict x, * __restrict y, * __restrict z, * __restrict a;
  const double* __restrict fx, * __restrict fy, * __restrict fz, * __restrict tx, * __restrict ty, * __restrict tz;
};

[[gnu::always_inline]] inline SourceArrays arrays(const GrandSources& s) {
  return {s.x, s.y, s.z, s.a, s.fx, s.fy, s.fz, s.tx, s.ty, s.tz};
}

// Pair (target, source q): separation, direction and coefficients (the translational f, gr only
// when kTranslation).
template <bool kEqual, bool kTranslation>
[[gnu::always_inline]] inline void pair_at(const SourceArrays& s, std::size_t q, double xi, double yi, double zi,
                                           const TargetRadius& ra, double& dx, double& dy, double& dz, double& ex,
                                           double& ey, double& ez, double& f, double& gr, double& ut, double& wf,
                                           double& h, double& k) {
  dx = xi - s.x[q];
  dy = yi - s.y[q];
  dz = zi - s.z[q];
  const double r2 = dx * dx + dy * dy + dz * dz;
  const double r = std::sqrt(r2);
  const double inv_r2 = 1.0 / (r2 > 0.0 ? r2 : 1.0);
  const double inv_r = r * inv_r2;  // 0 for coincident points
  ex = dx * inv_r;
  ey = dy * inv_r;
  ez = dz * inv_r;
  f = gr = 0.0;
  if constexpr (kEqual) {
    if constexpr (kTranslation) pair_scalars_equal(r2, ra.a, f, gr);
    rotation_equal(r, inv_r, inv_r2, ra, ut, wf, h, k);
  } else {
    if constexpr (kTranslation) pair_scalars(r2, ra.a, s.a[q], f, gr);
    rotation_different(r, inv_r, inv_r2, ra.a, s.a[q], ut, wf, h, k);
  }
}

// v x d, component by component.
[[gnu::always_inline]] inline double cross_x(double vy, double vz, double dy, double dz) {
  return vy * dz - vz * dy;
}

// Adds to (ux .. wz) the velocity and angular velocity that the load (F, T) at the other end of
// the pair gives: U += f F + gr d (d . F) + ut (T x d), W += wf (F x d) + h T + k e (e . T).
// The reverse direction passes the same d and e with the couplings swapped and negated
// (grand_sum_symmetric_loop).
template <bool kTranslation = true>
[[gnu::always_inline]] inline void add_load(double dx, double dy, double dz, double ex, double ey, double ez, double f,
                                            double gr, double ut, double wf, double h, double k, double fx, double fy,
                                            double fz, double tx, double ty, double tz, double& ux, double& uy,
                                            double& uz, double& wx, double& wy, double& wz) {
  const double ket = k * (ex * tx + ey * ty + ez * tz);
  if constexpr (kTranslation) {  // without it U gets only c_ut (T x e)
    const double gdf = gr * (dx * fx + dy * fy + dz * fz);
    ux += f * fx + gdf * dx + ut * cross_x(ty, tz, dy, dz);
    uy += f * fy + gdf * dy + ut * cross_x(tz, tx, dz, dx);
    uz += f * fz + gdf * dz + ut * cross_x(tx, ty, dx, dy);
  } else {
    ux += ut * cross_x(ty, tz, dy, dz);
    uy += ut * cross_x(tz, tx, dz, dx);
    uz += ut * cross_x(tx, ty, dx, dy);
  }
  wx += wf * cross_x(fy, fz, dy, dz) + h * tx + ket * ex;
  wy += wf * cross_x(fz, fx, dz, dx) + h * ty + ket * ey;
  wz += wf * cross_x(fx, fy, dx, dy) + h * tz + ket * ez;
}

// The one-sided loop: the target's sums over all sources but itself.
template <bool kEqual, bool kTranslation>
[[gnu::always_inline]] inline void grand_sum_loop(const GrandSources& src, const GrandTarget& t, GrandSums& out) {
  const TargetRadius ra(t.a);
  const SourceArrays s = arrays(src);
  const std::size_t* __restrict id = src.id;
  const std::size_t m = src.m, self = t.i;
  const double xi = t.x, yi = t.y, zi = t.z;
  double ux = 0, uy = 0, uz = 0, wx = 0, wy = 0, wz = 0;
#pragma omp simd reduction(+ : ux, uy, uz, wx, wy, wz)
  for (std::size_t q = 0; q < m; ++q) {
    double dx, dy, dz, ex, ey, ez, f, gr, ut, wf, h, k;
    pair_at<kEqual, kTranslation>(s, q, xi, yi, zi, ra, dx, dy, dz, ex, ey, ez, f, gr, ut, wf, h, k);
    // The self pair is added by the caller: every coefficient 0 for it.
    const double keep = id[q] == self ? 0.0 : 1.0;
    add_load<kTranslation>(dx, dy, dz, ex, ey, ez, keep * f, keep * gr, keep * ut, keep * wf, keep * h, keep * k,
                           s.fx[q], s.fy[q], s.fz[q], s.tx[q], s.ty[q], s.tz[q], ux, uy, uz, wx, wy, wz);
  }
  out = {{ux, uy, uz}, {wx, wy, wz}};
}

// Both directions: q <- i sees d_qi = -d, e_qi = -e and swaps the couplings (c_ut(q, i) =
// c_wf(i, q)); the translational block and h, k are symmetric. So d -> -d leaves the tt block,
// h and k e e^T unchanged and turns ut (T x d) into -wf (T x d), wf (F x d) into -ut (F x d).
template <bool kEqual>
[[gnu::always_inline]] inline void grand_sum_symmetric_loop(const GrandSources& src, const GrandTarget& t,
                                                            const GrandAccumulators& acc, GrandSums& out) {
  const TargetRadius ra(t.a);
  const SourceArrays s = arrays(src);
  const std::size_t m = src.m;
  const double xi = t.x, yi = t.y, zi = t.z;
  const double fix = t.f[0], fiy = t.f[1], fiz = t.f[2], tix = t.t[0], tiy = t.t[1], tiz = t.t[2];
  double* __restrict aux = acc.u[0];
  double* __restrict auy = acc.u[1];
  double* __restrict auz = acc.u[2];
  double* __restrict awx = acc.w[0];
  double* __restrict awy = acc.w[1];
  double* __restrict awz = acc.w[2];
  double ux = 0, uy = 0, uz = 0, wx = 0, wy = 0, wz = 0;
#pragma omp simd reduction(+ : ux, uy, uz, wx, wy, wz)
  for (std::size_t q = 0; q < m; ++q) {
    double dx, dy, dz, ex, ey, ez, f, gr, ut, wf, h, k;
    pair_at<kEqual, true>(s, q, xi, yi, zi, ra, dx, dy, dz, ex, ey, ez, f, gr, ut, wf, h, k);
    add_load(dx, dy, dz, ex, ey, ez, f, gr, ut, wf, h, k, s.fx[q], s.fy[q], s.fz[q], s.tx[q], s.ty[q], s.tz[q], ux, uy,
             uz, wx, wy, wz);
    double bx = aux[q], by = auy[q], bz = auz[q], cx = awx[q], cy = awy[q], cz = awz[q];
    add_load(dx, dy, dz, ex, ey, ez, f, gr, -wf, -ut, h, k, fix, fiy, fiz, tix, tiy, tiz, bx, by, bz, cx, cy, cz);
    aux[q] = bx;
    auy[q] = by;
    auz[q] = bz;
    awx[q] = cx;
    awy[q] = cy;
    awz[q] = cz;
  }
  out = {{ux, uy, uz}, {wx, wy, wz}};
}

}  // namespace

void grand_pair_sum(const GrandSources& src, const GrandTarget& target, GrandSums& out) {
  simd_dispatch([src, target, &out]() RPYFMM_SIMD_BODY {
    if (src.a == nullptr) {
      grand_sum_loop<true, true>(src, target, out);
    } else {
      grand_sum_loop<false, true>(src, target, out);
    }
  });
}

void rotation_pair_sum(const GrandSources& src, const GrandTarget& target, GrandSums& out) {
  simd_dispatch([src, target, &out]() RPYFMM_SIMD_BODY {
    if (src.a == nullptr) {
      grand_sum_loop<true, false>(src, target, out);
    } else {
      grand_sum_loop<false, false>(src, target, out);
    }
  });
}

void grand_pair_sum_symmetric(const GrandSources& src, const GrandTarget& target, const GrandAccumulators& acc,
                              GrandSums& out) {
  simd_dispatch([src, target, acc, &out]() RPYFMM_SIMD_BODY {
    if (src.a == nullptr) {
      grand_sum_symmetric_loop<true>(src, target, acc, out);
    } else {
      grand_sum_symmetric_loop<false>(src, target, acc, out);
    }
  });
}

}  // namespace rpyfmm::rpy::detail
