// Accuracy of the Lanczos and Chebyshev square roots against the dense
// principal square root (Eigen::SelfAdjointEigenSolver) of RPY matrices:
// random suspensions (phi = 0.1, overlaps included), equal and mixed radii,
// tolerances 1e-2 ... 1e-8.
#include <gtest/gtest.h>

#include <map>
#include <tuple>

#include "sqrt_test_util.hpp"

using namespace rpyfmm::rpy;

namespace {

struct Case {
  Eigen::MatrixXd M, S;  // matrix and its principal root
};

const Case& rpy_case(std::size_t N, bool mixed) {
  static std::map<std::pair<std::size_t, bool>, Case> cache;
  auto it = cache.find({N, mixed});
  if (it == cache.end()) {
    const auto x = sqrt_test::random_points(N, 0.1, 11u + static_cast<std::uint32_t>(N));
    const auto a = sqrt_test::radii(N, mixed, 7u);
    Case c;
    c.M = sqrt_test::rpy_matrix(x, a);
    c.S = sqrt_test::principal_sqrt(c.M);
    it = cache.emplace(std::make_pair(N, mixed), std::move(c)).first;
  }
  return it->second;
}

// Relative error vs the tolerance. Lanczos: the stopping test measures the
// last change; the error left is of the same order, we allow 10 tol.
// Chebyshev: error_estimate is an upper bound (given the bounds enclose the
// spectrum), so the error must be <= tol (x 1.5 for the bound estimate).
double slack(SqrtMethod m) {
  return m == SqrtMethod::lanczos ? 10.0 : 1.5;
}

void check(std::size_t N, bool mixed, SqrtMethod method, double tol) {
  const Case& c = rpy_case(N, mixed);
  const auto op = sqrt_test::view_of(c.M);
  const Eigen::VectorXd z = sqrt_test::gaussian(c.M.rows(), 3u);
  const Eigen::VectorXd ref = c.S * z;
  Eigen::VectorXd w(c.M.rows());
  SqrtOptions opt;
  opt.method = method;
  opt.tolerance = tol;
  const SqrtReport rep =
      sqrt_apply(op, std::span<const double>(z.data(), z.size()), std::span<double>(w.data(), w.size()), 1, opt);
  const double err = (w - ref).norm() / ref.norm();
  EXPECT_LE(err, slack(method) * tol) << to_string(method) << " N=" << N << " mixed=" << mixed << " tol=" << tol
                                      << " iterations=" << rep.iterations << " estimate=" << rep.error_estimate;
  EXPECT_TRUE(rep.converged);
  EXPECT_EQ(rep.method, method);
  if (method == SqrtMethod::lanczos) {
    EXPECT_LT(rep.error_estimate, tol);
    // The Krylov dimension never exceeds n.
    EXPECT_LE(rep.iterations, c.M.rows());
  } else {
    // The estimated bounds must enclose the spectrum for the bound to hold.
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(c.M, Eigen::EigenvaluesOnly);
    EXPECT_LE(rep.lambda_min, es.eigenvalues()[0]);
    EXPECT_GE(rep.lambda_max, es.eigenvalues()[c.M.rows() - 1]);
    EXPECT_LE(err, 1.0001 * rep.error_estimate + 1e-14);
  }
}

#ifndef RPYFMM_SQRT_LARGE
class SqrtAccuracy : public ::testing::TestWithParam<std::tuple<std::size_t, bool, SqrtMethod>> {};

TEST_P(SqrtAccuracy, RelativeErrorWithinConstantOfTolerance) {
  const auto [N, mixed, method] = GetParam();
  for (double tol : {1e-2, 1e-3, 1e-4, 1e-6, 1e-8}) check(N, mixed, method, tol);
}

INSTANTIATE_TEST_SUITE_P(Rpy, SqrtAccuracy,
                         ::testing::Combine(::testing::Values<std::size_t>(10, 100, 400), ::testing::Bool(),
                                            ::testing::Values(SqrtMethod::lanczos, SqrtMethod::chebyshev)));

// The dense methods: eigen is the principal root; cholesky has the same
// covariance: (L z)(L z)^T averaged = L L^T = M, checked exactly via L L^T = M
// from the unit-vector columns.
TEST(SqrtDense, EigenIsPrincipalRootAndCholeskyFactorsM) {
  const Case& c = rpy_case(100, true);
  const auto op = sqrt_test::view_of(c.M);
  const auto n = c.M.rows();
  const Eigen::MatrixXd Id = Eigen::MatrixXd::Identity(n, n);
  Eigen::MatrixXd W(n, n);
  SqrtOptions opt;
  opt.method = SqrtMethod::eigen;
  sqrt_apply(op, std::span<const double>(Id.data(), Id.size()), std::span<double>(W.data(), W.size()),
             static_cast<std::size_t>(n), opt);
  EXPECT_LE((W - c.S).norm() / c.S.norm(), 1e-12);
  opt.method = SqrtMethod::cholesky;
  const SqrtReport rep = sqrt_apply(op, std::span<const double>(Id.data(), Id.size()),
                                    std::span<double>(W.data(), W.size()), static_cast<std::size_t>(n), opt);
  EXPECT_EQ(rep.method, SqrtMethod::cholesky);
  EXPECT_LE((W * W.transpose() - c.M).norm() / c.M.norm(), 1e-12);
  // Lower triangular: L z, not the principal root.
  EXPECT_EQ(W(0, 1), 0.0);
}

#else
// N = 1000 (n = 3000): the dense references cost ~1 min on one core, hence a
// separate executable (same source, RPYFMM_SQRT_LARGE) labelled `slow`.
TEST(SqrtAccuracyLarge, N1000MixedRadii) {
  for (double tol : {1e-2, 1e-5, 1e-8}) {
    check(1000, true, SqrtMethod::lanczos, tol);
    check(1000, true, SqrtMethod::chebyshev, tol);
  }
}
#endif

}  // namespace
