// FmmRpy against the exact direct operator (DirectRpy, an independent O(N^2)
// pair sum), issue 7's configurations and tolerances. The contract is
// ||U_fmm - U_direct||_2 <= eps ||U_direct||_2; we check it with no slack.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstdio>
#include <span>
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

TEST(FmmRpy, TouchingAndOverlappingPairsExact) {
  // Two spheres touching, two overlapping, one inside another, two at the same point (equal and
  // different radii: M_12 = I / (6 pi eta max a)): all near-field, so the FMM operator must
  // reproduce the exact pair formulas to rounding.
  const std::vector<std::tuple<double, double, double>> pairs = {{2.0, 1.0, 1.0}, {1.3, 1.0, 1.0}, {0.2, 1.0, 3.0},
                                                                 {0.0, 1.0, 1.0}, {0.0, 0.7, 0.7}, {0.0, 1.0, 2.0}};
  for (auto [r, a1, a2] : pairs) {
    t::Configuration c{{0, 0, 0, r, 0, 0}, {a1, a2}};
    EXPECT_LE(fmm_error(c, 1e-6), 1e-13) << "r=" << r;
  }
}

TEST(FmmRpy, SingleParticleIsSelfMobility) {
  FmmRpy op(Geometry::open(), 2.0);
  op.set_positions(std::vector<double>{1, 2, 3}, 0.5);
  std::vector<double> f{1, -2, 3}, u(3);
  op.apply(f, u);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(u[k], f[k] / (6 * M_PI * 2.0 * 0.5), 1e-15);
}

TEST(FmmRpy, TranslationAndRotationInvariance) {
  auto c = t::random_suspension(1000, 1.0, 0.1, 11);
  const auto f = t::random_vector(c.x.size(), 12);
  FmmRpy op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-6});
  op.set_positions(c.x, c.a);
  const auto u = product(op, f);

  // Translation by a large offset: the operator must not lose accuracy with |x|.
  auto shifted = c.x;
  for (std::size_t i = 0; i < shifted.size(); ++i) shifted[i] += 1e4 * (1 + i % 3);
  op.set_positions(shifted, c.a);
  EXPECT_LE(t::relative_l2(product(op, f), u), 2e-6);

  // Rotation R about a generic axis: U(Rx; RF) = R U(x; F).
  const double th = 0.7, ct = std::cos(th), st = std::sin(th);
  const double R[3][3] = {{ct, -st, 0}, {st * 0.6, ct * 0.6, -0.8}, {st * 0.8, ct * 0.8, 0.6}};
  auto rot = [&](const std::vector<double>& v) {
    std::vector<double> w(v.size());
    for (std::size_t i = 0; i < v.size() / 3; ++i)
      for (int a = 0; a < 3; ++a) w[3 * i + a] = R[a][0] * v[3 * i] + R[a][1] * v[3 * i + 1] + R[a][2] * v[3 * i + 2];
    return w;
  };
  op.set_positions(rot(c.x), c.a);
  EXPECT_LE(t::relative_l2(product(op, rot(f)), rot(u)), 2e-6);
}

TEST(FmmRpy, SymmetricAndPositive) {
  auto c = t::bimodal_suspension(1000, 0.5, 4.0, 0.2, 13);
  FmmRpy op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-6});
  op.set_positions(c.x, c.a);
  for (unsigned s = 0; s < 3; ++s) {
    const auto uvec = t::random_vector(c.x.size(), 100 + s), v = t::random_vector(c.x.size(), 200 + s);
    const auto Mu = product(op, uvec), Mv = product(op, v);
    double vMu = 0, uMv = 0, vMv = 0, norm = 0;
    for (std::size_t i = 0; i < v.size(); ++i) {
      vMu += v[i] * Mu[i];
      uMv += uvec[i] * Mv[i];
      vMv += v[i] * Mv[i];
      norm += std::abs(v[i] * Mu[i]);
    }
    EXPECT_LE(std::abs(vMu - uMv), 1e-6 * norm);
    EXPECT_GT(vMv, 0.0);
  }
}

TEST(FmmRpy, BlockApplyEqualsSingleApplies) {
  auto c = t::random_suspension(600, 1.0, 0.1, 14);
  FmmRpy op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-6});
  op.set_positions(c.x, c.a);
  const std::size_t n3 = c.x.size();
  auto f = t::random_vector(3 * n3, 15);
  std::vector<double> block(3 * n3);
  op.apply_block(f, block, 3);
  for (std::size_t k = 0; k < 3; ++k) {
    std::vector<double> fk(f.begin() + k * n3, f.begin() + (k + 1) * n3);
    const auto uk = product(op, fk);
    for (std::size_t i = 0; i < n3; ++i) EXPECT_NEAR(block[k * n3 + i], uk[i], 1e-12 * (1 + std::abs(uk[i])));
  }
}

