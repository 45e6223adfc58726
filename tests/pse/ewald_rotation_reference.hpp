// Independent reference for the PSE grand mobility with rotation: [U; W] = M [F; T] for equal
// spheres in a periodic box by a direct Ewald sum, written plainly (no table, no FFT, no window,
// no grid, none of the operator's quadrature):
//  - wave space: a plain sum over k-vectors of the Fourier form of the periodic RPY grand
//    mobility (docs/theory/pse.md Sec. 5): per mode the force density
//    sinc(ka) F + (s(ka)/2) i k x T, the Stokes solution H(k)/(mu V k^2) (I - khat khat), and
//    U = sinc u, W = (s/2) i k x u, with s(x) = 3 j1(x)/x;
//  - real space: per image pair, the free-space RPY grand mobility (rpy_kernel.hpp,
//    rpy_rotation_kernel.hpp, checked term by term against Wajnryb et al. 2013 in tests/direct)
//    minus the inverse Fourier transform of the wave factor, by trapezoidal quadrature in k
//    (exponentially accurate for this smooth, Gaussian-decaying integrand) on a fine uniform grid.
// The splitting parameter xi is the reference's own: results must not depend on it, which the
// tests check, so the real and wave halves validate each other.
#pragma once

#include <array>
#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include "ewald_sums.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace pse_test {

struct GrandVectors {
  std::vector<double> u;
  std::vector<double> w;
};

/// j0(x), j1(x), j2(x), by their closed forms above x = 0.2 and power series below.
inline std::array<double, 3> spherical_bessel012(double x) {
  if (x < 0.2) {
    const double x2 = x * x;
    return {1.0 - x2 / 6.0 + x2 * x2 / 120.0 - x2 * x2 * x2 / 5040.0,
            x / 3.0 * (1.0 - x2 / 10.0 + x2 * x2 / 280.0 - x2 * x2 * x2 / 15120.0),
            x2 / 15.0 * (1.0 - x2 / 14.0 + x2 * x2 / 504.0 - x2 * x2 * x2 / 33264.0)};
  }
  const double s = std::sin(x), c = std::cos(x);
  const double j0 = s / x, j1 = s / (x * x) - c / x;
  return {j0, j1, 3.0 * j1 / x - j0};
}

/// The wave factor's inverse transform at r (times mu): the free-space-structured coefficients
/// c (U += c T x e), h, k (W += (h I + k e e^T) T) and the translational F, G (U += (F (I - ee) + G ee) F)
/// of the Hasimoto-weighted Fourier integrals; trapezoidal rule with step dk up to k = 14 xi (H < 1e-19 beyond).
struct WaveInRealSpace {
  double c, h, k, f, g;
};
inline WaveInRealSpace wave_in_real_space(double r, double xi, double a) {
  constexpr double pi = std::numbers::pi;
  const double k_max = 14.0 * xi;
  const double dk = std::min(0.02 * xi, 0.1 / (r + 2.0 * a));
  // The integrands are even in k, so the trapezoidal rule from k = 0 is spectrally accurate; at
  // k = 0 only F and G's integrands are nonzero (sinc^2 H (2/3)), with weight 1/2.
  WaveInRealSpace s{0, 0, 0, 1.0 / 3.0, 1.0 / 3.0};
  for (double k = dk; k <= k_max; k += dk) {
    const double q = k * k / (4.0 * xi * xi);
    const double H = (1.0 + q) * std::exp(-q);
    const auto ja = spherical_bessel012(k * a);
    const double sinc = ja[0], rot = 3.0 * ja[1] / (k * a);
    const auto jr = spherical_bessel012(k * r);
    const double j1_over_x = r > 0.0 ? jr[1] / (k * r) : 1.0 / 3.0;
    const double perp = jr[0] - j1_over_x;  // angular average of e^{ik.r} (I - khat khat), across
    const double par = 2.0 * j1_over_x;     // and along e
    s.c += sinc * rot * H * k * jr[1];
    s.h += rot * rot * H * k * k * perp;
    s.k += rot * rot * H * k * k * jr[2];
    s.f += sinc * sinc * H * perp;
    s.g += sinc * sinc * H * par;
  }
  s.c *= dk / (4.0 * pi * pi);
  s.h *= dk / (8.0 * pi * pi);
  s.k *= dk / (8.0 * pi * pi);
  s.f *= dk / (2.0 * pi * pi);
  s.g *= dk / (2.0 * pi * pi);
  return s;
}

