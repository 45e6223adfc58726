// rpyfmm — the Rotne-Prager-Yamakawa pair mobility, written once for host and
// device code (header-only, no std:: calls so that nvcc compiles it for the GPU).
//
// Every function here follows docs/theory/rpy.md:
//   equal radii a:      Guan, dissertation, eq. (3.1); Fiore et al., J. Chem. Phys. 2017, eq. (4);
//   different radii:    Zuk, Wajnryb, Mizerski & Szymczak, J. Fluid Mech. 741, R5 (2014),
//                       eqs. (10)-(12) (far field, partial overlap, one sphere inside the other).
// The pair tensor is isotropic-plus-dyadic,
//     M_ij = ( f(r) I + g(r) rhat rhat^T ) / eta ,   r = x_i - x_j,
// and the functions below return (f, g) with every factor except 1/eta folded in.
// The self term M_ii = I / (6 pi eta a_i) is the r = 0 limit of the overlap
// branch, so the same formula serves i == j and coincident particles.
#pragma once

#include <math.h>  // ::sqrt, usable in host code and (as a CUDA builtin) in device code

#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::rpy {

namespace rpy_detail {
inline constexpr double pi = 3.14159265358979323846;
inline constexpr double inv_6pi = 1.0 / (6.0 * pi);
inline constexpr double inv_8pi = 1.0 / (8.0 * pi);
}  // namespace rpy_detail

/// Coefficients of one pair block: M_ij = (f I + g rhat rhat^T) / eta.
struct RpyScalars {
  double f;
  double g;
};

/// Self mobility times eta: 1 / (6 pi a)   (M_ii = I / (6 pi eta a)).
RPYFMM_HOST_DEVICE inline double rpy_self(double a) {
  return rpy_detail::inv_6pi / a;
}

/// Equal radii a at distance r >= 0 (Guan eq. 3.1; Fiore et al. 2017 eq. 4):
///   r >  2a: f = (1 + 2a^2/(3r^2)) / (8 pi r),  g = (1 - 2a^2/r^2) / (8 pi r)
///   r <= 2a: f = (1 - 9r/(32a)) / (6 pi a),     g = (3r/(32a)) / (6 pi a)
/// r = 0 gives the self term (f = 1/(6 pi a), g = 0).
RPYFMM_HOST_DEVICE inline RpyScalars rpy_scalars_equal(double r, double a) {
  if (r > 2.0 * a) {
    const double c = rpy_detail::inv_8pi / r;
    const double s = a * a / (r * r);
    return {c * (1.0 + (2.0 / 3.0) * s), c * (1.0 - 2.0 * s)};
  }
  const double c = rpy_detail::inv_6pi / a;
  const double t = r / (32.0 * a);
  return {c * (1.0 - 9.0 * t), c * (3.0 * t)};
}

/// Radii ai, aj at distance r >= 0 (Zuk et al. 2014):
///   r > ai + aj (far):      f = (1 + (ai^2 + aj^2)/(3r^2)) / (8 pi r),  g = (1 - (ai^2 + aj^2)/r^2) / (8 pi r)
///   |ai - aj| < r <= ai + aj (partial overlap):
///       f = (16 r^3 (ai + aj) - ((ai - aj)^2 + 3r^2)^2) / (32 r^3) / (6 pi ai aj)
///       g = 3 ((ai - aj)^2 - r^2)^2 / (32 r^3) / (6 pi ai aj)
///   r <= |ai - aj| (one inside the other, and r = 0): f = 1 / (6 pi max(ai, aj)), g = 0
/// For ai == aj this equals rpy_scalars_equal up to rounding.
RPYFMM_HOST_DEVICE inline RpyScalars rpy_scalars(double r, double ai, double aj) {
  const double sum = ai + aj;
  if (r > sum) {
    const double c = rpy_detail::inv_8pi / r;
    const double s = (ai * ai + aj * aj) / (r * r);
    return {c * (1.0 + s / 3.0), c * (1.0 - s)};
  }
  const double diff = ai - aj;
  const double adiff = diff < 0.0 ? -diff : diff;
  if (r <= adiff) {
    const double amax = ai > aj ? ai : aj;
    return {rpy_detail::inv_6pi / amax, 0.0};
  }
  // Divided through by r^2 so that no r^3 appears (no overflow for tiny r > |ai - aj|):
  // f = [ (ai + aj)/2 - (p/r)^2 / (32 r) ] / (6 pi ai aj),  p = (ai - aj)^2 + 3 r^2,
  // g = 3 (q/r)^2 / (32 r) / (6 pi ai aj),                 q = (ai - aj)^2 - r^2.
  const double d2r = diff * diff / r;
  const double pr = d2r + 3.0 * r;
  const double qr = d2r - r;
  const double c = rpy_detail::inv_6pi / (ai * aj);
  const double inv_32r = 1.0 / (32.0 * r);
  return {c * (0.5 * sum - pr * pr * inv_32r), c * (3.0 * qr * qr * inv_32r)};
}

/// The 3x3 block M_ij (row-major) for separation d = x_i - x_j, radii ai, aj,
/// viscosity eta. d = 0 gives I / (6 pi eta max(ai, aj)).
RPYFMM_HOST_DEVICE inline void rpy_tensor(const double d[3], double ai, double aj, double eta, double m[9]) {
  const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  const double r = ::sqrt(r2);
  const RpyScalars s = rpy_scalars(r, ai, aj);
  const double inv_eta = 1.0 / eta;
  const double gr = r2 > 0.0 ? s.g / r2 : 0.0;  // g rhat rhat^T = (g / r^2) d d^T
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      m[3 * a + b] = inv_eta * ((a == b ? s.f : 0.0) + gr * (d[a] * d[b]));  // exactly symmetric
    }
  }
}

/// u += M_ij f for one pair: d = x_i - x_j, radii ai, aj, inv_eta = 1/eta.
/// Used by the direct operator's generic path, the FMM near field and CUDA kernels.
RPYFMM_HOST_DEVICE inline void rpy_pair_add(const double d[3], double ai, double aj, double inv_eta, const double f[3],
                                            double u[3]) {
  const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  const RpyScalars s = rpy_scalars(::sqrt(r2), ai, aj);
  const double gr = r2 > 0.0 ? s.g / r2 : 0.0;
  const double df = gr * (d[0] * f[0] + d[1] * f[1] + d[2] * f[2]);
  u[0] += inv_eta * (s.f * f[0] + df * d[0]);
  u[1] += inv_eta * (s.f * f[1] + df * d[1]);
  u[2] += inv_eta * (s.f * f[2] + df * d[2]);
}

/// Same as rpy_pair_add for equal radii a (fewer operations).
RPYFMM_HOST_DEVICE inline void rpy_pair_add_equal(const double d[3], double a, double inv_eta, const double f[3],
                                                  double u[3]) {
  const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  const RpyScalars s = rpy_scalars_equal(::sqrt(r2), a);
  const double gr = r2 > 0.0 ? s.g / r2 : 0.0;
  const double df = gr * (d[0] * f[0] + d[1] * f[1] + d[2] * f[2]);
  u[0] += inv_eta * (s.f * f[0] + df * d[0]);
  u[1] += inv_eta * (s.f * f[1] + df * d[1]);
  u[2] += inv_eta * (s.f * f[2] + df * d[2]);
}

}  // namespace rpyfmm::rpy
