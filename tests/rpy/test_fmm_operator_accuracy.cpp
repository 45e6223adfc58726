// FmmRpy tolerance sweep against the exact direct operator (DirectRpy, an independent O(N^2)
// pair sum), issue 7's configurations and tolerances. The contract is
// ||U_fmm - U_direct||_2 <= eps ||U_direct||_2; we check it with no slack.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <tuple>
#include <vector>

#include "configurations.hpp"
#include "fmm_rpy_test_util.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"

using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::FmmRpy;
using rpyfmm::rpy::FmmRpyOptions;
using rpyfmm::rpy::Geometry;
namespace t = rpyfmm::testing;
using t::fmm_error;
using t::product;

namespace {


struct Case {
  std::string name;
  t::Configuration config;
};

std::vector<Case> cases() {
  std::vector<Case> v;
  v.push_back({"suspension_phi005", t::random_suspension(1500, 1.0, 0.05, 1)});
  v.push_back({"suspension_phi03", t::random_suspension(1500, 1.0, 0.3, 2)});
  v.push_back({"bimodal_ratio16_phi01", t::bimodal_suspension(1500, 0.25, 16.0, 0.1, 3)});
  {
    auto c = t::random_suspension(1200, 1.0, 0.2, 4);
    for (std::size_t i = 0; i < c.a.size(); ++i) c.a[i] = 0.5 + 1.0 * ((i * 7919) % 100) / 100.0;  // mixed radii
    v.push_back({"polydisperse_phi02", c});
  }
  v.push_back({"touching_chain", t::touching_chain(1000, 1.0, 5)});
  v.push_back({"cylinder_surface", t::cylinder_surface(2000, 0.01, 6)});
  v.push_back({"eight_surface", t::eight_surface(2000, 0.01, 7)});
  v.push_back({"two_far_clusters", t::two_clusters(1000, 0.05, 8)});
  {
    auto c = t::random_suspension(800, 1.0, 0.6, 9);  // dense: many overlapping beads
    v.push_back({"overlapping_beads_phi06", c});
  }
  return v;
}

}  // namespace

class FmmRpyAccuracy : public ::testing::TestWithParam<double> {};

TEST_P(FmmRpyAccuracy, MatchesDirectOnAllConfigurations) {
  const double eps = GetParam();
  // Default leaves, and small leaves (32 points) so that at these CI sizes the far field
  // (plane waves, W/X lists) carries most of the interactions at every tolerance.
  for (const auto& c : cases()) {
    for (int leaf : {0, 32}) {
      const double err = fmm_error(c.config, eps, leaf);
      std::printf("  %-26s eps=%.0e leaf=%-3d relative l2 error %.2e\n", c.name.c_str(), eps, leaf, err);
      EXPECT_LE(err, eps) << c.name << " eps=" << eps << " leaf=" << leaf;
      EXPECT_TRUE(std::isfinite(err)) << c.name;
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Tolerances, FmmRpyAccuracy, ::testing::Values(1e-3, 1e-6, 1e-9));
