// Independent references for the PSE tests, written plainly:
//  - fourier_fg: F, G by numerical quadrature of the Fourier integral of [PSE] eqs. 12-13
//    (no closed form involved);
//  - ewald_reference: the periodic RPY product by a direct Ewald sum — real space from the
//    closed forms (themselves checked against fourier_fg) with explicit image loops, wave
//    space as a plain sum over k-vectors (no FFT, no window, no grid).
#pragma once

#include <array>
#include <cmath>
#include <complex>
#include <numbers>
#include <vector>

#include "ewald_sums.hpp"
#include "rpyfmm/rpy/pse/real_space.hpp"

namespace pse_test {

inline constexpr double kPi = std::numbers::pi;

/// Hasimoto: 6 pi mu a M_11 = 1 - C a/L + (4 pi/3) (a/L)^3 for one sphere in a cube (exact for RPY, L >= 2a).
inline double hasimoto(double a_over_L) {
  constexpr double C = 2.83729747948061947666591710460773907;
  return 1.0 - C * a_over_L + 4.0 * kPi / 3.0 * a_over_L * a_over_L * a_over_L;
}

/// F(r), G(r) (units of 1/(6 pi mu a)) from the Fourier integral of the real-space kernel:
/// M_r(r) = (1/mu) int d^3k/(2pi)^3 e^{ik.r} sinc^2(ka) (1 - H(k)) / k^2 (I - khat khat);
/// the angular average of e^{ik.r}(I - khat khat) is (j0 - j1/x)(I - rr) + (2 j1/x) rr, x = kr.
/// Gauss-Legendre panels of width 0.25/a up to k = kmax.
inline std::array<double, 2> fourier_fg(double r, double xi, double a, double kmax = 3000.0) {
  static const double gx[8] = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290, -0.1834346424956498,
                               0.1834346424956498,  0.5255324099163290,  0.7966664774136267,  0.9602898564975363};
  static const double gw[8] = {0.1012285362903763, 0.2223810344533745, 0.3137066458778873, 0.3626837833783620,
                               0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763};
  double F = 0.0, G = 0.0;
  const double panel = 0.25 / a;
  for (double k0 = 0.0; k0 < kmax / a; k0 += panel) {
    for (int q = 0; q < 8; ++q) {
      const double k = k0 + 0.5 * panel * (gx[q] + 1.0);
      const double w = 0.5 * panel * gw[q];
      const double s = std::sin(k * a) / (k * a);
      const double x2 = k * k / (4.0 * xi * xi);
      const double weight = s * s * (1.0 - (1.0 + x2) * std::exp(-x2));
      double perp, par;
      const double x = k * r;
      if (x < 1e-3) {  // series of j0 - j1/x and 2 j1/x
        perp = 2.0 / 3.0 - 2.0 * x * x / 15.0;
        par = 2.0 / 3.0 - x * x / 15.0;
      } else {
        const double j0 = std::sin(x) / x;
        const double j1 = std::sin(x) / (x * x) - std::cos(x) / x;
        perp = j0 - j1 / x;
        par = 2.0 * j1 / x;
      }
      F += w * weight * perp;
      G += w * weight * par;
    }
  }
  // (1/mu) (4 pi / (2 pi)^3) int k^2 dk / k^2 (...) = (1 / (2 pi^2 mu)) int (...) dk; times 6 pi mu a.
  const double unit = 6.0 * kPi * a / (2.0 * kPi * kPi);
  return {F * unit, G * unit};
}

/// U = M F for the periodic RPY mobility by a direct Ewald sum ([PSE] eqs. 9-13).
inline std::vector<double> ewald_reference(const std::vector<double>& x, double a, double mu,
                                           const std::array<double, 3>& L, const std::vector<double>& f, double xi) {
  using rpyfmm::rpy::pse::real_space_fg;
  const std::size_t n = x.size() / 3;
  std::vector<double> u(3 * n, 0.0);
  const double m0 = 1.0 / (6.0 * kPi * mu * a);
  // Real space: every image within rc(1e-16).
  const double rc = rpyfmm::rpy::pse::real_space_cutoff(1e-16, xi, a);
  const double self = rpyfmm::rpy::pse::real_space_self(xi, a);
  for_each_image_pair(x, L, rc, [&](std::size_t i, std::size_t j, const double* d, double r) {
    if (r == 0.0) {
      for (int c = 0; c < 3; ++c) u[3 * i + c] += m0 * self * f[3 * j + c];
      return;
    }
    const auto v = real_space_fg(r, xi, a);
    double rf = 0.0;
    for (int c = 0; c < 3; ++c) rf += d[c] / r * f[3 * j + c];
    for (int c = 0; c < 3; ++c) u[3 * i + c] += m0 * (v.f * f[3 * j + c] + (v.g - v.f) * d[c] / r * rf);
  });
  // Wave space: sum over k != 0 with |k| <= 2 xi sqrt(ln 1e16) (H < 1e-16 beyond).
  const double kmax = 2.0 * xi * std::sqrt(std::log(1e16));
  const double V = L[0] * L[1] * L[2];
  for_each_wave_vector(L, kmax, [&](const double* k, double k2) {
    const double kk = std::sqrt(k2);
    const double sinc = std::sin(kk * a) / (kk * a);
    const double x2 = k2 / (4.0 * xi * xi);
    const double c = sinc * sinc * (1.0 + x2) * std::exp(-x2) / (k2 * mu * V);
    std::complex<double> S[3] = {0.0, 0.0, 0.0};  // S(k) = sum_j F_j exp(-i k.x_j)
    for (std::size_t j = 0; j < n; ++j) {
      const double ph = k[0] * x[3 * j] + k[1] * x[3 * j + 1] + k[2] * x[3 * j + 2];
      const std::complex<double> e(std::cos(ph), -std::sin(ph));
      for (int d = 0; d < 3; ++d) S[d] += e * f[3 * j + d];
    }
    const std::complex<double> kS = (k[0] * S[0] + k[1] * S[1] + k[2] * S[2]) / k2;
    std::complex<double> P[3];
    for (int d = 0; d < 3; ++d) P[d] = S[d] - k[d] * kS;
    for (std::size_t i = 0; i < n; ++i) {
      const double ph = k[0] * x[3 * i] + k[1] * x[3 * i + 1] + k[2] * x[3 * i + 2];
      const std::complex<double> e(std::cos(ph), std::sin(ph));
      for (int d = 0; d < 3; ++d) u[3 * i + d] += c * std::real(e * P[d]);
    }
  });
  return u;
}

/// Random positions in the box (uniform; overlaps allowed) with a fixed seed.
inline std::vector<double> random_points(std::size_t n, const std::array<double, 3>& L, unsigned seed) {
  std::vector<double> x(3 * n);
  std::uint64_t s = seed * 0x9E3779B97F4A7C15ull + 1;
  for (std::size_t i = 0; i < x.size(); ++i) {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    x[i] = L[i % 3] * static_cast<double>(s >> 11) * 0x1.0p-53;
  }
  return x;
}

inline double rel_l2(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    num += (a[i] - b[i]) * (a[i] - b[i]);
    den += b[i] * b[i];
  }
  return std::sqrt(num / den);
}

}  // namespace pse_test
