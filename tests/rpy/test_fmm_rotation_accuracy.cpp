// FmmRpy's grand mobility with rotation against DirectRpy over the translational accuracy test's
// hard configurations and tolerances 1e-3, 1e-6, 1e-9: ||U_fmm - U_direct|| <= eps ||U_direct||
// and the same for W, for forces alone, torques alone and both, with no slack (~10 s in Release,
// too slow under sanitizers, hence the `slow` label).
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "configurations.hpp"
#include "fmm_rotation_test_util.hpp"

namespace t = rpyfmm::testing;
using t::Errors;
using t::Loads;
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
