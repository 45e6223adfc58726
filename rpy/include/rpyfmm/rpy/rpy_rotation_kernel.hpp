// rpyfmm — the rotational blocks of the Rotne-Prager-Yamakawa grand mobility, pair by pair
// (header-only, no std:: calls, so that device code can use it too).
//
// For spheres i, j at d = x_i - x_j, r = |d|, e = d / r, forces F and torques T:
//     U_i = sum_j  M^tt_ij F_j + c_ut(i, j) (T_j x e)
//     W_i = sum_j  c_wf(i, j) (F_j x e) + (h I + k e e^T) T_j
// with c_wf(i, j) = c_ut(j, i) (the grand matrix is symmetric), M^tt of rpy_kernel.hpp, and every
// factor except 1/eta folded into the coefficients below. The forms are the generalized RPY tensors
// of Wajnryb, Mizerski, Zuk & Szymczak, J. Fluid Mech. 731, R3 (2013): the Oseen tensor averaged
// over both spheres' surfaces with the rigid-motion weights (docs/theory/rpy.md, "Rotation"):
//   far, r > ai + aj (any radii; no a^2 corrections in the rotational blocks):
//       c_ut = 1 / (8 pi r^2),      h = -1 / (16 pi r^3),  k = 3 / (16 pi r^3)
//   partial overlap, |ai - aj| < r <= ai + aj:
//       c_ut(i, j) = (aj - ai + r)^2 (ai^2 + 2 ai (aj + r) - 3 (aj - r)^2) / (128 pi ai aj^3 r^2)
//       h = A / (8 pi ai^3 aj^3),  k = B / (8 pi ai^3 aj^3),
//       A = (5 r^6 - 27 r^4 (ai^2 + aj^2) + 32 r^3 (ai^3 + aj^3) - 9 r^2 (ai^2 - aj^2)^2
//            - (ai - aj)^4 (ai^2 + 4 ai aj + aj^2)) / (64 r^3)
//       B = 3 ((ai - aj)^2 - r^2)^2 (ai^2 + 4 ai aj + aj^2 - r^2) / (64 r^3)
//   one inside the other, r <= |ai - aj| (and r = 0):
//       c_ut(i, j) = r / (8 pi aj^3) where i lies inside j (aj > ai), 0 where j lies inside i
//       (a torque on the outer sphere turns its interior rigidly; the inner sphere's rotlet
//       averages to zero over the outer surface), h = 1 / (8 pi max(ai, aj)^3), k = 0.
// Equal radii a reduce to c_ut = (r / (16 pi a^3)) (1 - 3r/(8a)), h = (1 - 27r/(32a) + 5r^3/(64a^3))
// / (8 pi a^3), k = (9r/(32a) - 3r^3/(64a^3)) / (8 pi a^3) for r <= 2a. The self blocks are the r = 0
// limits: M^rr_ii = I / (8 pi eta a^3), M^tr_ii = 0.
#pragma once

#include "rpyfmm/rpy/rpy_kernel.hpp"

namespace rpyfmm::rpy {

/// The rotational coefficients of one ordered pair (i, j), times eta (see the header comment).
struct RpyRotationScalars {
  double ut;  ///< U_i += ut (T_j x e)
  double wf;  ///< W_i += wf (F_j x e)
  double h;   ///< W_i += (h I + k e e^T) T_j
  double k;
};

namespace rpy_detail {

/// c_ut(i, j) for a partial overlap |ai - aj| < r <= ai + aj.
RPYFMM_HOST_DEVICE inline double coupling_overlap(double r, double ai, double aj) {
  const double s = aj - ai + r;
  const double t = aj - r;
  return s * s * (ai * ai + 2.0 * ai * (aj + r) - 3.0 * t * t) / (128.0 * pi * ai * aj * aj * aj * r * r);
}

/// c_ut(i, j) for r <= |ai - aj|: nonzero only where i lies inside j.
RPYFMM_HOST_DEVICE inline double coupling_inside(double r, double ai, double aj) {
  return aj > ai ? r / (8.0 * pi * aj * aj * aj) : 0.0;
}

/// The partial-overlap coefficients, |ai - aj| < r <= ai + aj, evaluated in units of the larger
/// radius L (c_ut, c_wf ~ 1/L^2, h, k ~ 1/L^3): the sixth powers of the forms stay normal for
/// every radius the operators accept (down to 2^-300 of the suspension's size), where a_i^3 a_j^3
/// itself would underflow. Branch-free, so that vectorized loops can use it.
RPYFMM_HOST_DEVICE inline RpyRotationScalars rotation_overlap(double r, double ai, double aj) {
  const double length = ai > aj ? ai : aj;
  const double inv_l = 1.0 / length;
  const double x = r * inv_l, bi = ai * inv_l, bj = aj * inv_l;
  const double x2 = x * x, x3 = x2 * x;
  const double bi2 = bi * bi, bj2 = bj * bj;
  const double diff = bi - bj, d2 = diff * diff;
  const double q = bi2 + 4.0 * bi * bj + bj2;
  const double a_term = (5.0 * x3 * x3 - 27.0 * x2 * x2 * (bi2 + bj2) + 32.0 * x3 * (bi2 * bi + bj2 * bj) -
                         9.0 * x2 * (bi2 - bj2) * (bi2 - bj2) - d2 * d2 * q) /
                        (64.0 * x3);
  const double w = d2 - x2;
  const double b_term = 3.0 * w * w * (q - x2) / (64.0 * x3);
  const double c = inv_l * inv_l * inv_l / (8.0 * pi * bi2 * bi * bj2 * bj);
  return {coupling_overlap(x, bi, bj) * inv_l * inv_l, coupling_overlap(x, bj, bi) * inv_l * inv_l, c * a_term,
          c * b_term};
}

}  // namespace rpy_detail

/// Rotational self mobility times eta: 1 / (8 pi a^3).
RPYFMM_HOST_DEVICE inline double rpy_rotation_self(double a) {
  return rpy_detail::inv_8pi / (a * a * a);
}

/// The far form of the rotational coefficients at r > 0, the same for any radii: c_ut = c_wf =
/// 1 / (8 pi r^2), h = -1 / (16 pi r^3), k = 3 / (16 pi r^3). These are the harmonic fields
/// curl (T / r) / (8 pi) and grad div (T / r) / (16 pi) (docs/theory/rpy.md, section 7), which a
/// Laplace far field sums for every pair at r > 0, overlapping ones included.
RPYFMM_HOST_DEVICE inline RpyRotationScalars rpy_rotation_far(double r) {
  const double c = rpy_detail::inv_8pi / (r * r);
  const double h = -0.5 * c / r;
  return {c, c, h, -3.0 * h};
}

/// The rotational coefficients of the ordered pair (i, j) at distance r >= 0.
RPYFMM_HOST_DEVICE inline RpyRotationScalars rpy_rotation_scalars(double r, double ai, double aj) {
  if (r > ai + aj) return rpy_rotation_far(r);
  const double diff = ai - aj;
  const double adiff = diff < 0.0 ? -diff : diff;
  if (r <= adiff) {
    const double amax = ai > aj ? ai : aj;
    return {rpy_detail::coupling_inside(r, ai, aj), rpy_detail::coupling_inside(r, aj, ai), rpy_rotation_self(amax),
            0.0};
  }
  return rpy_detail::rotation_overlap(r, ai, aj);
}

}  // namespace rpyfmm::rpy
