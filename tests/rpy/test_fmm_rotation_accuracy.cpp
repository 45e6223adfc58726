// FmmRpy's grand mobility with rotation against DirectRpy over the translational accuracy test's
// hard configurations and tolerances 1e-3, 1e-6, 1e-9: ||U_fmm - U_direct|| <= eps ||U_direct||
// and the same for W, for forces alone, torques alone and both, with no slack (~10 s in Release,
// too slow under sanitizers, hence the `slow` label); and the plan of products with torques on
// 5e5 points (~2 min).
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "configurations.hpp"
#include "fmm_rotation_test_util.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"

namespace t = rpyfmm::testing;
using t::Errors;
using t::Loads;
using t::Motion;
using t::rotation_errors;

// The tolerance contract with no slack, at the ends and the middle of the range.
class FmmRotationAccuracy : public ::testing::TestWithParam<double> {};

TEST_P(FmmRotationAccuracy, WithinToleranceOnHardConfigurations) {
  const double eps = GetParam();
  // Automatic leaves, and leaves of 24 points that hand most pairs to the far field.
  for (int leaf : {0, 24})
    for (const t::Case& c : t::accuracy_cases())
      for (Loads kind : {Loads::forces, Loads::torques, Loads::both}) {
        const Errors e = rotation_errors(c.config, eps, kind, leaf);
        const char* load = kind == Loads::forces ? "forces" : kind == Loads::torques ? "torques" : "both";
        std::printf("eps %.0e leaf %2d %-24s %-7s  U %.2e  W %.2e\n", eps, leaf, c.name.c_str(), load, e.u, e.w);
        EXPECT_LE(e.u, eps) << c.name << " " << load << " leaf " << leaf;
        EXPECT_LE(e.w, eps) << c.name << " " << load << " leaf " << leaf;
      }
}

INSTANTIATE_TEST_SUITE_P(Tolerances, FmmRotationAccuracy, ::testing::Values(1e-3, 1e-6, 1e-9));

// Automatic leaves at 6 digits from 5e5 points (fmm_operator.cpp, rotation_plan_rule): products
// with torques run on their own plan, built on the first of them after set_positions (its time in
// rpy_rotation_plan) and kept until the next; repeated products agree bit for bit; U and W meet
// the tolerance against exact sums at 200 sampled particles (the relative l2 error over all
// particles is bounded by eps; measured on this plan 1.7e-7 and 4.8e-8 at 1e6 points, so the
// 200-particle estimate, within a few per cent of it, stays below eps with a wide margin).
TEST(FmmRotationPlan, BuiltOnFirstUseAndKeptUntilTheNextConfiguration) {
  const t::Configuration c = t::random_suspension(500000, 1.0, 0.1, 23);
  const auto [f, tq] = t::loads(c, Loads::both, 5);
  rpyfmm::rpy::FmmRpy op(rpyfmm::rpy::Geometry::open(), 1.0, {.tolerance = 1e-6});
  op.set_positions(c.x, c.a);
  EXPECT_EQ(op.rotation_laplace_plan(), nullptr);
  const Motion first = t::grand_product(op, f, tq);
  const auto* plan = op.rotation_laplace_plan();
  ASSERT_NE(plan, nullptr);
  EXPECT_NE(plan, op.laplace_plan());
  EXPECT_GT(op.last_timings()["rpy_rotation_plan"], 0.0);
  const Motion again = t::grand_product(op, f, tq);
  EXPECT_EQ(op.rotation_laplace_plan(), plan);
  EXPECT_LT(op.last_timings()["rpy_rotation_plan"], 1e-2);  // only the look-up
  EXPECT_EQ(first.u, again.u);
  EXPECT_EQ(first.w, again.w);
  const Errors e = t::sampled_rotation_errors(c, f, tq, first.u, first.w, 200);
  std::printf("5e5 points, plan of products with torques: U %.2e  W %.2e (200 sampled particles)\n", e.u, e.w);
  EXPECT_LE(e.u, 1e-6);
  EXPECT_LE(e.w, 1e-6);
  op.set_positions(c.x, c.a);
  EXPECT_EQ(op.rotation_laplace_plan(), nullptr);
}
