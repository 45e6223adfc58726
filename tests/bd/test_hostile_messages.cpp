// Error messages print the offending number as %g does (format_number), so that a tiny or
// negative value stays readable: std::to_string(double) printed -1e-10 as "-0.000000", a PSE
// tolerance of 1e-9 as "0.000000" and 0.99999999 as "1.000000", which contradicted the range
// stated beside it (docs/safety-limits.md, "Command-line options").
#include <gtest/gtest.h>

#include <vector>

#include "../common/expect_error.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"

namespace {

using rpyfmm::ErrorCode;
using rpyfmm::rpy::Geometry;
using rpyfmm_test::expect_error;

TEST(HostileMessages, NumbersArePrintedAsTheyWereGiven) {
  expect_error([] { rpyfmm::fmm::LaplaceFmm({.min_leaf_side = -1e-10}); }, ErrorCode::invalid_argument,
               "min_leaf_side must be finite and >= 0, got -1e-10");
  expect_error([] { rpyfmm::fmm::LaplaceFmm({.root_scale = 1e-7}); }, ErrorCode::invalid_argument,
               "root_scale must be in [1, 8], got 1e-07");
  expect_error([] { rpyfmm::rpy::pse::PseRpy(Geometry::periodic(20.0), 1.0, {.tolerance = 1e-9}); },
               ErrorCode::invalid_argument, "tolerance must lie in [1e-8, 0.1), got 1e-09");
  expect_error([] { rpyfmm::rpy::pse::OpenPseRpy(1.0, {.xi = -1e-10}); }, ErrorCode::invalid_argument,
               "xi must be >= 0 (0 = automatic), got -1e-10");
  rpyfmm::rpy::DirectRpy direct;
  expect_error(
      [&] {
        direct.set_positions(std::vector<double>{0, 0, 0, 3, 0, 0}, std::vector<double>{1.0, -1e-10});
      },
      ErrorCode::invalid_argument, "radius of particle 1 must be finite and > 0, got -1e-10");
  expect_error([] { rpyfmm::bd::NeighbourList(Geometry::open(), 1.0, {.skin = -1e-10}); }, ErrorCode::invalid_argument,
               "skin must be finite and >= 0, got -1e-10");
}

// Per-particle radii follow the rule of one common radius: a subnormal radius is refused by name
// (its mobility overflowed, reported as "scale the forces down").
TEST(HostileMessages, SubnormalPerParticleRadiusIsRefused) {
  rpyfmm::rpy::DirectRpy direct;
  expect_error(
      [&] {
        direct.set_positions(std::vector<double>{0, 0, 0, 3, 0, 0}, std::vector<double>{1.0, 5e-320});
      },
      ErrorCode::invalid_argument, "radius of particle 1 must be a normal number");
}

}  // namespace
