// Grand-mobility pair sums (rotation_pair_sums.hpp): portable loops
// that GCC vectorizes, compiled for AVX-512, AVX2 and the baseline and chosen by simd_level().
// Every regime is evaluated branch-free and selected, as in fmm_near_kernels.cpp.
#include "rotation_pair_sums.hpp"

#include <cmath>

#include "rpy_pair_scalars.hpp"
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
  double f, gr;  // the translational block f I + gr d d^T
  PairCoefficients c;
};

template <bool kEqual, bool kTranslation = true>
[[gnu::always_inline]] inline PairGeometry pair_at(const GrandSources& s, std::size_t q, const GrandTarget& t) {
  PairGeometry g{};
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
    if constexpr (kTranslation) pair_scalars_equal(r2, t.a, g.f, g.gr);
    g.c = pair_coefficients_equal(r, inv_r, inv_r2, t.a);
  } else {
    if constexpr (kTranslation) pair_scalars(r2, t.a, s.a[q], g.f, g.gr);
    g.c = pair_coefficients(r, inv_r, inv_r2, t.a, s.a[q]);
  }
  return g;
}

// v x d, component by component.
[[gnu::always_inline]] inline double cross_x(double vy, double vz, double dy, double dz) {
  return vy * dz - vz * dy;
}

// The target's velocity and angular velocity from one source's F and T.
struct PairContribution {
  double ux, uy, uz, wx, wy, wz;
};

template <bool kTranslation = true>
[[gnu::always_inline]] inline PairContribution contribution(const PairGeometry& g, double fx, double fy, double fz,
                                                            double tx, double ty, double tz) {
  const PairCoefficients& c = g.c;
  const double ket = c.k * (g.ex * tx + g.ey * ty + g.ez * tz);
  PairContribution p{c.ut * cross_x(ty, tz, g.dy, g.dz),
                     c.ut * cross_x(tz, tx, g.dz, g.dx),
                     c.ut * cross_x(tx, ty, g.dx, g.dy),
                     c.wf * cross_x(fy, fz, g.dy, g.dz) + c.h * tx + ket * g.ex,
                     c.wf * cross_x(fz, fx, g.dz, g.dx) + c.h * ty + ket * g.ey,
                     c.wf * cross_x(fx, fy, g.dx, g.dy) + c.h * tz + ket * g.ez};
  if constexpr (kTranslation) {  // without it U gets only c_ut (T x e)
    const double gdf = g.gr * (g.dx * fx + g.dy * fy + g.dz * fz);
    p.ux += g.f * fx + gdf * g.dx;
    p.uy += g.f * fy + gdf * g.dy;
    p.uz += g.f * fz + gdf * g.dz;
  }
  return p;
}

// The one-sided loop: the target's sums over all sources but itself.
template <bool kEqual, bool kTranslation>
[[gnu::always_inline]] inline void grand_sum_loop(const GrandSources& s, const GrandTarget& t, GrandSums& out) {
  double ux = 0, uy = 0, uz = 0, wx = 0, wy = 0, wz = 0;
#pragma omp simd reduction(+ : ux, uy, uz, wx, wy, wz)
  for (std::size_t q = 0; q < s.m; ++q) {
    PairGeometry g = pair_at<kEqual, kTranslation>(s, q, t);
    // The self pair is added by the caller.
    const bool self = s.id[q] == t.i;
    g.f = self ? 0.0 : g.f;
    g.gr = self ? 0.0 : g.gr;
    g.c = self ? PairCoefficients{0.0, 0.0, 0.0, 0.0} : g.c;
    const PairContribution p = contribution<kTranslation>(g, s.fx[q], s.fy[q], s.fz[q], s.tx[q], s.ty[q], s.tz[q]);
    ux += p.ux;
    uy += p.uy;
    uz += p.uz;
    wx += p.wx;
    wy += p.wy;
    wz += p.wz;
  }
  out = {{ux, uy, uz}, {wx, wy, wz}};
}

// Both directions: q <- i sees d_qi = -d, e_qi = -e and swaps the couplings (c_ut(q, i) =
// c_wf(i, q)); the translational block and h, k are symmetric.
template <bool kEqual>
[[gnu::always_inline]] inline void grand_sum_symmetric_loop(const GrandSources& s, const GrandTarget& t,
                                                            const GrandAccumulators& acc, GrandSums& out) {
  const double fix = t.f[0], fiy = t.f[1], fiz = t.f[2], tix = t.t[0], tiy = t.t[1], tiz = t.t[2];
  double* __restrict aux = acc.u[0];
  double* __restrict auy = acc.u[1];
  double* __restrict auz = acc.u[2];
  double* __restrict awx = acc.w[0];
  double* __restrict awy = acc.w[1];
  double* __restrict awz = acc.w[2];
  double ux = 0, uy = 0, uz = 0, wx = 0, wy = 0, wz = 0;
#pragma omp simd reduction(+ : ux, uy, uz, wx, wy, wz)
  for (std::size_t q = 0; q < s.m; ++q) {
    PairGeometry g = pair_at<kEqual>(s, q, t);
    const PairContribution p = contribution(g, s.fx[q], s.fy[q], s.fz[q], s.tx[q], s.ty[q], s.tz[q]);
    ux += p.ux;
    uy += p.uy;
    uz += p.uz;
    wx += p.wx;
    wy += p.wy;
    wz += p.wz;
    // Reverse direction: d -> -d (e -> -e) leaves the tt block, h and k e e^T unchanged and
    // turns c_ut (T x d) into -c_wf (T x d), c_wf (F x d) into -c_ut (F x d).
    const double ut = g.c.ut;
    g.c.ut = -g.c.wf;
    g.c.wf = -ut;
    const PairContribution b = contribution(g, fix, fiy, fiz, tix, tiy, tiz);
    aux[q] += b.ux;
    auy[q] += b.uy;
    auz[q] += b.uz;
    awx[q] += b.wx;
    awy[q] += b.wy;
    awz[q] += b.wz;
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
