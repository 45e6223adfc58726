// Rotational pair sums (rotation_pair_sums.hpp): portable loops
// that GCC vectorizes, compiled for AVX-512, AVX2 and the baseline and chosen by simd_level().
// Every regime is evaluated branch-free and selected, as in fmm_near_kernels.cpp.
#include "rotation_pair_sums.hpp"

#include <cmath>

#include "rpyfmm/core/simd_dispatch.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::rpy::detail {
namespace {

using rpy_detail::inv_8pi;

// The coefficients of rpy_rotation_scalars with the couplings divided by r, so that they multiply
// the separation d rather than e = d / r: ut_i += ut (T_q x d), wf_i += wf (F_q x d),
// rr_i += (h I + k e e^T) T_q (k multiplies e, not d: k / r^2 would overflow for the smallest
// separations accepted, ~2^-299). Coincident points (r2 = 0) fall in the "one inside the other"
// regime: h = 1 / (8 pi max(a)^3), and the couplings multiply d = 0.
struct PairCoefficients {
  double ut, wf, h, k;
};

// Far field r > ai + aj, any radii: c_ut = 1 / (8 pi r^2), h = -1 / (16 pi r^3), k = 3 / (16 pi r^3).
[[gnu::always_inline]] inline PairCoefficients far_coefficients(double inv_r, double inv_r2) {
  const double c = inv_8pi * inv_r2 * inv_r;
  return {c, c, -0.5 * c, 1.5 * c};
}

// Equal radii a.
[[gnu::always_inline]] inline PairCoefficients pair_coefficients_equal(double r, double inv_r, double inv_r2,
                                                                       double a) {
  const PairCoefficients far = far_coefficients(inv_r, inv_r2);
  // r <= 2a (Wajnryb et al. 2013): c_ut = r (1 - 3r/(8a)) / (16 pi a^3),
  // h = (1 - 27r/(32a) + 5r^3/(64a^3)) / (8 pi a^3), k = (9r/(32a) - 3r^3/(64a^3)) / (8 pi a^3).
  const double inv_a = 1.0 / a, c3 = inv_8pi * inv_a * inv_a * inv_a, t = r * inv_a, t3 = t * t * t;
  const double ut_near = 0.5 * c3 * (1.0 - 0.375 * t);
  const double h_near = c3 * (1.0 - (27.0 / 32.0) * t + (5.0 / 64.0) * t3);
  const double k_near = c3 * ((9.0 / 32.0) * t - (3.0 / 64.0) * t3);
  const bool is_far = r > 2.0 * a;
  return {is_far ? far.ut : ut_near, is_far ? far.wf : ut_near, is_far ? far.h : h_near, is_far ? far.k : k_near};
}

// Different radii ai (target), aj (source): far, partial overlap (rotation_overlap), one inside
// the other (the inner sphere turns with the outer one: c_ut / r = 1 / (8 pi a_outer^3) towards
// the inner sphere only, h = 1 / (8 pi a_outer^3), k = 0).
[[gnu::always_inline]] inline PairCoefficients pair_coefficients(double r, double inv_r, double inv_r2, double ai,
                                                                 double aj) {
  const PairCoefficients far = far_coefficients(inv_r, inv_r2);
  const RpyRotationScalars o = rpy_detail::rotation_overlap(r, ai, aj);
  const PairCoefficients overlap{o.ut * inv_r, o.wf * inv_r, o.h, o.k};
  const double outer = ai > aj ? ai : aj, c_outer = inv_8pi / (outer * outer * outer);
  const PairCoefficients inside{ai < aj ? c_outer : 0.0, aj < ai ? c_outer : 0.0, c_outer, 0.0};
  const double diff = ai - aj;
  const bool is_far = r > ai + aj, is_inside = r <= (diff < 0.0 ? -diff : diff);
  const auto pick = [&](double f, double ov, double in) { return is_far ? f : (is_inside ? in : ov); };
  return {pick(far.ut, overlap.ut, inside.ut), pick(far.wf, overlap.wf, inside.wf), pick(far.h, overlap.h, inside.h),
          pick(far.k, overlap.k, inside.k)};
}

// One pair: the separation d = x_i - x_q, the direction e = d / r (0 for coincident points) and
// the coefficients.
struct PairGeometry {
  double dx, dy, dz, ex, ey, ez;
  PairCoefficients c;
};

template <bool kEqual>
[[gnu::always_inline]] inline PairGeometry pair_at(const RotationSources& s, std::size_t q, const RotationTarget& t) {
  PairGeometry g;
  g.dx = t.x - s.x[q];
  g.dy = t.y - s.y[q];
  g.dz = t.z - s.z[q];
  const double r2 = g.dx * g.dx + g.dy * g.dy + g.dz * g.dz;
  const double r = std::sqrt(r2);
  const double inv_r2 = 1.0 / (r2 > 0.0 ? r2 : 1.0);
  const double inv_r = r * inv_r2;  // 0 for coincident points
  g.ex = g.dx * inv_r;
  g.ey = g.dy * inv_r;
  g.ez = g.dz * inv_r;
  if constexpr (kEqual) {
    g.c = pair_coefficients_equal(r, inv_r, inv_r2, t.a);
  } else {
    g.c = pair_coefficients(r, inv_r, inv_r2, t.a, s.a[q]);
  }
  return g;
}

// v x d, component by component.
[[gnu::always_inline]] inline double cross_x(double vy, double vz, double dy, double dz) {
  return vy * dz - vz * dy;
}

// The one-sided loop: the target's three sums over all sources but itself.
template <bool kEqual>
[[gnu::always_inline]] inline void rotation_sum_loop(const RotationSources& s, const RotationTarget& t,
                                                     RotationSums& out) {
  double ux = 0, uy = 0, uz = 0, fx = 0, fy = 0, fz = 0, rx = 0, ry = 0, rz = 0;
#pragma omp simd reduction(+ : ux, uy, uz, fx, fy, fz, rx, ry, rz)
  for (std::size_t q = 0; q < s.m; ++q) {
    PairGeometry g = pair_at<kEqual>(s, q, t);
    const double on = s.id[q] == t.i ? 0.0 : 1.0;  // the self pair is added by the caller
    const double tqx = s.tx[q], tqy = s.ty[q], tqz = s.tz[q], fqx = s.fx[q], fqy = s.fy[q], fqz = s.fz[q];
    const double ut = on * g.c.ut, wf = on * g.c.wf, h = on * g.c.h;
    ux += ut * cross_x(tqy, tqz, g.dy, g.dz);
    uy += ut * cross_x(tqz, tqx, g.dz, g.dx);
    uz += ut * cross_x(tqx, tqy, g.dx, g.dy);
    fx += wf * cross_x(fqy, fqz, g.dy, g.dz);
    fy += wf * cross_x(fqz, fqx, g.dz, g.dx);
    fz += wf * cross_x(fqx, fqy, g.dx, g.dy);
    const double ket = on * g.c.k * (g.ex * tqx + g.ey * tqy + g.ez * tqz);
    rx += h * tqx + ket * g.ex;
    ry += h * tqy + ket * g.ey;
    rz += h * tqz + ket * g.ez;
  }
  out = {{ux, uy, uz}, {fx, fy, fz}, {rx, ry, rz}};
}

// Both directions: q <- i sees d_qi = -d and swaps the couplings (c_ut(q, i) = c_wf(i, q)).
template <bool kEqual>
[[gnu::always_inline]] inline void rotation_sum_symmetric_loop(const RotationSources& s, const RotationTarget& t,
                                                               const RotationAccumulators& acc, RotationSums& out) {
  const double fix = t.f[0], fiy = t.f[1], fiz = t.f[2], tix = t.t[0], tiy = t.t[1], tiz = t.t[2];
  double* __restrict aux = acc.ut[0];
  double* __restrict auy = acc.ut[1];
  double* __restrict auz = acc.ut[2];
  double* __restrict afx = acc.wf[0];
  double* __restrict afy = acc.wf[1];
  double* __restrict afz = acc.wf[2];
  double* __restrict arx = acc.rr[0];
  double* __restrict ary = acc.rr[1];
  double* __restrict arz = acc.rr[2];
  double ux = 0, uy = 0, uz = 0, fx = 0, fy = 0, fz = 0, rx = 0, ry = 0, rz = 0;
#pragma omp simd reduction(+ : ux, uy, uz, fx, fy, fz, rx, ry, rz)
  for (std::size_t q = 0; q < s.m; ++q) {
    const PairGeometry g = pair_at<kEqual>(s, q, t);
    const PairCoefficients& c = g.c;
    const double tqx = s.tx[q], tqy = s.ty[q], tqz = s.tz[q], fqx = s.fx[q], fqy = s.fy[q], fqz = s.fz[q];
    ux += c.ut * cross_x(tqy, tqz, g.dy, g.dz);
    uy += c.ut * cross_x(tqz, tqx, g.dz, g.dx);
    uz += c.ut * cross_x(tqx, tqy, g.dx, g.dy);
    fx += c.wf * cross_x(fqy, fqz, g.dy, g.dz);
    fy += c.wf * cross_x(fqz, fqx, g.dz, g.dx);
    fz += c.wf * cross_x(fqx, fqy, g.dx, g.dy);
    const double ket = c.k * (g.ex * tqx + g.ey * tqy + g.ez * tqz);
    rx += c.h * tqx + ket * g.ex;
    ry += c.h * tqy + ket * g.ey;
    rz += c.h * tqz + ket * g.ez;
    aux[q] -= c.wf * cross_x(tiy, tiz, g.dy, g.dz);
    auy[q] -= c.wf * cross_x(tiz, tix, g.dz, g.dx);
    auz[q] -= c.wf * cross_x(tix, tiy, g.dx, g.dy);
    afx[q] -= c.ut * cross_x(fiy, fiz, g.dy, g.dz);
    afy[q] -= c.ut * cross_x(fiz, fix, g.dz, g.dx);
    afz[q] -= c.ut * cross_x(fix, fiy, g.dx, g.dy);
    const double kei = c.k * (g.ex * tix + g.ey * tiy + g.ez * tiz);
    arx[q] += c.h * tix + kei * g.ex;
    ary[q] += c.h * tiy + kei * g.ey;
    arz[q] += c.h * tiz + kei * g.ez;
  }
  out = {{ux, uy, uz}, {fx, fy, fz}, {rx, ry, rz}};
}

}  // namespace

void near_rotation_sum(const RotationSources& src, const RotationTarget& target, RotationSums& out) {
  simd_dispatch([src, target, &out]() RPYFMM_SIMD_BODY {
    if (src.a == nullptr) {
      rotation_sum_loop<true>(src, target, out);
    } else {
      rotation_sum_loop<false>(src, target, out);
    }
  });
}

void near_rotation_sum_symmetric(const RotationSources& src, const RotationTarget& target,
                                 const RotationAccumulators& acc, RotationSums& out) {
  simd_dispatch([src, target, acc, &out]() RPYFMM_SIMD_BODY {
    if (src.a == nullptr) {
      rotation_sum_symmetric_loop<true>(src, target, acc, out);
    } else {
      rotation_sum_symmetric_loop<false>(src, target, acc, out);
    }
  });
}

}  // namespace rpyfmm::rpy::detail
