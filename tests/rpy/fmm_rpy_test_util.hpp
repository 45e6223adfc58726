// Shared helpers of the FmmRpy tests: one product, and the relative l2 error of
// FmmRpy against the exact DirectRpy on a configuration.
#pragma once

#include <vector>

#include "configurations.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"

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

}  // namespace rpyfmm::testing
