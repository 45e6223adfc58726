// FmmOptions::planewave_nodes: the plane-wave tables between the four steps (docs/theory/fmm.md,
// Sec. 7). Each table of more nodes, with an order to match, must be at least as accurate as the
// step below it against the direct sum, the plan must report the nodes it used, and values outside
// [kMinPlaneWaveNodes, kMaxPlaneWaveNodes] must be refused with a message naming the option.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "fmm_accuracy_util.hpp"
#include "fmm_test_util.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

using rpyfmm::fmm::FmmOptions;
using rpyfmm::fmm::LaplaceFmm;

namespace {

// Relative l2 errors of potential, gradient and Hessian (the worst of them) at the sources of a
// uniform cube (leaf 20: a deep tree, every list and the M2L run), for one table and order.
double worst_error(int nodes, int order, double tolerance) {
  const auto x = fmmtest::cube(3000, 41);
  FmmOptions o;
  o.tolerance = tolerance;
  o.leaf_capacity = 20;
  o.order = order;
  o.planewave_nodes = nodes;
  LaplaceFmm fmm(o);
  fmm.set_points(x);
  EXPECT_EQ(fmm.stats().nlams, nodes == 0 ? rpyfmm::fmm::fmm_planewave_nodes_for(tolerance) : nodes);
  const auto q = fmmtest::charges(3000, 1, 7);
  std::vector<double> out(3000 * 10);
  fmm.evaluate(q, 1, rpyfmm::fmm::all_outputs, out);
  const auto which = fmmtest::sample(3000, 400, 3);
  const auto ref = fmmtest::direct(x, q, 1, {}, which);
  return std::max({fmmtest::rel_l2(out, 3000, ref, which, 0, 0, 1), fmmtest::rel_l2(out, 3000, ref, which, 0, 1, 4),
                   fmmtest::rel_l2(out, 3000, ref, which, 0, 4, 10)});
}

}  // namespace

// The tables FmmRpy takes just above the steps (rpy/src/fmm_laplace_accuracy.cpp; LaplaceFmm's
// own choice there, fmm_planewave_nodes_for) and one of each between: within the step's
// tolerance, and no less accurate than the step's own table (12 / 20 / 29 / 37 nodes with the
// capped order 9 / 18 / 32 / 42, fmm_order_for 10x above the step).
TEST(FmmPlaneWaveNodes, TablesBetweenTheStepsMeetTheirStep) {
  struct Case {
    double tolerance;
    int nodes, order;
    int step_nodes, step_order;
  };
  for (const Case c : {Case{1e-3, 14, 10, 12, 9}, Case{1e-3, 17, 12, 12, 9}, Case{1e-6, 23, 20, 20, 18},
                       Case{1e-6, 26, 22, 20, 18}, Case{1e-9, 32, 34, 29, 32}, Case{1e-12, 39, 46, 37, 42}}) {
    const double step = worst_error(c.step_nodes, c.step_order, c.tolerance),
                 between = worst_error(c.nodes, c.order, c.tolerance);
    std::printf("tolerance %.0e: %2d nodes (the step's) %.2e, %d nodes order %d %.2e\n", c.tolerance, c.step_nodes,
                step, c.nodes, c.order, between);
    EXPECT_LE(between, c.tolerance) << c.nodes << " nodes";
    EXPECT_LE(between, step) << c.nodes << " nodes";
  }
}

TEST(FmmPlaneWaveNodes, OutOfRangeIsRefused) {
  const auto x = fmmtest::cube(100, 1);
  for (int nodes : {-1, 1, rpyfmm::fmm::kMinPlaneWaveNodes - 1, rpyfmm::fmm::kMaxPlaneWaveNodes + 1, 1000}) {
    FmmOptions o;
    o.planewave_nodes = nodes;
    try {
      LaplaceFmm fmm(o);
      fmm.set_points(x);
      ADD_FAILURE() << nodes << " nodes accepted";
    } catch (const rpyfmm::Error& e) {
      EXPECT_NE(std::string(e.what()).find("planewave_nodes"), std::string::npos) << e.what();
    }
  }
}
