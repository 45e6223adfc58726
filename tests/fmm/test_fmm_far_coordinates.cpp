// LaplaceFmm on clouds far from the origin and at the ends of the length scales it accepts,
// against the plain double-loop reference of fmm_test_util.hpp; clouds beyond them are refused
// with an error naming the two points that span them (they used to give NaN or silently wrong
// outputs: relative error 1 in the gradient at extent 2^406, NaN at 2^-394).
// Contract as in test_fmm_accuracy.cpp: relative l2 error <= eps per output kind.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "fmm_test_util.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

namespace fmm = rpyfmm::fmm;

namespace {

constexpr std::size_t kN = 3000;

// Points on the dyadic grid 2^-6 {0, ..., 4095}^3 (extent just below 64 = 2^6): a translation by a
// multiple of 2^-6 below 2^46 in magnitude keeps every coordinate exact (at most 53 bits), and so
// does a scaling by a power of two that stays within the normal numbers. The pair differences,
// and with them the reference sums, are then exactly those of the untranslated, unscaled grid.
std::vector<double> grid_points(std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> k(0, 4095);
  std::vector<double> x(3 * n);
  for (double& v : x) v = std::ldexp(double(k(rng)), -6);
  return x;
}

fmm::FmmOptions options(double eps = 1e-6) {
  fmm::FmmOptions o;
  o.tolerance = eps;
  o.leaf_capacity = 50;  // a tree of several levels: far field through expansions
  return o;
}

// Outputs of x0 2^e + offset 2^e, multiplied back by the powers of 2^e that the potential
// (length^-1), gradient (^-2) and Hessian (^-3) carry: exact unless they under- or overflow.
std::vector<double> scaled_run(const std::vector<double>& x0, const std::vector<double>& q, int e, double offset,
                               double eps) {
  std::vector<double> x(x0.size());
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::ldexp(x0[i] + offset, e);
  fmm::LaplaceFmm f(options(eps));
  f.set_points(x);
  std::vector<double> r(kN * 10);
  f.evaluate(q, 1, fmm::potential | fmm::gradient | fmm::hessian, r);
  for (double v : r) EXPECT_TRUE(std::isfinite(v)) << "e = " << e << ", offset = " << offset;
  for (std::size_t i = 0; i < kN; ++i)
    for (int c = 0; c < 10; ++c) r[10 * i + c] = std::ldexp(r[10 * i + c], (c == 0 ? 1 : c < 4 ? 2 : 3) * e);
  return r;
}

void expect_accurate(const std::vector<double>& r, const std::vector<double>& ref, double eps,
                     const std::string& what) {
  std::vector<std::size_t> all(kN);
  for (std::size_t i = 0; i < kN; ++i) all[i] = i;
  EXPECT_LE(fmmtest::rel_l2(r, kN, ref, all, 0, 0, 1), eps) << what << ": potential";
  EXPECT_LE(fmmtest::rel_l2(r, kN, ref, all, 0, 1, 4), eps) << what << ": gradient";
  EXPECT_LE(fmmtest::rel_l2(r, kN, ref, all, 0, 4, 10), eps) << what << ": Hessian";
}

std::string refusal(const std::vector<double>& x) {
  fmm::LaplaceFmm f(options());
  try {
    f.set_points(x);
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), rpyfmm::ErrorCode::invalid_input);
    return e.what();
  }
  return "";
}

}  // namespace

// Far from the origin (2^40 and -2^46 grid units of 2^-6, i.e. 2^34 and 2^40 cloud extents
// away), and scaled to the ends of the accepted extents 2^-150 ... 2^200: the same accuracy as
// the plain cloud, against the reference of the plain grid.
TEST(FmmFarCoordinates, TranslatedAndScaledCloudsKeepTheirAccuracy) {
  const auto x0 = grid_points(kN, 11);
  const auto q = fmmtest::charges(kN, 1, 5);
  const auto ref = fmmtest::direct(x0, q, 1, {});
  for (double eps : {1e-6, 1e-12})
    for (double offset : {0.0, std::ldexp(1.0, 40), -std::ldexp(1.0, 46)}) {
      // e = 194: extent just below 2^200 (4095/64 < 2^6); e = -155: just above 2^-150.
      for (int e : {0, 194, -155}) {
        expect_accurate(
            scaled_run(x0, q, e, offset, eps), ref, eps,
            "eps = " + std::to_string(eps) + ", e = " + std::to_string(e) + ", offset = " + std::to_string(offset));
      }
    }
}

