// FmmRpy's grand mobility with rotation, [U; W] = M [F; T], against the exact direct operator
// (DirectRpy's pair sums of rpy_rotation_kernel.hpp, an independent O(N^2) evaluation).
// The contract: ||U_fmm - U_direct|| <= eps ||U_direct|| and the same for W, for each load case
// (forces alone, torques alone, both), on the translational tests' hard configurations.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "configurations.hpp"
#include "fmm_rotation_test_util.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "simd_levels.hpp"

using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::FmmRpy;
using rpyfmm::rpy::FmmRpyOptions;
using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::MobilityOperator;
namespace t = rpyfmm::testing;
using t::Errors;
using t::grand_product;
using t::Loads;
using t::loads;
using t::Motion;
using t::rotation_errors;

TEST(FmmRotation, SupportsRotation) {
  EXPECT_TRUE(FmmRpy().supports_rotation());
}

// Pairs in every regime are near-field pairs: the FMM operator must reproduce the exact couplings
// to rounding (touching, partial overlap of equal and different radii, one inside another,
// coincident centres, and a single sphere's self mobilities).
TEST(FmmRotation, PairsInEveryRegimeAreExact) {
  const std::vector<std::tuple<double, double, double>> pairs = {{2.0, 1.0, 1.0}, {1.3, 1.0, 1.0}, {1.1, 0.5, 1.0},
                                                                 {0.2, 1.0, 3.0}, {0.2, 3.0, 1.0}, {0.0, 1.0, 1.0},
                                                                 {0.0, 1.0, 2.0}, {5.0, 1.0, 2.0}};
  for (auto [r, a1, a2] : pairs) {
    const t::Configuration c{{0.1, -0.2, 0.3, 0.1 + 0.6 * r, -0.2 + 0.8 * r, 0.3}, {a1, a2}};
    DirectRpy direct;
    FmmRpy fast;
    direct.set_positions(c.x, c.a);
    fast.set_positions(c.x, c.a);
    for (Loads kind : {Loads::forces, Loads::torques, Loads::both}) {
      // Absolute differences against the size of the whole motion: some parts vanish exactly
      // (coincident centres do not couple translation and rotation).
      const auto [f, tq] = loads(c, kind, 11);
      const Motion exact = grand_product(direct, f, tq), approx = grand_product(fast, f, tq);
      double scale = 0.0;
      for (std::size_t k = 0; k < 6; ++k) scale = std::max({scale, std::abs(exact.u[k]), std::abs(exact.w[k])});
      for (std::size_t k = 0; k < 6; ++k) {
        EXPECT_NEAR(approx.u[k], exact.u[k], 1e-13 * scale) << "r=" << r << " a=" << a1 << "," << a2;
        EXPECT_NEAR(approx.w[k], exact.w[k], 1e-13 * scale) << "r=" << r << " a=" << a1 << "," << a2;
      }
    }
  }
  FmmRpy one(Geometry::open(), 2.0);
  one.set_positions(std::vector<double>{1, 2, 3}, 0.5);
  const std::vector<double> f1 = {1, -2, 3}, t1 = {0.5, 0.25, -1};
  const Motion m = grand_product(one, f1, t1);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(m.u[k], f1[k] / (6 * M_PI * 2.0 * 0.5), 1e-15);
    EXPECT_NEAR(m.w[k], t1[k] / (8 * M_PI * 2.0 * 0.125), 1e-15);
  }
}

// The tolerance contract on one hard configuration (radius ratio 16) in the middle of the range;
// test_fmm_rotation_accuracy sweeps all configurations and tolerances.
TEST(FmmRotation, WithinToleranceOnABimodalSuspension) {
  const t::Configuration c = t::bimodal_suspension(1200, 0.25, 16.0, 0.1, 3);
  for (Loads kind : {Loads::forces, Loads::torques, Loads::both}) {
    const Errors e = rotation_errors(c, 1e-6, kind, 24);  // small leaves: most pairs in the far field
    EXPECT_LE(e.u, 1e-6) << static_cast<int>(kind);
    EXPECT_LE(e.w, 1e-6) << static_cast<int>(kind);
  }
}

