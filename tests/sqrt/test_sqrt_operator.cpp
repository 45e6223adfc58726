// The square roots through the mobility interface (MobilityOperator::apply_sqrt
// with the DirectRpy operator): agreement with the dense principal root,
// fluctuation-dissipation (covariance) tests, thread independence.
#include <gtest/gtest.h>
#include <omp.h>

#include <array>
#include <cmath>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "sqrt_test_util.hpp"

using namespace rpyfmm::rpy;

namespace {

// The operator's own dense matrix agrees with the plain test builder, and the
// default apply_sqrt (Lanczos) matches the principal root to the tolerance.
TEST(SqrtOperator, DirectDefaultIsLanczosAndAccurate) {
  const std::size_t N = 150;
  const auto x = sqrt_test::random_points(N, 0.1, 21u);
  const auto a = sqrt_test::radii(N, true, 22u);
  DirectRpy op(Geometry::open(), 1.0);
  op.set_positions(x, a);
  const Eigen::MatrixXd M = sqrt_test::dense_of(op);
  ASSERT_LE((M - sqrt_test::rpy_matrix(x, a)).norm(), 1e-12 * M.norm());
  const Eigen::MatrixXd S = sqrt_test::principal_sqrt(M);
  std::vector<double> z(3 * N), w(3 * N);
  fill_normal(z, 1u, 0u);
  for (double tol : {1e-3, 1e-6}) {
    SqrtOptions opt;
    opt.tolerance = tol;
    const SqrtReport rep = op.apply_sqrt(z, w, opt);
    EXPECT_EQ(rep.method, SqrtMethod::lanczos);
    const Eigen::VectorXd ref = S * Eigen::Map<const Eigen::VectorXd>(z.data(), M.rows());
    EXPECT_LE((Eigen::Map<const Eigen::VectorXd>(w.data(), M.rows()) - ref).norm() / ref.norm(), 10 * tol);
  }
  for (SqrtMethod m : {SqrtMethod::chebyshev, SqrtMethod::eigen}) {
    SqrtOptions opt;
    opt.method = m;
    opt.tolerance = 1e-5;
    const SqrtReport rep = op.apply_sqrt(z, w, opt);
    EXPECT_EQ(rep.method, m);
    const Eigen::VectorXd ref = S * Eigen::Map<const Eigen::VectorXd>(z.data(), M.rows());
    EXPECT_LE((Eigen::Map<const Eigen::VectorXd>(w.data(), M.rows()) - ref).norm() / ref.norm(), 1e-4);
  }
}

// The FMM operator behind the same interface: Lanczos on FmmRpy agrees with
// the dense principal root of the exact (direct) matrix to about the larger of
// the FMM and square-root tolerances.
TEST(SqrtOperator, FmmOperatorLanczosAndChebyshev) {
  const std::size_t N = 400;
  const auto x = sqrt_test::random_points(N, 0.1, 51u);
  const auto a = sqrt_test::radii(N, true, 52u);
  DirectRpy direct(Geometry::open(), 1.0);
  direct.set_positions(x, a);
  const Eigen::MatrixXd S = sqrt_test::principal_sqrt(sqrt_test::dense_of(direct));
  FmmRpyOptions fo;
  fo.tolerance = 1e-8;
  FmmRpy fmm(Geometry::open(), 1.0, fo);
  fmm.set_positions(x, a);
  std::vector<double> z(3 * N), w(3 * N);
  fill_normal(z, 3u, 0u);
  const Eigen::VectorXd ref = S * Eigen::Map<const Eigen::VectorXd>(z.data(), 3 * N);
  for (SqrtMethod m : {SqrtMethod::lanczos, SqrtMethod::chebyshev}) {
    SqrtOptions opt;
    opt.method = m;
    opt.tolerance = 1e-6;
    fmm.apply_sqrt(z, w, opt);
    EXPECT_LE((Eigen::Map<const Eigen::VectorXd>(w.data(), 3 * N) - ref).norm() / ref.norm(), 1e-5) << to_string(m);
  }
}

struct CovarianceVerdict {
  double ks = 0, ks_crit = 0;
  double max_z = 0;  // largest |C_ij - delta_ij| in units of its standard error
};

/// Whitens S samples (columns of W) with the Cholesky factor of M:
/// y = L^{-1} w is N(0, I) iff Cov(w) = M. Returns the KS statistic of all y
/// entries against N(0,1) and the largest standardized entry of C - I, where
/// C = Y Y^T / S (off-diagonal sd 1/sqrt(S), diagonal sd sqrt(2/S)).
CovarianceVerdict covariance_test(const Eigen::MatrixXd& M, const Eigen::MatrixXd& W) {
  const Eigen::LLT<Eigen::MatrixXd> llt(M);
  const Eigen::MatrixXd Y = llt.matrixL().solve(W);
  const double S = static_cast<double>(W.cols());
  CovarianceVerdict v;
  v.ks = sqrt_test::ks_statistic_normal(std::vector<double>(Y.data(), Y.data() + Y.size()));
  v.ks_crit = 1.95 / std::sqrt(static_cast<double>(Y.size()));  // significance 1e-3
  const Eigen::MatrixXd C = Y * Y.transpose() / S;
  for (Eigen::Index i = 0; i < C.rows(); ++i)
    for (Eigen::Index j = 0; j <= i; ++j) {
      const double sd = i == j ? std::sqrt(2 / S) : 1 / std::sqrt(S);
      v.max_z = std::max(v.max_z, std::abs(C(i, j) - (i == j ? 1.0 : 0.0)) / sd);
    }
  return v;
}

// Fluctuation-dissipation: samples M^{1/2} z (and the block-preconditioned
// B z, B B^T = M; last loop pass) have covariance M. 1830 entries
// of C tested at 5 standard errors (Bonferroni: false alarm ~1e-3) plus a KS
// test at 1e-3; fixed seeds. Negative control: the diagonal-only sampler
// sqrt(diag M) z must fail the same test (so the test can fail).
TEST(SqrtOperator, CovarianceIsMobilityLanczosChebyshev) {
  const std::size_t N = 20;
  DirectRpy op(Geometry::open(), 1.0);
  op.set_positions(sqrt_test::random_points(N, 0.15, 31u), sqrt_test::radii(N, true, 32u));
  const Eigen::MatrixXd M = sqrt_test::dense_of(op);
  const auto n = M.rows();
  const std::size_t S = 4000, block = 200;
  for (int variant = 0; variant < 4; ++variant) {
    const SqrtMethod m = std::array{SqrtMethod::lanczos, SqrtMethod::chebyshev, SqrtMethod::cholesky,
                                    SqrtMethod::lanczos}[static_cast<std::size_t>(variant)];
    const bool preconditioned = variant == 3;  // blocks of 8 particles (3 blocks for N = 20)
    Eigen::MatrixXd W(n, static_cast<Eigen::Index>(S));
    std::vector<double> z(3 * N * block);
    for (std::size_t s0 = 0; s0 < S; s0 += block) {
      for (std::size_t k = 0; k < block; ++k)
        fill_normal(std::span<double>(&z[k * 3 * N], 3 * N), 77u, s0 + k);  // step = sample index
      SqrtOptions opt;
      opt.method = m;
      opt.tolerance = 1e-4;
      if (preconditioned)
        opt = {.tolerance = 1e-4, .preconditioner = SqrtPreconditioner::block, .preconditioner_block = 8};
      op.apply_sqrt_block(z, std::span<double>(W.col(static_cast<Eigen::Index>(s0)).data(), 3 * N * block), block, opt);
    }
    const CovarianceVerdict v = covariance_test(M, W);
    EXPECT_LT(v.ks, v.ks_crit) << to_string(m) << (preconditioned ? " + block" : "");
    EXPECT_LT(v.max_z, 5.0) << to_string(m) << (preconditioned ? " + block" : "");
    if (variant == 0) {
      // Negative control on the same noise: ignore the hydrodynamic coupling.
      Eigen::MatrixXd Z(n, static_cast<Eigen::Index>(S));
      for (std::size_t s = 0; s < S; ++s)
        fill_normal(std::span<double>(Z.col(static_cast<Eigen::Index>(s)).data(), 3 * N), 77u, s);
      const Eigen::MatrixXd Wd = M.diagonal().cwiseSqrt().asDiagonal() * Z;
      EXPECT_GT(covariance_test(M, Wd).max_z, 5.0);
    }
  }
}

// Same output for 1 and 2 threads through the operator (DirectRpy sums each
// velocity in a fixed order; the solvers' reductions are chunked).
TEST(SqrtOperator, SameOutputForOneAndTwoThreads) {
  const std::size_t N = 1000;
  DirectRpy op(Geometry::open(), 1.0);
  op.set_positions(sqrt_test::random_points(N, 0.1, 41u), sqrt_test::radii(N, true, 42u));
  std::vector<double> z(2 * 3 * N), w1(z.size()), w2(z.size());
  fill_normal(std::span<double>(z.data(), 3 * N), 5u, 0u);
  fill_normal(std::span<double>(z.data() + 3 * N, 3 * N), 5u, 1u);
  const int saved = omp_get_max_threads();
  for (SqrtMethod m : {SqrtMethod::lanczos, SqrtMethod::chebyshev}) {
    SqrtOptions opt;
    opt.method = m;
    opt.tolerance = 1e-3;
    omp_set_num_threads(1);
    const SqrtReport r1 = op.apply_sqrt_block(z, w1, 2, opt);
    omp_set_num_threads(2);
    const SqrtReport r2 = op.apply_sqrt_block(z, w2, 2, opt);
    EXPECT_EQ(r1.iterations, r2.iterations);
    EXPECT_EQ(w1, w2) << to_string(m);
  }
  omp_set_num_threads(saved);
}

// The interface validates before the solver runs.
TEST(SqrtOperator, BadInputThroughInterface) {
  DirectRpy op(Geometry::open(), 1.0);
  std::vector<double> z(30), w(30);
  EXPECT_THROW(op.apply_sqrt(z, w), rpyfmm::Error);  // no positions yet
  op.set_positions(sqrt_test::random_points(10, 0.1, 1u), 1.0);
  std::vector<double> shortz(27);
  EXPECT_THROW(op.apply_sqrt(shortz, w), rpyfmm::Error);
  SqrtOptions opt;
  opt.tolerance = 1.5;
  EXPECT_THROW(op.apply_sqrt(z, w, opt), rpyfmm::Error);
  opt = {};
  opt.method = SqrtMethod::split;
  EXPECT_THROW(op.apply_sqrt(z, w, opt), rpyfmm::Error);
}

}  // namespace
