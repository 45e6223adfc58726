// FmmRpy's Laplace accuracy rule (fmm_laplace_accuracy.hpp; docs/theory/rpy.md, Sec. 2).
#include "fmm_laplace_accuracy.hpp"

#include <algorithm>
#include <cmath>

#include "rpyfmm/fmm/laplace_fmm.hpp"

namespace rpyfmm::rpy::detail {

namespace {

// Per plane-wave table (3, 6, 9, 12 digits): the nodes and the least order used where the
// tolerance lies within a factor 10 above the table's step. Measured on suspensions of force
// dipoles (pairs of spheres at 2.1 a with opposite forces along their axis, 4000 and 16000
// spheres, the test of tests/rpy/test_fmm_force_dipoles.cpp) against DirectRpy: with the tables'
// own 12 / 20 / 29 / 37 nodes the relative error of U reached 1.37 / 2.67 / 2.31 / 4.1 times the
// tolerance at 1e-3 / 1e-6 / 1e-9 / 1e-12 (0.89 at 3e-6, 0.46 at 3e-3, at most 0.09 at 3e-5 and
// 3e-8); with these 0.36 / 0.29 / 0.27 / 0.71 (W with torques 0.02 at 1e-3 and 1e-6). The cost at
// N = 1e5 (random suspension, one thread, Intel Xeon with AVX-512, commit f7a2d14, 2026-12-07):
// 1.06x at 1e-3 and 1.18x at 1e-6, against 1.5x for the next table. LaplaceFmm's own defaults
// near the steps (fmm_order_for, for its Hessian) now take the same nodes and orders 10 / 22 / 32 /
// 46; the larger of the two orders applies.
struct Boost {
  int nodes, order;
};

Boost boost_for(int digits) {
  switch (digits) {
    case 3:
      return {14, 10};
    case 6:
      return {23, 20};
    case 9:
      return {32, 34};
    default:
      return {39, 46};
  }
}

}  // namespace

LaplaceAccuracy laplace_accuracy_for(double rpy_tolerance) {
  LaplaceAccuracy accuracy{rpy_tolerance, 0, 0};
  const int digits = fmm::fmm_table_digits_for(rpy_tolerance);
  // The table's step 10^-digits; tolerances 10x above it and more keep the table's defaults.
  if (rpy_tolerance >= 10.0 * std::pow(10.0, -digits)) return accuracy;
  const Boost boost = boost_for(digits);
  accuracy.planewave_nodes = boost.nodes;
  accuracy.order = std::max(fmm::fmm_order_for(rpy_tolerance), boost.order);
  return accuracy;
}

}  // namespace rpyfmm::rpy::detail