// With T = 0 the velocities are the translational product (an explicit leaf capacity: both kinds
// of product share one plan), and repeated products agree bit for bit whatever was called in
// between (translational products, other loads).
TEST(FmmRotation, RepeatableAndConsistentWithTheTranslationalProduct) {
  const t::Configuration c = t::bimodal_suspension(1500, 0.25, 4.0, 0.2, 21);
  FmmRpy op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-6, .leaf_capacity = 400});
  op.set_positions(c.x, c.a);
  const auto [f, tq] = loads(c, Loads::both, 3);
  const Motion first = grand_product(op, f, tq);
  std::vector<double> u_tt(f.size());
  op.apply(f, u_tt);
  const Motion other = grand_product(op, tq, f);
  (void)other;
  const Motion again = grand_product(op, f, tq);
  EXPECT_EQ(first.u, again.u);
  EXPECT_EQ(first.w, again.w);
  const Motion forces_only = grand_product(op, f, std::vector<double>(f.size(), 0.0));
  EXPECT_LE(t::relative_l2(forces_only.u, u_tt), 1e-14);
}

TEST(FmmRotation, SameResultForAnyThreadCount) {
  const t::Configuration c = t::random_suspension(3000, 1.0, 0.3, 22);
  FmmRpy op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-3});
  op.set_positions(c.x, c.a);
  const auto [f, tq] = loads(c, Loads::both, 4);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const Motion one = grand_product(op, f, tq);
  omp_set_num_threads(3);
  const Motion three = grand_product(op, f, tq);
  omp_set_num_threads(threads);
  EXPECT_EQ(one.u, three.u);
  EXPECT_EQ(one.w, three.w);
}

// The 6N x 6N matrix of the FMM operator is that of the direct one to the tolerance, hence
// symmetric to it, on a dense suspension of mixed radii with overlaps.
TEST(FmmRotation, GrandMatrixMatchesDirect) {
  t::Configuration c = t::random_suspension(40, 1.0, 0.5, 23);
  for (std::size_t i = 0; i < c.a.size(); ++i) c.a[i] = 0.6 + 0.8 * static_cast<double>(i % 5) / 4.0;
  const std::size_t n = c.a.size();
  FmmRpy fast(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-6, .leaf_capacity = 8});
  DirectRpy direct;
  fast.set_positions(c.x, c.a);
  direct.set_positions(c.x, c.a);
  double max_diff = 0.0, max_entry = 0.0, max_asym = 0.0;
  std::vector<std::vector<double>> columns;
  for (std::size_t col = 0; col < 6 * n; ++col) {
    std::vector<double> f(3 * n, 0.0), tq(3 * n, 0.0);
    (col < 3 * n ? f[col] : tq[col - 3 * n]) = 1.0;
    const Motion a = grand_product(fast, f, tq), b = grand_product(direct, f, tq);
    std::vector<double> column(a.u);
    column.insert(column.end(), a.w.begin(), a.w.end());
    for (std::size_t row = 0; row < 3 * n; ++row) {
      max_diff = std::max({max_diff, std::abs(a.u[row] - b.u[row]), std::abs(a.w[row] - b.w[row])});
      max_entry = std::max({max_entry, std::abs(b.u[row]), std::abs(b.w[row])});
    }
    columns.push_back(std::move(column));
  }
  for (std::size_t i = 0; i < 6 * n; ++i)
    for (std::size_t j = 0; j < i; ++j) max_asym = std::max(max_asym, std::abs(columns[i][j] - columns[j][i]));
  EXPECT_LE(max_diff, 1e-6 * max_entry);
  EXPECT_LE(max_asym, 2e-6 * max_entry);
}