// Deep trees at both ends of the range: two clusters of size 1e-8 at distance sqrt(3) give 31
// levels, leaves down to 2^-31 of the extent (at extent 2^-188 their Hessians were NaN).
// 6 digits only: at 12 the clusters' coordinates near 1 bound any method (fmm_test_util.hpp).
TEST(FmmFarCoordinates, DeepTreesAtTheEndsOfTheRange) {
  const std::size_t n = 4000;
  const auto x0 = fmmtest::two_clusters(n, 3, 1e-8);
  const auto q = fmmtest::charges(n, 1, 5);
  const auto ref = fmmtest::direct(x0, q, 1, {});
  std::vector<std::size_t> all(n);
  for (std::size_t i = 0; i < n; ++i) all[i] = i;
  for (int e : {-149, 198}) {
    std::vector<double> x(x0.size());
    for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::ldexp(x0[i], e);
    fmm::FmmOptions o = options(1e-6);
    o.leaf_capacity = 20;
    fmm::LaplaceFmm f(o);
    f.set_points(x);
    EXPECT_GE(f.stats().levels, 25) << "e = " << e;
    std::vector<double> r(n * 10);
    f.evaluate(q, 1, fmm::potential | fmm::gradient | fmm::hessian, r);
    for (double v : r) ASSERT_TRUE(std::isfinite(v)) << "e = " << e;
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 10; ++c) r[10 * i + c] = std::ldexp(r[10 * i + c], (c == 0 ? 1 : c < 4 ? 2 : 3) * e);
    EXPECT_LE(fmmtest::rel_l2(r, n, ref, all, 0, 0, 1), 1e-6) << "e = " << e << ": potential";
    EXPECT_LE(fmmtest::rel_l2(r, n, ref, all, 0, 1, 4), 1e-6) << "e = " << e << ": gradient";
    EXPECT_LE(fmmtest::rel_l2(r, n, ref, all, 0, 4, 10), 1e-6) << "e = " << e << ": Hessian";
  }
}

TEST(FmmFarCoordinates, CloudsBeyondTheExtentLimitsAreRefused) {
  const auto x0 = grid_points(kN, 11);
  for (int e : {200, 400, 900, -157, -400, -900}) {
    std::vector<double> x(x0.size());
    for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::ldexp(x0[i], e);
    const std::string what = refusal(x);
    EXPECT_NE(what.find("LaplaceFmm::set_points: source "), std::string::npos) << "e = " << e << ": " << what;
    EXPECT_NE(what.find("2^-150 ... 2^200"), std::string::npos) << what;
  }
  // One outlier at 1e300 (an extent whose square overflows): refused, naming it.
  std::vector<double> x = x0;
  x[3 * 17 + 1] = 1e300;
  const std::string what = refusal(x);
  EXPECT_NE(what.find("source 17 (y = 1.0000000000000001e+300)"), std::string::npos) << what;
  // Targets are checked with the sources.
  fmm::LaplaceFmm f(options());
  const std::vector<double> far_target = {0.0, 0.0, -1e300};
  try {
    f.set_points(x0, far_target);
    ADD_FAILURE() << "a target 1e300 away was accepted";
  } catch (const rpyfmm::Error& e) {
    EXPECT_NE(std::string(e.what()).find("target 0 (z = -1.0000000000000001e+300)"), std::string::npos) << e.what();
  }
}

// Extent 0 is accepted anywhere: coinciding points far out (the pairs at distance 0 are skipped,
// as in the reference) give zeros, not NaN; and so are tiny clouds that a leaf side larger than
// their extent keeps in one box (summed directly).
TEST(FmmFarCoordinates, CoincidentAndUnsplitTinyCloudsAreSummedDirectly) {
  const std::vector<double> same = {1e300, -1e300, 3e-300, 1e300, -1e300, 3e-300, 1e300, -1e300, 3e-300};
  fmm::LaplaceFmm f(options());
  f.set_points(same);
  std::vector<double> r(3 * 10), q = {1.0, 2.0, 3.0};
  f.evaluate(q, 1, fmm::potential | fmm::gradient | fmm::hessian, r);
  for (double v : r) EXPECT_EQ(v, 0.0);

  const auto x0 = grid_points(40, 3);
  std::vector<double> x(x0.size());
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = std::ldexp(x0[i], -400);  // extent ~2^-394
  fmm::FmmOptions o = options();
  o.min_leaf_side = 1.0;
  fmm::LaplaceFmm g(o);
  g.set_points(x);
  const auto q40 = fmmtest::charges(40, 1, 2);
  std::vector<double> out(40 * 10);
  g.evaluate(q40, 1, fmm::potential, out);
  const auto ref = fmmtest::direct(x0, q40, 1, {});
  for (std::size_t i = 0; i < 40; ++i)
    EXPECT_NEAR(std::ldexp(out[10 * i], -400), ref[10 * i], 1e-13 * std::abs(ref[10 * i])) << i;
}
