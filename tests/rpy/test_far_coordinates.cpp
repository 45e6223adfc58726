// FmmRpy on suspensions far from the origin and at extreme length scales, against DirectRpy.
// It used to return NaN for clouds of extent ~1e188 placed at ~1e200 and for a single particle
// 1e300 away, and velocities 24% wrong for a cloud of extent 1e137 (lost a^2 T terms); tiny
// clouds (extent 1e-130) gave NaN. Contract as in test_fmm_operator.cpp: relative l2 error of U
// <= the requested tolerance, here 1e-6, against the exact product, and no NaN.
#include <gtest/gtest.h>

#include <cmath>
#include <initializer_list>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"

using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::FmmRpy;
using rpyfmm::rpy::FmmRpyOptions;
using rpyfmm::rpy::Geometry;

namespace {

constexpr std::size_t kN = 3000;
constexpr double kTol = 1e-6;
constexpr double kRadius = 0.5;

// Centres on the dyadic grid 2^-6 {0, ..., 4095}^3 (extent just below 64, volume fraction ~0.5%,
// some overlapping pairs): translations by multiples of 2^-6 below 2^46 in magnitude and
// scalings by powers of two (staying within the normal numbers) are exact, so the translated and
// scaled suspensions have exactly the pair geometry of the plain one.
std::vector<double> grid_points(unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> k(0, 4095);
  std::vector<double> x(3 * kN);
  for (double& v : x) v = std::ldexp(double(k(rng)), -6);
  return x;
}

std::vector<double> forces(std::size_t n) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g;
  std::vector<double> f(3 * n);
  for (double& v : f) v = g(rng);
  return f;
}

std::vector<double> product(const rpyfmm::rpy::MobilityOperator& op, const std::vector<double>& f) {
  std::vector<double> u(f.size());
  op.apply(f, u);
  return u;
}

// Relative l2 error, with both vectors divided by the reference's largest entry first so that
// velocities of 1e-300 or 1e300 do not under- or overflow when squared.
double relative_error(const std::vector<double>& u, const std::vector<double>& ref) {
  double scale = 0.0;
  for (double v : ref) scale = std::max(scale, std::abs(v));
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < u.size(); ++i) {
    const double d = u[i] / scale - ref[i] / scale, r = ref[i] / scale;
    num += d * d;
    den += r * r;
  }
  return std::sqrt(num / den);
}

void expect_finite(const std::vector<double>& u, const std::string& what) {
  std::size_t bad = 0;
  for (double v : u) bad += std::isfinite(v) ? 0 : 1;
  EXPECT_EQ(bad, 0u) << what << ": non-finite velocities";
}

FmmRpy make_fmm() {
  return FmmRpy(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = kTol, .leaf_capacity = 50});
}

// The plain suspension translated by `offset` and scaled by 2^e with radius 2^e kRadius; M's exact
// product is 2^-e times the plain one (u0), since M is homogeneous of degree -1 in its lengths.
// Returns the relative error of op's product against it, after checking that it is finite.
double scaled_error(rpyfmm::rpy::MobilityOperator& op, const std::vector<double>& x0, const std::vector<double>& u0,
                    const std::vector<double>& f, int e, double offset) {
  const std::string what = "e = " + std::to_string(e) + ", offset = " + std::to_string(offset);
  std::vector<double> x(x0.size());
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::ldexp(x0[i] + offset, e);
  op.set_positions(x, std::ldexp(kRadius, e));
  const auto u = product(op, f);
  expect_finite(u, what);
  std::vector<double> ref(u0.size());
  for (std::size_t i = 0; i < ref.size(); ++i) ref[i] = std::ldexp(u0[i], -e);
  return relative_error(u, ref);
}

// scaled_error for each exponent and the offsets 0, 2^40, -2^46 (grid units), against DirectRpy's
// product on the plain suspension.
template <class MakeOperator>
void expect_scaled_products(MakeOperator make_operator, std::initializer_list<int> exponents, double tol) {
  const auto x0 = grid_points(3);
  const auto f = forces(kN);
  DirectRpy plain;
  plain.set_positions(x0, kRadius);
  const auto u0 = product(plain, f);
  for (int e : exponents)
    for (double offset : {0.0, std::ldexp(1.0, 40), -std::ldexp(1.0, 46)}) {
      const auto op = make_operator();
      EXPECT_LE(scaled_error(*op, x0, u0, f, e, offset), tol) << "e = " << e << ", offset = " << offset;
    }
}

}  // namespace

// Translated by 2^40 and -2^46 grid units (~2^34 and 2^40 extents away), and scaled by 2^e with
// centres out to ~2^1012: the RPY tensor is homogeneous of degree -1 in its lengths
// (M(s x, s a) = M(x, a) / s), so the exact product is 2^-e that of the plain suspension,
// computed by DirectRpy at ordinary lengths.
TEST(FmmFarCoordinates, TranslatedAndScaledSuspensionsMatchDirect) {
  // e = 450: extent ~1e137 (lost the a^2 T terms: 24% error); 620: extent ~1e188 at ~3e200 and
  // 960 (centres near 2^1012) gave NaN; -600 (extent ~1e-179) and -1000 (~1e-300) gave NaN.
  expect_scaled_products(
      [] {
        return std::make_unique<FmmRpy>(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = kTol, .leaf_capacity = 50});
      },
      {0, 100, 450, 620, 960, -100, -600, -1000}, kTol);
}