// Extreme length scales are evaluated in units of the suspension's size: the blocks scale as 1/L
// (UF), 1/L^2 (UT, WF) and 1/L^3 (WT). Lengths 2^(+-300) and 2^(+-400) with torques scaled alike
// reproduce the plain product to the tolerance (at 2^(+-400), W ~ 2^(-+800) is in range although
// a^3 and the torque's square are not).
TEST(FmmRotation, ExtremeScalesGiveTheScaledProduct) {
  const t::Configuration c = t::random_suspension(400, 1.0, 0.3, 24);
  const auto [f, tq] = loads(c, Loads::both, 5);
  FmmRpy plain_op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-6});
  plain_op.set_positions(c.x, c.a);
  const Motion plain = grand_product(plain_op, f, tq);
  for (int e : {300, -300, 400, -400}) {
    t::Configuration s = c;
    for (double& v : s.x) v = std::ldexp(v, e);
    for (double& v : s.a) v = std::ldexp(v, e);
    std::vector<double> ts(tq);
    for (double& v : ts) v = std::ldexp(v, e);  // torque ~ force x length
    FmmRpy op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-6});
    op.set_positions(s.x, s.a);
    Motion m = grand_product(op, f, ts);
    for (double& v : m.u) v = std::ldexp(v, e);
    for (double& v : m.w) v = std::ldexp(v, 2 * e);
    EXPECT_LE(t::relative_l2(m.u, plain.u), 1e-6) << e;
    EXPECT_LE(t::relative_l2(m.w, plain.w), 1e-6) << e;
  }
}

TEST(FmmRotation, BadInput) {
  FmmRpy op;
  std::vector<double> f(6, 0.0), tq(6, 0.0), u(6), w(6);
  EXPECT_THROW(op.apply(f, tq, u, w), rpyfmm::Error);  // no positions yet
  op.set_positions(std::vector<double>{0, 0, 0, 3, 0, 0}, 1.0);
  std::vector<double> short_t(3, 0.0);
  EXPECT_THROW(op.apply(f, short_t, u, w), rpyfmm::Error);
  tq[4] = std::nan("");
  EXPECT_THROW(op.apply(f, tq, u, w), rpyfmm::Error);
}

// Every instruction-set level this machine runs (the RPYFMM_SIMD override): the vectorized pair
// sums of FmmRpy and DirectRpy give the grand mobility within FmmRpy's tolerance of the direct
// product at the scalar level, a reference that does not share the level's kernels.
class FmmRotationLevels : public rpyfmm::test::SimdLevelTest {};

TEST_P(FmmRotationLevels, WithinToleranceOfTheScalarDirectProduct) {
  t::Configuration c = t::random_suspension(600, 1.0, 0.4, 25);
  for (std::size_t i = 0; i < c.a.size(); ++i) c.a[i] = 0.6 + 0.8 * static_cast<double>(i % 7) / 6.0;
  const auto [f, tq] = loads(c, Loads::both, 6);
  const rpyfmm::SimdLevel level = rpyfmm::simd_level();
  rpyfmm::set_simd_level(rpyfmm::SimdLevel::scalar);
  DirectRpy reference;
  reference.set_positions(c.x, c.a);
  const Motion exact = grand_product(reference, f, tq);
  rpyfmm::set_simd_level(level);
  DirectRpy direct;
  FmmRpy fast(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-6, .leaf_capacity = 24});
  direct.set_positions(c.x, c.a);
  fast.set_positions(c.x, c.a);
  const Motion d = grand_product(direct, f, tq), m = grand_product(fast, f, tq);
  EXPECT_LE(t::relative_l2(d.u, exact.u), 1e-13);  // rounding only
  EXPECT_LE(t::relative_l2(d.w, exact.w), 1e-13);
  EXPECT_LE(t::relative_l2(m.u, exact.u), 1e-6);
  EXPECT_LE(t::relative_l2(m.w, exact.w), 1e-6);
}

INSTANTIATE_TEST_SUITE_P(Levels, FmmRotationLevels, ::testing::ValuesIn(rpyfmm::test::all_simd_levels()),
                         rpyfmm::test::simd_level_param_name);
