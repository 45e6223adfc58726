// rpyfmm — PSE real-space kernel of the rotational blocks: the wave-space part in real space by
// quadrature of its radial transforms, the real-space coefficients, their table
// (rotation_real_space.hpp; docs/theory/pse.md Sec. 5).
#include "rpyfmm/rpy/pse/rotation_real_space.hpp"

#include <algorithm>
#include <boost/math/quadrature/gauss.hpp>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <utility>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"
#include "table_refinement.hpp"

namespace rpyfmm::rpy::pse {

namespace {

constexpr double kPi = std::numbers::pi;
/// Below this argument the spherical Bessel combinations come from their series: the closed forms
/// cancel (j2(x) ~ x^2 / 15 from terms ~ 3 / x^2).
constexpr double kSeriesBelow = 0.5;

/// sum_m (-x^2/2)^m / (m! (2n+3)(2n+5)...(2n+2m+1)), the series of j_n(x) (2n+1)!! / x^n, to full precision
/// for x < kSeriesBelow.
double bessel_series(int n, double x) {
  const double q = -0.5 * x * x;
  double term = 1.0, sum = 1.0;
  for (int m = 1; m < 30 && std::abs(term) > 1e-18 * std::abs(sum); ++m) {
    term *= q / (m * (2.0 * n + 2.0 * m + 1.0));
    sum += term;
  }
  return sum;
}

/// j0(x) - j1(x) / x, j1(x) and j2(x) from sin x and cos x (or the series below kSeriesBelow).
struct BesselCombinations {
  double perp;  // j0 - j1 / x
  double j1;
  double j2;
};
BesselCombinations bessel_combinations(double x, double sin_x, double cos_x) {
  if (x < kSeriesBelow) {
    const double j0 = bessel_series(0, x);
    const double j1_over_x = bessel_series(1, x) / 3.0;
    return {j0 - j1_over_x, x * j1_over_x, x * x * bessel_series(2, x) / 15.0};
  }
  const double inv_x = 1.0 / x;
  const double j0 = sin_x * inv_x;
  const double j1 = (j0 - cos_x) * inv_x;
  return {j0 - j1 * inv_x, j1, 3.0 * j1 * inv_x - j0};
}

/// The translational and rotational shape factors sinc(x) = j0(x) and s(x) = 3 j1(x) / x.
struct ShapeFactors {
  double sinc;
  double rot;
};
ShapeFactors shape_factors(double x) {
  if (x < kSeriesBelow) return {bessel_series(0, x), bessel_series(1, x)};
  const double sinc = std::sin(x) / x;
  return {sinc, 3.0 * (sinc - std::cos(x)) / (x * x)};
}

/// c, h, k of the free-space grand mobility for equal radii (r = 0: the self block).
RotationCoefficients free_space(double r, double a) {
  if (r == 0.0) return {0.0, rpy_rotation_self(a), 0.0};
  const RpyRotationScalars s = rpy_rotation_scalars(r, a, a);
  return {s.ut, s.h, s.k};
}

}  // namespace

RotationWaveKernel::RotationWaveKernel(double xi, double a, double r_max) {
  const char* where = "RotationWaveKernel";
  require_positive(xi, where, "xi");
  require_positive(a, where, "radius");
  require(std::isfinite(r_max) && r_max >= 0.0, ErrorCode::invalid_argument, where, "r_max must be finite and >= 0");
  // H(k) = (1 + q) e^-q, q = k^2 / (4 xi^2), is below 1e-19 for q > 49: k_max = 14 xi. Panels of
  // 16 points spanning at most 2 radians of the fastest phase, k (r + 2a), and xi / 2 of H.
  const double k_max = 14.0 * xi;
  const double width = std::min(0.5 * xi, 2.0 / (r_max + 2.0 * a));
  const auto panels = static_cast<std::size_t>(std::ceil(k_max / width));
  using Rule = boost::math::quadrature::gauss<double, 16>;
  const auto& x = Rule::abscissa();
  const auto& w = Rule::weights();
  const double inv_4xi2 = 1.0 / (4.0 * xi * xi);
  k_.reserve(16 * panels);
  for (std::size_t p = 0; p < panels; ++p) {
    const double half = 0.5 * k_max / static_cast<double>(panels);
    const double mid = (2.0 * static_cast<double>(p) + 1.0) * half;
    for (std::size_t i = 0; i < x.size(); ++i) {
      for (const double sign : {-1.0, 1.0}) {
        const double k = mid + sign * half * x[i];
        const double q = k * k * inv_4xi2;
        const double H = (1.0 + q) * std::exp(-q);
        const ShapeFactors s = shape_factors(k * a);
        k_.push_back(k);
        w_cross_.push_back(half * w[i] * s.sinc * s.rot * H * k / (4.0 * kPi * kPi));
        w_rot_.push_back(half * w[i] * s.rot * s.rot * H * k * k / (8.0 * kPi * kPi));
      }
    }
  }
}

RotationCoefficients RotationWaveKernel::operator()(double r) const {
  RotationCoefficients sum{0.0, 0.0, 0.0};
  for (std::size_t q = 0; q < k_.size(); ++q) {
    const double x = k_[q] * r;
    const BesselCombinations b = bessel_combinations(x, std::sin(x), std::cos(x));
    sum.c += w_cross_[q] * b.j1;
    sum.h += w_rot_[q] * b.perp;
    sum.k += w_rot_[q] * b.j2;
  }
  return sum;
}

void RotationWaveKernel::tabulate(double step, std::size_t count, RotationCoefficients* out) const {
  constexpr std::size_t kChunk = 64;
  const std::size_t nq = k_.size();
  const auto chunks = static_cast<std::int64_t>((count + kChunk - 1) / kChunk);
  // Chunks of r run in parallel, each from exact sines and cosines at its first r: the values do
  // not depend on the thread count.
#pragma omp parallel
  {
    std::vector<double> sin_kr(nq), cos_kr(nq), sin_step(nq), cos_step(nq);
    for (std::size_t q = 0; q < nq; ++q) {
      sin_step[q] = std::sin(k_[q] * step);
      cos_step[q] = std::cos(k_[q] * step);
    }
#pragma omp for schedule(static)
    for (std::int64_t chunk = 0; chunk < chunks; ++chunk) {
      const std::size_t first = static_cast<std::size_t>(chunk) * kChunk;
      const std::size_t last = std::min(count, first + kChunk);
      for (std::size_t q = 0; q < nq; ++q) {
        const double x = k_[q] * step * static_cast<double>(first);
        sin_kr[q] = std::sin(x);
        cos_kr[q] = std::cos(x);
      }
      for (std::size_t j = first; j < last; ++j) {
        const double r = step * static_cast<double>(j);
        RotationCoefficients sum{0.0, 0.0, 0.0};
        for (std::size_t q = 0; q < nq; ++q) {
          const BesselCombinations b = bessel_combinations(k_[q] * r, sin_kr[q], cos_kr[q]);
          sum.c += w_cross_[q] * b.j1;
          sum.h += w_rot_[q] * b.perp;
          sum.k += w_rot_[q] * b.j2;
          const double s = sin_kr[q] * cos_step[q] + cos_kr[q] * sin_step[q];
          cos_kr[q] = cos_kr[q] * cos_step[q] - sin_kr[q] * sin_step[q];
          sin_kr[q] = s;
        }
        out[j] = sum;
      }
    }
  }
}

RotationCoefficients rotation_real_space(double r, double xi, double a) {
  require(std::isfinite(r) && r >= 0.0, ErrorCode::invalid_argument, "pse::rotation_real_space",
          "r must be finite and >= 0");
  const RotationCoefficients wave = RotationWaveKernel(xi, a, r)(r);
  const RotationCoefficients full = free_space(r, a);
  return {full.c - wave.c, full.h - wave.h, full.k - wave.k};
}

PseRotationTable::PseRotationTable(double xi, double a, double r_cut, double eps_t) {
  const char* where = "PseRotationTable";
  require_positive(xi, where, "xi");
  require_positive(a, where, "radius");
  require_positive(r_cut, where, "r_cut");
  require_positive(eps_t, where, "table tolerance");
  unit_c_ = 1.0 / (6.0 * kPi * a * a);
  unit_hk_ = unit_c_ / a;
  const RotationWaveKernel wave(xi, a, r_cut + a);
  // The coefficients, dimensionless, at r = j dr / 2: even j are the nodes, odd j the midpoints.
  const auto sample = [&](double dr, std::size_t n) {
    std::vector<double> v(3 * (2 * n + 1));
    std::vector<RotationCoefficients> waves(2 * n + 1);
    wave.tabulate(0.5 * dr, waves.size(), waves.data());
    for (std::size_t j = 0; j < waves.size(); ++j) {
      const RotationCoefficients& w = waves[j];
      const RotationCoefficients f = free_space(0.5 * dr * static_cast<double>(j), a);
      const std::size_t at = 3 * j;
      v[at] = (f.c - w.c) / unit_c_;
      v[at + 1] = (f.h - w.h) / unit_hk_;
      v[at + 2] = (f.k - w.k) / unit_hk_;
    }
    return v;
  };
  // As the translational table (real_space.cpp): start near the spacing that the curvature allows
  // and halve until every midpoint is within eps_t.
  const double dr0 = std::min(std::sqrt(8.0 * eps_t / 2.0) * a, r_cut / 16.0);
  detail::RefinedTable t =
      detail::refine_linear_table(dr0, r_cut, eps_t, 3, std::size_t{1} << 22, where, "2^22", sample);
  dr_ = t.dr;
  inv_dr_ = 1.0 / t.dr;
  data_ = std::move(t.values);
}

}  // namespace rpyfmm::rpy::pse
