// Bad input to the square-root solvers: rpyfmm::Error with a message naming
// the problem, never a crash and never NaN in the output.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "expect_error.hpp"
#include "rpyfmm/core/error.hpp"
#include "sqrt_test_util.hpp"

using namespace rpyfmm::rpy;
using rpyfmm::ErrorCode;

namespace {

using rpyfmm_test::expect_error;

struct Fixture {
  Eigen::MatrixXd M = sqrt_test::rpy_matrix(sqrt_test::random_points(10, 0.1, 1u), sqrt_test::radii(10, false, 0u));
  Eigen::VectorXd z = sqrt_test::gaussian(30, 1u);
  Eigen::VectorXd w = Eigen::VectorXd::Constant(30, -7.0);
  LinearOperatorView op = sqrt_test::view_of(M);
  std::span<const double> zs() const { return {z.data(), 30}; }
  std::span<double> ws() { return {w.data(), 30}; }
};

TEST(SqrtBadInput, Tolerance) {
  Fixture f;
  for (double tol :
       {0.0, -1e-3, 1.0, 2.0, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    for (SqrtMethod m : {SqrtMethod::lanczos, SqrtMethod::chebyshev, SqrtMethod::eigen}) {
      SqrtOptions opt;
      opt.method = m;
      opt.tolerance = tol;
      expect_error([&] { sqrt_apply(f.op, f.zs(), f.ws(), 1, opt); }, ErrorCode::invalid_argument,
                   "tolerance must lie in (0, 1)");
    }
  }
  EXPECT_EQ(f.w[0], -7.0);  // output untouched
}

TEST(SqrtBadInput, Sizes) {
  Fixture f;
  Eigen::VectorXd shortz(29), longw(33);
  expect_error(
      [&] {
        sqrt_apply(f.op, {shortz.data(), 29}, f.ws(), 1, {});
      },
      ErrorCode::invalid_input, "noise has 29 entries, expected 30");
  expect_error(
      [&] {
        sqrt_apply(f.op, f.zs(), {longw.data(), 33}, 1, {});
      },
      ErrorCode::invalid_input, "output has 33 entries, expected 30");
  expect_error([&] { sqrt_apply(f.op, f.zs(), f.ws(), 2, {}); }, ErrorCode::invalid_input,
               "noise has 30 entries, expected 60");
  expect_error([&] { sqrt_apply(f.op, f.zs(), f.ws(), 0, {}); }, ErrorCode::invalid_argument,
               "right-hand sides must be > 0");
  LinearOperatorView empty;
  expect_error([&] { sqrt_apply(empty, {}, {}, 1, {}); }, ErrorCode::invalid_input, "size 0");
  LinearOperatorView noapply;
  noapply.n = 30;
  expect_error([&] { sqrt_apply(noapply, f.zs(), f.ws(), 1, {}); }, ErrorCode::invalid_argument, "no apply function");
}

TEST(SqrtBadInput, NonFiniteNoise) {
  Fixture f;
  f.z[7] = std::numeric_limits<double>::quiet_NaN();
  expect_error([&] { sqrt_apply(f.op, f.zs(), f.ws(), 1, {}); }, ErrorCode::invalid_input, "noise entry 7 is NaN");
  f.z[7] = -std::numeric_limits<double>::infinity();
  expect_error([&] { sqrt_apply(f.op, f.zs(), f.ws(), 1, {}); }, ErrorCode::invalid_input, "noise entry 7 is infinite");
}

TEST(SqrtBadInput, Options) {
  Fixture f;
  SqrtOptions opt;
  opt.max_iterations = -1;
  expect_error([&] { sqrt_apply(f.op, f.zs(), f.ws(), 1, opt); }, ErrorCode::invalid_argument, "max_iterations");
  opt = {};
  opt.method = SqrtMethod::chebyshev;
  opt.lambda_min = 2.0;
  opt.lambda_max = 1.0;
  expect_error([&] { sqrt_apply(f.op, f.zs(), f.ws(), 1, opt); }, ErrorCode::invalid_argument,
               "0 < lambda_min < lambda_max");
  opt.lambda_min = -1.0;
  opt.lambda_max = 1.0;
  expect_error([&] { sqrt_apply(f.op, f.zs(), f.ws(), 1, opt); }, ErrorCode::invalid_argument,
               "0 < lambda_min < lambda_max");
  opt = {};
  opt.method = SqrtMethod::chebyshev;
  opt.bound_estimate_iterations = 1;
  expect_error([&] { sqrt_apply(f.op, f.zs(), f.ws(), 1, opt); }, ErrorCode::invalid_argument,
               "bound_estimate_iterations");
  opt = {};
  opt.method = SqrtMethod::split;
  expect_error([&] { sqrt_apply(f.op, f.zs(), f.ws(), 1, opt); }, ErrorCode::not_supported, "PSE");
  expect_error([] { sqrt_method_from_string("krylov"); }, ErrorCode::invalid_argument, "unknown method 'krylov'");
  EXPECT_EQ(sqrt_method_from_string("chebyshev"), SqrtMethod::chebyshev);
}

// Not positive definite: detected, reported with the offending Lanczos
// coefficient, and no NaN reaches the output.
TEST(SqrtBadInput, IndefiniteOperator) {
  Fixture f;
  // (a) alpha_0 = z^T M z < 0: negative definite.
  const Eigen::MatrixXd neg = -f.M;
  expect_error([&] { sqrt_apply(sqrt_test::view_of(neg), f.zs(), f.ws(), 1, {}); }, ErrorCode::numerical_failure,
               "Lanczos coefficient alpha_0");
  // (b) one negative eigenvalue: alpha stays > 0 but a Ritz value turns negative.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(f.M);
  Eigen::VectorXd lam = es.eigenvalues();
  lam[0] = -0.5 * lam[29];
  const Eigen::MatrixXd ind = es.eigenvectors() * lam.asDiagonal() * es.eigenvectors().transpose();
  for (SqrtMethod m : {SqrtMethod::lanczos, SqrtMethod::chebyshev}) {
    SqrtOptions opt;
    opt.method = m;
    f.w.setConstant(-7.0);
    expect_error([&] { sqrt_apply(sqrt_test::view_of(ind), f.zs(), f.ws(), 1, opt); }, ErrorCode::numerical_failure,
                 "not positive definite");
    EXPECT_TRUE(f.w.allFinite());
  }
  SqrtOptions opt;
  opt.method = SqrtMethod::eigen;
  expect_error([&] { sqrt_apply(sqrt_test::view_of(ind), f.zs(), f.ws(), 1, opt); }, ErrorCode::numerical_failure,
               "smallest eigenvalue");
  opt.method = SqrtMethod::cholesky;
  expect_error([&] { sqrt_apply(sqrt_test::view_of(ind), f.zs(), f.ws(), 1, opt); }, ErrorCode::numerical_failure,
               "not positive definite");
  // Non-symmetric operator: the dense methods refuse it.
  Eigen::MatrixXd asym = f.M;
  asym(0, 5) += 0.1;
  opt.method = SqrtMethod::eigen;
  expect_error([&] { sqrt_apply(sqrt_test::view_of(asym), f.zs(), f.ws(), 1, opt); }, ErrorCode::numerical_failure,
               "not symmetric");
  EXPECT_THROW(estimate_spectrum_bounds(sqrt_test::view_of(ind), 30), rpyfmm::Error);
}

// An operator that returns NaN is reported, naming the product.
TEST(SqrtBadInput, OperatorReturnsNaN) {
  Fixture f;
  LinearOperatorView op;
  op.n = 30;
  op.apply = [](std::span<const double>, std::span<double> y, std::size_t) {
    for (auto& v : y) v = 1.0;
    y[4] = std::nan("");
  };
  for (SqrtMethod m : {SqrtMethod::lanczos, SqrtMethod::chebyshev, SqrtMethod::eigen}) {
    SqrtOptions opt;
    opt.method = m;
    expect_error([&] { sqrt_apply(op, f.zs(), f.ws(), 1, opt); }, ErrorCode::numerical_failure,
                 "non-finite value (entry 4");
  }
}

TEST(SqrtBadInput, DenseTooLarge) {
  LinearOperatorView op;
  op.n = kDenseSqrtMaxRows + 3;
  bool called = false;
  op.apply = [&](std::span<const double>, std::span<double>, std::size_t) { called = true; };
  std::vector<double> z(op.n, 1.0), w(op.n);
  SqrtOptions opt;
  opt.method = SqrtMethod::cholesky;
  expect_error([&] { sqrt_apply(op, z, w, 1, opt); }, ErrorCode::out_of_memory, "use lanczos or chebyshev");
  EXPECT_FALSE(called);
}

}  // namespace
