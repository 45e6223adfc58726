// The translational RPY pair scalars in branch-free form, for vectorized pair loops (FmmRpy's
// near field, the grand-mobility pair sums). Internal to rpyfmm::rpy.
#pragma once

#include <cmath>

#include "rpyfmm/rpy/rpy_kernel.hpp"

namespace rpyfmm::rpy::detail {

// The pair scalars of the exact RPY block M_iq = (f I + gr d d^T) (times eta), d = x_i - x_q,
// r2 = |d|^2 (rpy_kernel.hpp, docs/theory/rpy.md): all regimes evaluated branch-free and selected, so
// that the loops calling them vectorize. Coincident distinct points (r = 0) get
// f = 1 / (6 pi max a), gr = 0. Shared by the fused single-rhs sums and the block path.

// Different radii ai, aj: far (r > ai + aj), partial overlap, one sphere inside the other.
[[gnu::always_inline]] inline void pair_scalars(double r2, double ai, double aj, double& f, double& gr) {
  const double safe_r2 = r2 > 0.0 ? r2 : 1.0;
  const double r = std::sqrt(safe_r2);
  const double inv_r = 1.0 / r;
  const double sum = ai + aj, diff = ai - aj;
  // far: r > ai + aj
  const double s2 = (ai * ai + aj * aj) * inv_r * inv_r;
  const double c8 = rpy_detail::inv_8pi * inv_r;
  const double f_far = c8 * (1.0 + s2 / 3.0), g_far = c8 * (1.0 - s2);
  // partial overlap: |ai - aj| < r <= ai + aj
  const double c6 = rpy_detail::inv_6pi / (ai * aj);
  const double d2r = diff * diff * inv_r, pr = d2r + 3.0 * r, qr = d2r - r;
  const double inv_32r = inv_r / 32.0;
  const double f_ov = c6 * (0.5 * sum - pr * pr * inv_32r), g_ov = c6 * (3.0 * qr * qr * inv_32r);
  // one sphere inside the other, and coincident points
  const double f_in = rpy_detail::inv_6pi / (ai > aj ? ai : aj);
  const bool far = r > sum, inside = r <= (diff < 0.0 ? -diff : diff) || r2 == 0.0;
  f = far ? f_far : (inside ? f_in : f_ov);
  const double g = far ? g_far : (inside ? 0.0 : g_ov);
  gr = g * inv_r * inv_r;
}

// Equal radii a (rpy_scalars_equal, Guan eq. 3.1): one sqrt and one division per pair.
[[gnu::always_inline]] inline void pair_scalars_equal(double r2, double a, double& f, double& gr) {
  const double two_a = 2.0 * a, a2 = a * a, c6 = rpy_detail::inv_6pi / a, inv_32a = 1.0 / (32.0 * a);
  const double safe_r2 = r2 > 0.0 ? r2 : 1.0;
  const double r = std::sqrt(r2);  // 0 for coincident points: the overlap branch gives I / (6 pi a)
  const double inv_r2 = 1.0 / safe_r2;
  const double inv_r = r * inv_r2;
  const double s = a2 * inv_r2;
  const double c8 = rpy_detail::inv_8pi * inv_r;
  const double t = r * inv_32a;
  const bool far = r > two_a;
  f = far ? c8 * (1.0 + (2.0 / 3.0) * s) : c6 * (1.0 - 9.0 * t);
  double g = far ? c8 * (1.0 - 2.0 * s) : c6 * (3.0 * t);
  g = r2 > 0.0 ? g : 0.0;  // coincident distinct points: I / (6 pi a)
  gr = g * inv_r2;
}

}  // namespace rpyfmm::rpy::detail
