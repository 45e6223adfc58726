// Chebyshev square root: the coefficient expansion, the bound estimate, the
// degree chosen from the tolerance, given bounds.
#include <gtest/gtest.h>

#include <cmath>

#include "../../rpy/src/sqrt/detail.hpp"
#include "sqrt_test_util.hpp"

using namespace rpyfmm::rpy;

namespace {

std::span<const double> cspan(const Eigen::VectorXd& v) {
  return {v.data(), static_cast<std::size_t>(v.size())};
}
std::span<double> mspan(Eigen::VectorXd& v) {
  return {v.data(), static_cast<std::size_t>(v.size())};
}

// The series sum c_k T_k(t) reproduces sqrt on [a, b] (checked at points
// that are not interpolation nodes) to the size of the neglected tail.
TEST(Chebyshev, CoefficientsReproduceSqrt) {
  const double a = 0.05, b = 3.0;
  const auto c = sqrt_detail::chebyshev_sqrt_coefficients(a, b, 200);
  for (int i = 0; i <= 1000; ++i) {
    const double lam = a + (b - a) * i / 1000.0;
    const double t = (2 * lam - a - b) / (b - a);
    double s = 0.0;
    for (std::size_t k = 0; k < c.size(); ++k) s += c[k] * std::cos(k * std::acos(std::clamp(t, -1.0, 1.0)));
    EXPECT_NEAR(s, std::sqrt(lam), 1e-13) << "lambda " << lam;
  }
  // Geometric decay at the rate of the Bernstein ellipse through lambda = 0.
  const double rho = (std::sqrt(b) + std::sqrt(a)) / (std::sqrt(b) - std::sqrt(a));
  EXPECT_LT(std::abs(c[40]), 2.0 * std::sqrt(b) * std::pow(rho, -40));
}

// The estimated bounds enclose the spectrum of RPY matrices (equal and mixed radii).
TEST(Chebyshev, EstimatedBoundsEncloseSpectrum) {
  for (bool mixed : {false, true})
    for (std::size_t N : {20, 200}) {
      const Eigen::MatrixXd M =
          sqrt_test::rpy_matrix(sqrt_test::random_points(N, 0.1, 4u), sqrt_test::radii(N, mixed, 5u));
      const SpectrumBounds b = estimate_spectrum_bounds(sqrt_test::view_of(M), 30);
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M, Eigen::EigenvaluesOnly);
      EXPECT_LE(b.lambda_min, es.eigenvalues()[0]) << "N " << N << " mixed " << mixed;
      EXPECT_GE(b.lambda_max, es.eigenvalues()[M.rows() - 1]) << "N " << N << " mixed " << mixed;
      EXPECT_LE(b.ritz_max, es.eigenvalues()[M.rows() - 1] * (1 + 1e-12));
      EXPECT_GE(b.ritz_min, es.eigenvalues()[0] * (1 - 1e-12));
      EXPECT_EQ(b.iterations, 30);
    }
}

// With exact bounds given, the error is below the tolerance, the degree grows
// like log(1/tol), and products = degree (no estimate needed).
TEST(Chebyshev, GivenBoundsDegreeFromTolerance) {
  const std::size_t N = 60;
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(sqrt_test::random_points(N, 0.1, 9u), sqrt_test::radii(N, true, 1u));
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M);
  const Eigen::VectorXd z = sqrt_test::gaussian(M.rows(), 4u);
  const Eigen::VectorXd ref =
      es.eigenvectors() * es.eigenvalues().cwiseSqrt().asDiagonal() * es.eigenvectors().transpose() * z;
  SqrtOptions opt;
  opt.method = SqrtMethod::chebyshev;
  opt.lambda_min = es.eigenvalues()[0];
  opt.lambda_max = es.eigenvalues()[M.rows() - 1];
  int prev = 0;
  for (double tol : {1e-2, 1e-4, 1e-6, 1e-8, 1e-10}) {
    opt.tolerance = tol;
    Eigen::VectorXd w(M.rows());
    const SqrtReport rep = sqrt_apply(sqrt_test::view_of(M), cspan(z), mspan(w), 1, opt);
    EXPECT_LE((w - ref).norm() / ref.norm(), tol) << "tol " << tol;
    EXPECT_LE(rep.error_estimate, tol);
    EXPECT_EQ(rep.operator_applications, rep.iterations);
    EXPECT_EQ(rep.lambda_min, opt.lambda_min);
    EXPECT_GT(rep.iterations, prev);
    prev = rep.iterations;
  }
}

// Block: one operator call per degree for all right-hand sides, same result.
TEST(Chebyshev, BlockMatchesSingle) {
  const std::size_t N = 40;
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(sqrt_test::random_points(N, 0.1, 2u), sqrt_test::radii(N, false, 1u));
  const auto n = M.rows();
  Eigen::MatrixXd Z(n, 3), W(n, 3);
  for (int k = 0; k < 3; ++k) Z.col(k) = sqrt_test::gaussian(n, 50u + static_cast<std::uint32_t>(k));
  SqrtOptions opt;
  opt.method = SqrtMethod::chebyshev;
  const SqrtReport rep = sqrt_apply(sqrt_test::view_of(M), {Z.data(), static_cast<std::size_t>(Z.size())},
                                    {W.data(), static_cast<std::size_t>(W.size())}, 3, opt);
  EXPECT_EQ(rep.operator_applications, rep.iterations + opt.bound_estimate_iterations);
  for (int k = 0; k < 3; ++k) {
    const Eigen::VectorXd z = Z.col(k);
    Eigen::VectorXd w(n);
    sqrt_apply(sqrt_test::view_of(M), cspan(z), mspan(w), 1, opt);
    EXPECT_LE((W.col(k) - w).norm(), 1e-13 * w.norm());
  }
}

// Lanczos needs fewer products than Chebyshev for the same tolerance (the
// documented trade-off), on an RPY matrix.
TEST(Chebyshev, NeedsMoreProductsThanLanczos) {
  const std::size_t N = 200;
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(sqrt_test::random_points(N, 0.1, 3u), sqrt_test::radii(N, true, 1u));
  const Eigen::VectorXd z = sqrt_test::gaussian(M.rows(), 4u);
  Eigen::VectorXd w(M.rows());
  SqrtOptions opt;
  opt.tolerance = 1e-6;
  const SqrtReport lan = sqrt_apply(sqrt_test::view_of(M), cspan(z), mspan(w), 1, opt);
  opt.method = SqrtMethod::chebyshev;
  const SqrtReport che = sqrt_apply(sqrt_test::view_of(M), cspan(z), mspan(w), 1, opt);
  EXPECT_LT(lan.operator_applications, che.operator_applications);
}

}  // namespace
