// PSE sampler (fast part): split sampler contract, generic Lanczos on the full PSE operator,
// Lanczos iterations flat in N. Statistical covariance tests: test_pse_statistics.cpp (slow).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "../../rpy/src/pse/real_space_sqrt.hpp"  // the split sampler's Lanczos options
#include "ewald_reference.hpp"
#include "pse_sampler_util.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/random.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;
using pse_test::dense;
using pse_test::SmallSystem;

TEST(PseSampler, GenericLanczosOnFullOperatorMatchesDenseSquareRoot) {
  const SmallSystem s;
  PseRpy op(Geometry::periodic(s.L[0], s.L[1], s.L[2]), 1.0, s.options());
  op.set_positions(s.x, 1.0);
  const Eigen::MatrixXd M = dense(op);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (M + M.transpose()));
  const Eigen::MatrixXd S =
      es.eigenvectors() * es.eigenvalues().cwiseSqrt().asDiagonal() * es.eigenvectors().transpose();
  std::vector<double> z(s.x.size()), w(s.x.size());
  fill_normal(z, 5, 0);
  SqrtOptions so;
  so.method = SqrtMethod::lanczos;
  so.tolerance = 1e-10;
  const SqrtReport rep = op.apply_sqrt(z, w, so);
  EXPECT_EQ(rep.method, SqrtMethod::lanczos);
  const Eigen::VectorXd ref = S * Eigen::Map<const Eigen::VectorXd>(z.data(), static_cast<Eigen::Index>(z.size()));
  const Eigen::VectorXd got = Eigen::Map<const Eigen::VectorXd>(w.data(), static_cast<Eigen::Index>(w.size()));
  EXPECT_LT((got - ref).norm() / ref.norm(), 1e-8);
}

TEST(PseSampler, LanczosIterationsOnRealPartDoNotGrowWithN) {
  // Random points at number density matching phi = 0.1 for a = 1: the condition number of
  // M_r depends on the local environment only ([PSE] Fig. 1).
  int iters[2] = {0, 0};
  const std::size_t sizes[2] = {200, 1600};
  for (int t = 0; t < 2; ++t) {
    const double L = std::cbrt(static_cast<double>(sizes[t]) * 4.18879 / 0.1);
    PseOptions o;
    o.xi = 0.5;
    o.tolerance = 1e-3;
    PseRpy op(Geometry::periodic(L), 1.0, o);
    op.set_positions(pse_test::random_points(sizes[t], {L, L, L}, 41), 1.0);
    std::vector<double> w(3 * sizes[t]);
    iters[t] = op.sample(1, 0, w).iterations;
  }
  EXPECT_LE(iters[1], iters[0] + 2);
  EXPECT_LE(iters[1], 12);
}

TEST(PseSampler, SplitSamplerIsKeyedAndDeterministic) {
  const SmallSystem s;
  PseRpy op(Geometry::periodic(s.L[0], s.L[1], s.L[2]), 1.0, s.options());
  op.set_positions(s.x, 1.0);
  std::vector<double> a(s.x.size()), b(s.x.size()), c(s.x.size()), z(s.x.size());
  EXPECT_EQ(op.sample(3, 1, a).method, SqrtMethod::split);
  op.sample(3, 1, b);
  op.sample(3, 2, c);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  fill_normal(z, 3, 1);
  EXPECT_EQ(op.apply_sqrt(z, a).method, SqrtMethod::split);
  op.apply_sqrt(z, b);
  EXPECT_EQ(a, b);
  // apply_with_noise(F, 0) is the plain product.
  std::vector<double> f(s.x.size(), 0.5), u(s.x.size()), v(s.x.size());
  op.apply(f, u);
  op.apply_with_noise(f, 0.0, 1, 1, v);
  for (std::size_t i = 0; i < u.size(); ++i) EXPECT_NEAR(u[i], v[i], 1e-14 * (1 + std::abs(u[i])));
}

TEST(PseSampler, PlainLanczosOnRealPartMatchesDenseSquareRoot) {
  // The split sampler's real-space Lanczos runs without reorthogonalization
  // (detail::real_space_sqrt_options). On 300 random spheres (overlapping pairs included) its
  // M_r^{1/2} z meets the Lanczos contract (<= 10 tol) against the dense principal square root,
  // and equals the reorthogonalized Lanczos (same iterations) to rounding.
  const double L = 16.0;
  const auto x = pse_test::random_points(300, {L, L, L}, 77);
  PseOptions o;
  o.tolerance = 1e-6;
  o.xi = 0.6;
  PseRpy op(Geometry::periodic(L), 1.0, o);
  op.set_positions(x, 1.0);
  const auto Mr_op = op.real_space_operator();
  const auto n = static_cast<Eigen::Index>(x.size());
  Eigen::MatrixXd Mr(n, n);
  {
    const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
    Mr_op.apply(std::span<const double>(I.data(), I.size()), std::span<double>(Mr.data(), Mr.size()),
                static_cast<std::size_t>(n));
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (Mr + Mr.transpose()));
  ASSERT_GT(es.eigenvalues().minCoeff(), 0.0);
  const Eigen::MatrixXd S =
      es.eigenvectors() * es.eigenvalues().cwiseSqrt().asDiagonal() * es.eigenvectors().transpose();
  std::vector<double> z(x.size());
  fill_normal(z, 11, 2, 1);
  const Eigen::VectorXd ref = S * Eigen::Map<const Eigen::VectorXd>(z.data(), n);
  for (const double tol : {1e-3, 1e-6, 1e-9}) {
    std::vector<double> plain(x.size()), full(x.size());
    SqrtOptions with = detail::real_space_sqrt_options(tol);
    ASSERT_FALSE(with.reorthogonalize);
    const SqrtReport rp = sqrt_apply(Mr_op, z, plain, 1, with);
    with.reorthogonalize = true;
    const SqrtReport rf = sqrt_apply(Mr_op, z, full, 1, with);
    const Eigen::Map<const Eigen::VectorXd> p(plain.data(), n), f(full.data(), n);
    EXPECT_LT((p - ref).norm() / ref.norm(), 10.0 * tol) << "tol " << tol;
    EXPECT_EQ(rp.iterations, rf.iterations) << "tol " << tol;
    EXPECT_LT((p - f).norm() / f.norm(), 1e-12) << "tol " << tol;
    EXPECT_GT(rp.iterations, 3) << "tol " << tol;  // a real Krylov run, not a 1-step case
  }
}
