// Shared helpers of the FmmRpy rotation tests: grand-mobility products, random loads of each kind,
// and the relative l2 errors of FmmRpy's U and W against DirectRpy's.
#pragma once

#include <tuple>
#include <vector>

#include "configurations.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"

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

}  // namespace rpyfmm::testing