// Block products evaluate each near-field pair block once for all right-hand sides; the result
// equals single products (to rounding of the reordered sums) for equal and for mixed radii,
// dense overlapping suspensions included, and a block of 2 (BD's drift + first Krylov vector).
TEST(FmmRpy, BlockApplyEqualsSingleAppliesMixedRadiiAndOverlaps) {
  for (const auto& c : {t::bimodal_suspension(800, 1.0, 4.0, 0.3, 21), t::random_suspension(700, 1.0, 0.5, 22)}) {
    FmmRpy op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-3});
    op.set_positions(c.x, c.a);
    const std::size_t n3 = c.x.size();
    for (std::size_t nrhs : {2u, 5u}) {
      auto f = t::random_vector(nrhs * n3, 23 + static_cast<unsigned>(nrhs));
      std::vector<double> block(nrhs * n3);
      op.apply_block(f, block, nrhs);
      for (std::size_t k = 0; k < nrhs; ++k) {
        std::vector<double> fk(f.begin() + k * n3, f.begin() + (k + 1) * n3);
        const auto uk = product(op, fk);
        std::vector<double> bk(block.begin() + k * n3, block.begin() + (k + 1) * n3);
        EXPECT_LT(t::relative_l2(bk, uk), 1e-13) << "nrhs " << nrhs << " rhs " << k;
      }
    }
  }
}

// Trees with many leaves evaluate each adjacent leaf pair once for both directions (the
// symmetric near-field schedule): still exact against DirectRpy, with overlaps and mixed radii,
// for single and block products.
TEST(FmmRpy, SymmetricNearFieldMatchesDirect) {
  for (const auto& c : {t::bimodal_suspension(2500, 1.0, 2.0, 0.2, 41), t::random_suspension(2000, 1.0, 0.5, 42)}) {
    // 3 digits keep the far field cheap; a near-field error (a pair missed, doubled or given the
    // wrong direction) would be of the order of the near-field velocity itself.
    FmmRpy op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-3, .leaf_capacity = 20});
    op.set_positions(c.x, c.a);
    // kSymmetricMinLeaves (fmm_operator.cpp) is 64: the symmetric schedule is in use.
    ASSERT_GE(op.laplace_plan()->stats().leaves, 64u) << "too few leaves for the symmetric schedule";
    DirectRpy direct;
    direct.set_positions(c.x, c.a);
    const std::size_t n3 = c.x.size();
    const auto f = t::random_vector(3 * n3, 43);
    std::vector<double> fast(3 * n3), exact(3 * n3);
    op.apply_block(f, fast, 3);
    direct.apply_block(f, exact, 3);
    for (std::size_t k = 0; k < 3; ++k) {
      std::vector<double> fk(f.begin() + k * n3, f.begin() + (k + 1) * n3);
      std::vector<double> bk(fast.begin() + k * n3, fast.begin() + (k + 1) * n3);
      std::vector<double> ek(exact.begin() + k * n3, exact.begin() + (k + 1) * n3);
      EXPECT_LE(t::relative_l2(bk, ek), 1e-3) << "block rhs " << k;
      EXPECT_LE(t::relative_l2(product(op, fk), ek), 1e-3) << "single rhs " << k;
      EXPECT_LT(t::relative_l2(bk, product(op, fk)), 1e-13) << "block vs single, rhs " << k;
    }
  }
}

// Results do not depend on the thread count, bit for bit (each near-field target leaf and each
// FMM box is one thread's, summed in a fixed order): BD restarts and tests rely on it. Mixed radii
// with overlaps, enough particles for a multi-level tree at both the 3- and 6-digit leaf sizes.
TEST(FmmRpy, SameResultForAnyThreadCount) {
  const auto c = t::bimodal_suspension(4000, 1.0, 3.0, 0.2, 31);
  const std::size_t n3 = c.x.size();
  const auto f = t::random_vector(2 * n3, 32);
  const int saved = omp_get_max_threads();
  for (double eps : {1e-3, 1e-6}) {
    FmmRpy op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = eps});
    op.set_positions(c.x, c.a);
    ASSERT_GT(op.laplace_plan()->stats().levels, 2) << "tree too shallow to exercise parallel loops";
    std::vector<std::vector<double>> single, block;
    for (int threads : {1, 2, 3}) {
      omp_set_num_threads(threads);
      std::vector<double> u(n3), ub(2 * n3);
      op.apply(std::span<const double>(f.data(), n3), u);
      op.apply_block(f, ub, 2);
      single.push_back(u);
      block.push_back(ub);
    }
    omp_set_num_threads(saved);
    for (std::size_t k = 1; k < single.size(); ++k) {
      EXPECT_EQ(single[k], single[0]) << "eps " << eps << ", " << k + 1 << " threads";
      EXPECT_EQ(block[k], block[0]) << "eps " << eps << ", " << k + 1 << " threads";
    }
  }
}

TEST(FmmRpy, BadInput) {
  EXPECT_THROW(FmmRpy(Geometry::periodic(10.0)), rpyfmm::Error);
  EXPECT_THROW(FmmRpy(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 0.0}), rpyfmm::Error);
  EXPECT_THROW(FmmRpy(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 0.5}), rpyfmm::Error);
  EXPECT_THROW(FmmRpy(Geometry::open(), -1.0), rpyfmm::Error);
  FmmRpy op;
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1, 1, NAN}, 1.0), rpyfmm::Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1, 1, 1}, std::vector<double>{1.0}), rpyfmm::Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1, 1, 1}, std::vector<double>{1.0, -1.0}), rpyfmm::Error);
  std::vector<double> f(6), u(6);
  EXPECT_THROW(op.apply(f, u), rpyfmm::Error);  // no positions yet
}