/// [U; W] = M [F; T] by the direct Ewald sum with splitting parameter xi (see above).
inline GrandVectors ewald_rotation_reference(const std::vector<double>& x, double a, double mu,
                                             const std::array<double, 3>& L, const std::vector<double>& F,
                                             const std::vector<double>& T, double xi) {
  constexpr double pi = std::numbers::pi;
  const std::size_t n = x.size() / 3;
  GrandVectors out{std::vector<double>(3 * n, 0.0), std::vector<double>(3 * n, 0.0)};
  // Real space: the free kernel minus the wave factor's transform, every image with r < r_max (the
  // difference is below 1e-16 of the self terms beyond ~ 2a + 6.5 / xi).
  const double r_max = 2.0 * a + 6.5 / xi;
  for_each_image_pair(x, L, r_max, [&](std::size_t i, std::size_t j, const double* d, double r) {
    const WaveInRealSpace wv = wave_in_real_space(r, xi, a);
    const double* f = &F[3 * j];
    const double* t = &T[3 * j];
    if (r == 0.0) {
      for (int c = 0; c < 3; ++c) {
        out.u[3 * i + c] += (1.0 / (6.0 * pi * a) - wv.f) * f[c] / mu;
        out.w[3 * i + c] += (1.0 / (8.0 * pi * a * a * a) - wv.h) * t[c] / mu;
      }
      return;
    }
    const double e[3] = {d[0] / r, d[1] / r, d[2] / r};
    const auto tt = rpyfmm::rpy::rpy_scalars(r, a, a);  // U = (f I + g ee) F / mu, free space
    const auto rot = rpyfmm::rpy::rpy_rotation_scalars(r, a, a);
    const double cf = tt.f - wv.f;
    const double cg = tt.f + tt.g - wv.g;  // along e: f + g free, G wave
    const double cc = rot.ut - wv.c, ch = rot.h - wv.h, ck = rot.k - wv.k;
    const double ef = e[0] * f[0] + e[1] * f[1] + e[2] * f[2];
    const double et = e[0] * t[0] + e[1] * t[1] + e[2] * t[2];
    const double txe[3] = {t[1] * e[2] - t[2] * e[1], t[2] * e[0] - t[0] * e[2], t[0] * e[1] - t[1] * e[0]};
    const double fxe[3] = {f[1] * e[2] - f[2] * e[1], f[2] * e[0] - f[0] * e[2], f[0] * e[1] - f[1] * e[0]};
    for (int c = 0; c < 3; ++c) {
      out.u[3 * i + c] += (cf * f[c] + (cg - cf) * ef * e[c] + cc * txe[c]) / mu;
      out.w[3 * i + c] += (cc * fxe[c] + ch * t[c] + ck * et * e[c]) / mu;
    }
  });
  // Wave space: every k != 0 with H(k) > 1e-19.
  const double k_max = 14.0 * xi;
  const double V = L[0] * L[1] * L[2];
  using C = std::complex<double>;
  for_each_wave_vector(L, k_max, [&](const double* k, double k2) {
    const double kk = std::sqrt(k2);
    const auto ja = spherical_bessel012(kk * a);
    const double sinc = ja[0], half_rot = 1.5 * ja[1] / (kk * a);
    const double xq = k2 / (4.0 * xi * xi);
    const double g = (1.0 + xq) * std::exp(-xq) / (k2 * mu * V);
    // Force density f(k) = sum_j e^{-ik.x_j} (sinc F_j + (s/2) i k x T_j).
    C fk[3] = {0.0, 0.0, 0.0};
    for (std::size_t j = 0; j < n; ++j) {
      const double ph = k[0] * x[3 * j] + k[1] * x[3 * j + 1] + k[2] * x[3 * j + 2];
      const C e(std::cos(ph), -std::sin(ph));
      const double* t = &T[3 * j];
      const double kxt[3] = {k[1] * t[2] - k[2] * t[1], k[2] * t[0] - k[0] * t[2], k[0] * t[1] - k[1] * t[0]};
      for (int d = 0; d < 3; ++d) fk[d] += e * (sinc * F[3 * j + d] + C(0.0, half_rot * kxt[d]));
    }
    const C kf = (k[0] * fk[0] + k[1] * fk[1] + k[2] * fk[2]) / k2;
    C u[3];
    for (int d = 0; d < 3; ++d) u[d] = g * (fk[d] - k[d] * kf);
    const C kxu[3] = {k[1] * u[2] - k[2] * u[1], k[2] * u[0] - k[0] * u[2], k[0] * u[1] - k[1] * u[0]};
    for (std::size_t i = 0; i < n; ++i) {
      const double ph = k[0] * x[3 * i] + k[1] * x[3 * i + 1] + k[2] * x[3 * i + 2];
      const C e(std::cos(ph), std::sin(ph));
      for (int d = 0; d < 3; ++d) {
        out.u[3 * i + d] += std::real(e * sinc * u[d]);
        out.w[3 * i + d] += std::real(e * C(0.0, half_rot) * kxu[d]);
      }
    }
  });
  return out;
}

}  // namespace pse_test
