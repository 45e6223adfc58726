// Shared helpers of the FmmRpy rotation tests: grand-mobility products, random loads of each kind,
// and the relative l2 errors of FmmRpy's U and W against DirectRpy's.
#pragma once

#include <algorithm>
#include <cmath>
#include <tuple>
#include <vector>

#include "configurations.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::testing {

struct Motion {
  std::vector<double> u, w;
};

inline Motion grand_product(const rpy::MobilityOperator& op, const std::vector<double>& f,
                            const std::vector<double>& tq) {
  Motion m{std::vector<double>(f.size()), std::vector<double>(f.size())};
  op.apply(f, tq, m.u, m.w);
  return m;
}

// Random loads of one case: forces, torques (times the mean radius, so that both load kinds move
// the particles comparably), or both.
enum class Loads { forces, torques, both };

inline std::tuple<std::vector<double>, std::vector<double>> loads(const Configuration& c, Loads kind, unsigned seed) {
  double mean_a = 0.0;
  for (double a : c.a) mean_a += a / static_cast<double>(c.a.size());
  std::vector<double> f = random_vector(c.x.size(), seed), tq = random_vector(c.x.size(), seed + 100);
  for (double& v : tq) v *= mean_a;
  if (kind == Loads::torques) f.assign(f.size(), 0.0);
  if (kind == Loads::forces) tq.assign(tq.size(), 0.0);
  return {f, tq};
}

struct Errors {
  double u, w;
};

inline Errors rotation_errors(const Configuration& c, double eps, Loads kind, int leaf_capacity = 0) {
  rpy::DirectRpy direct;
  rpy::FmmRpy fast(rpy::Geometry::open(), 1.0, rpy::FmmRpyOptions{.tolerance = eps, .leaf_capacity = leaf_capacity});
  direct.set_positions(c.x, c.a);
  fast.set_positions(c.x, c.a);
  const auto [f, tq] = loads(c, kind, 11);
  const Motion exact = grand_product(direct, f, tq), approx = grand_product(fast, f, tq);
  return {relative_l2(approx.u, exact.u), relative_l2(approx.w, exact.w)};
}

// Exact [U; W] at sampled targets (i = 7919 s mod N, s < samples) from the pair couplings of
// rpy_rotation_kernel.hpp, independent of the operators: the relative l2 errors of u and w there.
// For sizes where a dense DirectRpy product is too slow (the benchmarks, the 5e5-point plan test).
inline Errors sampled_rotation_errors(const Configuration& c, const std::vector<double>& f,
                                      const std::vector<double>& tq, const std::vector<double>& u,
                                      const std::vector<double>& w, std::size_t samples) {
  const auto cross = [](const double* a, const double e[3], double out[3]) {
    out[0] = a[1] * e[2] - a[2] * e[1];
    out[1] = a[2] * e[0] - a[0] * e[2];
    out[2] = a[0] * e[1] - a[1] * e[0];
  };
  const std::size_t n = c.a.size();
  double num_u = 0, den_u = 0, num_w = 0, den_w = 0;
  for (std::size_t s = 0; s < std::min(samples, n); ++s) {
    const std::size_t i = (s * 7919) % n;
    double ui[3] = {0, 0, 0}, wi[3] = {0, 0, 0};
    for (std::size_t j = 0; j < n; ++j) {
      const double d[3] = {c.x[3 * i] - c.x[3 * j], c.x[3 * i + 1] - c.x[3 * j + 1], c.x[3 * i + 2] - c.x[3 * j + 2]};
      if (i == j) {
        for (int k = 0; k < 3; ++k) {
          ui[k] += rpy::rpy_self(c.a[i]) * f[3 * i + k];
          wi[k] += rpy::rpy_rotation_self(c.a[i]) * tq[3 * i + k];
        }
        continue;
      }
      rpy::rpy_pair_add(d, c.a[i], c.a[j], 1.0, &f[3 * j], ui);
      const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      const double e[3] = {d[0] / r, d[1] / r, d[2] / r};
      const auto q = rpy::rpy_rotation_scalars(r, c.a[i], c.a[j]);
      double te[3], fe[3];
      cross(&tq[3 * j], e, te);
      cross(&f[3 * j], e, fe);
      const double et = e[0] * tq[3 * j] + e[1] * tq[3 * j + 1] + e[2] * tq[3 * j + 2];
      for (int k = 0; k < 3; ++k) {
        ui[k] += q.ut * te[k];
        wi[k] += q.wf * fe[k] + q.h * tq[3 * j + k] + q.k * et * e[k];
      }
    }
    for (int k = 0; k < 3; ++k) {
      num_u += (u[3 * i + k] - ui[k]) * (u[3 * i + k] - ui[k]);
      den_u += ui[k] * ui[k];
      num_w += (w[3 * i + k] - wi[k]) * (w[3 * i + k] - wi[k]);
      den_w += wi[k] * wi[k];
    }
  }
  return {std::sqrt(num_u / den_u), std::sqrt(num_w / den_w)};
}

}  // namespace rpyfmm::testing