// DirectRpy itself at the same extreme scales: extent ~1e137 (its r^2 and a^2 terms stay finite,
// but the FMM's do not), centres near 2^1012 (r^2 overflowed: pair terms lost) and extents 1e-179,
// 1e-300 (r^2 underflowed: pairs taken as coincident, or NaN). In units of the suspension's size
// the evaluation is the plain one scaled by a power of two, so the products agree to rounding
// (1e-13 relative; the scaled and plain sums round identically but for the translation's rounding).
TEST(DirectFarCoordinates, TranslatedAndScaledSuspensionsMatchThePlainProduct) {
  expect_scaled_products([] { return std::make_unique<DirectRpy>(); }, {450, 620, 960, -600, -1000}, 1e-13);
}

// Radii far below the suspension's size (2^-290 of it, within the ratio limit) in a small
// suspension (extent 2^-179), two of them 2^-465 apart (not overlapping): in plain units the
// near kernel's g / r^2 ~ 1/r^3 of that pair overflows (NaN), so the suspension is evaluated in
// units of its size too. Reference: DirectRpy on the suspension scaled by 2^185 (tiny radii
// 2^-285 at distance 2^-280, ordinary otherwise), scaled back exactly.
TEST(FmmFarCoordinates, TinyRadiiInASmallSuspensionMatchDirect) {
  auto x0 = grid_points(3);
  std::vector<double> a0(kN, kRadius);
  for (std::size_t i = 0; i < kN; i += 10) a0[i] = std::ldexp(1.0, -285);
  for (int c = 0; c < 3; ++c) x0[c] = x0[30 + c] = 0.0;  // particles 0 and 10 at the origin ...
  x0[30] = std::ldexp(1.0, -280);                        // ... and 2^-280 apart along x
  const auto f = forces(kN);
  DirectRpy direct;
  direct.set_positions(x0, a0);
  auto ref = product(direct, f);
  constexpr int e = -185;
  std::vector<double> x(x0.size()), a(kN);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::ldexp(x0[i], e);
  for (std::size_t i = 0; i < kN; ++i) a[i] = std::ldexp(a0[i], e);
  for (double& v : ref) v = std::ldexp(v, -e);
  FmmRpy fmm = make_fmm();
  fmm.set_positions(x, a);
  const auto u = product(fmm, f);
  expect_finite(u, "tiny radii");
  // Only particles of ordinary radius: the tiny ones' self mobility (2^285 larger) would hide them.
  std::vector<double> u_big, ref_big;
  for (std::size_t i = 0; i < kN; ++i)
    if (i % 10 != 0)
      for (int c = 0; c < 3; ++c) u_big.push_back(u[3 * i + c]), ref_big.push_back(ref[3 * i + c]);
  EXPECT_LE(relative_error(u_big, ref_big), kTol);
  EXPECT_LE(relative_error(u, ref), kTol);
}

// One particle 1e80 away from a suspension of ordinary lengths: handled (the cloud is scaled by
// 2^-265, the suspension's pair distances stay exact and their squares normal), and equal to
// DirectRpy, whose pairs with the outlier contribute ~1e-80 next to velocities ~0.1.
TEST(FmmFarCoordinates, OutlierFarAwayMatchesDirect) {
  auto x = grid_points(3);
  const auto f = forces(kN);
  for (double far : {1e80, -1e80}) {
    x[3 * 17 + 1] = far;
    DirectRpy direct;
    direct.set_positions(x, kRadius);
    FmmRpy fmm = make_fmm();
    fmm.set_positions(x, kRadius);
    const auto u = product(fmm, f);
    expect_finite(u, "outlier");
    EXPECT_LE(relative_error(u, product(direct, f)), kTol) << far;
  }
}

// One particle 1e300 away from spheres of radius 0.5: no length unit keeps both the outlier's
// squared distance finite and the spheres' squared distances normal (scaled to the outlier's
// size they underflowed and U was 30x wrong; unscaled it was NaN). Refused, naming the particles
// that span the cloud and the limit on the ratio of extent to radius (2^300).
TEST(FmmFarCoordinates, OutlierBeyondTheSizeRatioIsRefused) {
  auto x = grid_points(3);
  x[3 * 17 + 1] = 1e300;
  FmmRpy fmm = make_fmm();
  try {
    fmm.set_positions(x, kRadius);
    ADD_FAILURE() << "accepted an outlier at 1e300 next to spheres of radius 0.5";
  } catch (const rpyfmm::Error& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.code(), rpyfmm::ErrorCode::invalid_input);
    EXPECT_NE(what.find("FmmRpy::set_positions: radius of particle 0 (0.5) is below 2^-300"), std::string::npos)
        << what;
    EXPECT_NE(what.find(" and 17 (y = 1.0000000000000001e+300) span 1e+300 along y"), std::string::npos) << what;
  }
}

// The same limit for a radius tiny next to an ordinary suspension (32 / 1e-100 > 2^300).
TEST(FmmFarCoordinates, RadiusTooSmallForTheCloudIsRefused) {
  const auto x = grid_points(3);
  std::vector<double> a(kN, kRadius);
  a[5] = 1e-100;
  FmmRpy fmm = make_fmm();
  try {
    fmm.set_positions(x, a);
    ADD_FAILURE() << "accepted a radius of 1e-100 in a cloud of extent 64";
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), rpyfmm::ErrorCode::invalid_input);
    EXPECT_NE(std::string(e.what()).find("radius of particle 5 (1e-100) is below 2^-300"), std::string::npos)
        << e.what();
  }
  // The operator is unset after the refusal, and accepts the suspension once the radius is ordinary
  // (1e-80: 32 / 1e-80 < 2^300), matching DirectRpy.
  a[5] = 1e-80;
  fmm.set_positions(x, a);
  DirectRpy direct;
  direct.set_positions(x, a);
  const auto f = forces(kN);
  const auto u = product(fmm, f);
  expect_finite(u, "after refusal");
  EXPECT_LE(relative_error(u, product(direct, f)), kTol);
}
