// The PSE operators at scales they cannot represent: they evaluate in the caller's units (no
// rescaling, unlike DirectRpy and FmmRpy), so a viscosity or radius outside the documented ranges,
// or positions whose distances overflow, must be refused by name instead of giving NaN products
// or errors about internal options.
#include <gtest/gtest.h>

#include <vector>

#include "../common/expect_error.hpp"
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"

namespace {

using rpyfmm::ErrorCode;
using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::pse::OpenPseRpy;
using rpyfmm::rpy::pse::PseRpy;
using rpyfmm_test::expect_error;

const std::vector<double> kPair{4.0, 5.0, 6.0, 9.0, 5.0, 6.0};

// A viscosity of 1e-300 gave NaN velocities ("the product overflows ... scale the forces down").
TEST(HostilePseScales, ViscosityOutsideItsRangeIsRefused) {
  expect_error([] { PseRpy(Geometry::periodic(20.0), 1e-300); }, ErrorCode::invalid_argument,
               "viscosity must lie in [1e-30, 1e+30], got 1e-300");
  expect_error([] { OpenPseRpy(1e300); }, ErrorCode::invalid_argument, "viscosity must lie in [1e-30, 1e+30]");
}

// A radius of 1e300 in a periodic box gave NaN, 1e-300 in open boundaries an error about
// pair_density, an option the caller never set.
TEST(HostilePseScales, RadiusOutsideItsRangeIsRefused) {
  PseRpy periodic(Geometry::periodic(1e150), 1.0);
  expect_error([&] { periodic.set_positions(kPair, 1e148); }, ErrorCode::invalid_argument,
               "radius must lie in [1e-30, 1e+30], got 1e+148");
  OpenPseRpy open(1.0);
  expect_error(
      [&] {
        open.set_positions(std::vector<double>{0, 0, 0, 0, 0, 0}, 1e-300);
      },
      ErrorCode::invalid_argument, "radius must lie in [1e-30, 1e+30], got 1e-300");
  EXPECT_EQ(open.size(), 0u);  // no positions held after the refusal
}

// Open boundaries need a grid over the particles: positions whose distances overflow were
// refused with "open_truncation must be finite", another option the caller never set.
TEST(HostilePseScales, OpenBoundariesRefuseOverflowingDistances) {
  OpenPseRpy open(1.0);
  expect_error(
      [&] {
        open.set_positions(std::vector<double>{-1e308, 0, 0, 1e308, 0, 0}, 1.0);
      },
      ErrorCode::out_of_memory, "distances overflow");
  // The operator stays usable: an ordinary configuration afterwards gives a finite product.
  open.set_positions(kPair, 1.0);
  std::vector<double> f{1, 0, 0, 0, 1, 0}, u(6);
  open.apply(f, u);
  for (double v : u) EXPECT_TRUE(std::isfinite(v));
}

}  // namespace
