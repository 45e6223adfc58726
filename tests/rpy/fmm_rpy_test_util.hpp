// Shared helpers of the FmmRpy tests (and of bench/rpy): one product, the relative l2 error of
// FmmRpy against the exact DirectRpy on a configuration, and against exact RPY sums at sampled
// rows (for sizes where a whole direct product is too dear).
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include "configurations.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"

namespace rpyfmm::testing {

inline std::vector<double> product(const rpy::MobilityOperator& op, const std::vector<double>& f) {
  std::vector<double> u(f.size());
  op.apply(f, u);
  return u;
}

/// ||U_fmm - U_direct|| / ||U_direct|| for random forces (fixed seed).
inline double fmm_error(const Configuration& c, double eps, int leaf_capacity = 0, unsigned seed = 7) {
  rpy::DirectRpy direct;
  rpy::FmmRpy fast(rpy::Geometry::open(), 1.0, rpy::FmmRpyOptions{.tolerance = eps, .leaf_capacity = leaf_capacity});
  direct.set_positions(c.x, c.a);
  fast.set_positions(c.x, c.a);
  const auto f = random_vector(c.x.size(), seed);
  return relative_l2(product(fast, f), product(direct, f));
}

/// Relative l2 error of the velocities u (3N) over `samples` rows i = (s * 7919) mod N, against
/// exact RPY sums over all sources (rpy_self, rpy_pair_add: independent of the operators).
inline double sampled_error(const Configuration& c, const std::vector<double>& f, const std::vector<double>& u,
                            std::size_t samples) {
  const std::size_t n = c.a.size();
  double num = 0.0, den = 0.0;
  for (std::size_t s = 0; s < std::min(samples, n); ++s) {
    const std::size_t i = (s * 7919) % n;
    double ui[3] = {0.0, 0.0, 0.0};
    for (std::size_t j = 0; j < n; ++j) {
      const double d[3] = {c.x[3 * i] - c.x[3 * j], c.x[3 * i + 1] - c.x[3 * j + 1], c.x[3 * i + 2] - c.x[3 * j + 2]};
      if (i == j) {
        for (int k = 0; k < 3; ++k) ui[k] += rpy::rpy_self(c.a[i]) * f[3 * i + k];
      } else {
        rpy::rpy_pair_add(d, c.a[i], c.a[j], 1.0, &f[3 * j], ui);
      }
    }
    for (int k = 0; k < 3; ++k) {
      num += (u[3 * i + k] - ui[k]) * (u[3 * i + k] - ui[k]);
      den += ui[k] * ui[k];
    }
  }
  return std::sqrt(num / den);
}

}  // namespace rpyfmm::testing
