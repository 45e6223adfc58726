// PSE: bad input is rejected with rpyfmm::Error naming the problem, before allocation.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"

using namespace rpyfmm;
using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

namespace {

template <class Fn>
void expect_error(Fn&& fn, ErrorCode code, const std::string& words) {
  try {
    fn();
    ADD_FAILURE() << "no error thrown, expected: " << words;
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
  }
}

const std::vector<double> kTwo = {1.0, 1.0, 1.0, 4.0, 4.0, 4.0};

}  // namespace

TEST(PseBadInput, OpenGeometryRejected) {
  expect_error([] { PseRpy op(Geometry::open(), 1.0); }, ErrorCode::not_supported, "periodic");
}

TEST(PseBadInput, ToleranceOutOfRange) {
  for (double eps : {0.0, -1e-3, 0.1, 0.5, 1e-9, std::numeric_limits<double>::quiet_NaN()}) {
    PseOptions o;
    o.tolerance = eps;
    expect_error([&] { PseRpy op(Geometry::periodic(20.0), 1.0, o); }, ErrorCode::invalid_argument, "tolerance");
  }
}

TEST(PseBadInput, UnequalRadiiNotSupported) {
  PseRpy op(Geometry::periodic(20.0), 1.0);
  const std::vector<double> radii = {1.0, 1.5};
  expect_error([&] { op.set_positions(kTwo, radii); }, ErrorCode::not_supported, "equal radii");
}

TEST(PseBadInput, BoxSmallerThanTwiceTheCutoff) {
  PseOptions o;
  o.xi = 0.5;  // r_cut ~ 5.7 a at 1e-3
  PseRpy op(Geometry::periodic(10.0, 20.0, 20.0), 1.0, o);
  expect_error([&] { op.set_positions(kTwo, 1.0); }, ErrorCode::invalid_argument, "2 r_cut");
}

// A failed plan leaves no half-built operator behind: products refuse with a message (rather than
// reach the discarded FFT/real-space parts), and a later good call recovers.
TEST(PseBadInput, FailedPlanIsNotUsable) {
  PseOptions o;
  o.xi = 0.5;
  PseRpy op(Geometry::periodic(20.0), 1.0, o);
  std::vector<double> u(6);
  const std::vector<double> f = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0};
  op.set_positions(kTwo, 1.0);
  op.apply(f, u);
  expect_error([&] { op.set_positions(kTwo, 4.0); }, ErrorCode::invalid_argument, "2 r_cut");  // r_cut ~ 23
  expect_error([&] { op.apply(f, u); }, ErrorCode::invalid_input, "positions not set");
  expect_error([&] { op.sample(1, 2, u); }, ErrorCode::invalid_input, "positions not set");
  EXPECT_EQ(op.size(), 0u);
  op.set_positions(kTwo, 1.0);
  op.apply(f, u);
  EXPECT_GT(u[0], 0.0);
}

TEST(PseBadInput, BoxSmallerThanTheParticle) {
  PseRpy op(Geometry::periodic(1.5), 1.0);
  expect_error(
      [&] {
        op.set_positions(std::vector<double>{0.1, 0.1, 0.1}, 1.0);
      },
      ErrorCode::invalid_argument, "particle diameter");
}

TEST(PseBadInput, XiTooSmall) {
  PseOptions o;
  o.xi = 0.01;
  PseRpy op(Geometry::periodic(400.0), 1.0, o);
  expect_error([&] { op.set_positions(kTwo, 1.0); }, ErrorCode::invalid_argument, "xi a");
}

TEST(PseBadInput, GridOverMemoryLimitBeforeAllocation) {
  PseOptions o;
  o.tolerance = 1e-8;
  o.xi = 1.0;
  o.max_memory_bytes = std::size_t{1} << 20;  // 1 MiB
  PseRpy op(Geometry::periodic(100.0), 1.0, o);
  expect_error([&] { op.set_positions(kTwo, 1.0); }, ErrorCode::out_of_memory, "max_memory_bytes");
  // A huge box with the default limit: refused by the same check (no attempt to allocate).
  PseOptions big;
  big.tolerance = 1e-8;
  big.xi = 1.0;
  PseRpy huge(Geometry::periodic(1e5), 1.0, big);
  expect_error([&] { huge.set_positions(kTwo, 1.0); }, ErrorCode::out_of_memory, "grid");
}

TEST(PseBadInput, NanPositionsAndForces) {
  PseRpy op(Geometry::periodic(20.0), 1.0);
  std::vector<double> x = kTwo;
  x[4] = std::numeric_limits<double>::quiet_NaN();
  expect_error([&] { op.set_positions(x, 1.0); }, ErrorCode::invalid_input, "NaN");
  op.set_positions(kTwo, 1.0);
  std::vector<double> f(6, 0.0), u(6);
  f[2] = std::numeric_limits<double>::infinity();
  expect_error([&] { op.apply(f, u); }, ErrorCode::invalid_input, "infinite");
  std::vector<double> bad(5);
  expect_error([&] { op.apply(bad, u); }, ErrorCode::invalid_input, "forces");
}

TEST(PseBadInput, WindowWiderThanGridOverride) {
  PseOptions o;
  o.xi = 1.0;
  o.grid = {8, 8, 8};
  o.support = 12;
  PseRpy op(Geometry::periodic(12.0), 1.0, o);
  expect_error([&] { op.set_positions(kTwo, 1.0); }, ErrorCode::invalid_argument, "wider than the grid");
}

TEST(PseBadInput, WindowShapeOutOfRange) {
  // window_eta: 0 (automatic) or in (0, 1); anything else is refused when the plan is made.
  for (double eta : {-0.1, 1.0, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    PseOptions o;
    o.window_eta = eta;
    PseRpy op(Geometry::periodic(20.0), 1.0, o);
    expect_error([&] { op.set_positions(kTwo, 1.0); }, ErrorCode::invalid_argument, "window_eta");
  }
}

TEST(PseBadInput, ApplyBeforePositions) {
  PseRpy op(Geometry::periodic(20.0), 1.0);
  std::vector<double> f(6, 0.0), u(6);
  expect_error([&] { op.apply(f, u); }, ErrorCode::invalid_input, "positions not set");
}
