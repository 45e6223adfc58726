// The rigid-body solver's restarted GMRES (rpy/src/rigid/gmres.hpp, internal) against dense LU
// (Eigen) on nonsymmetric and indefinite systems: with and without restarts, with a
// preconditioner, a breakdown (exact solution in a small Krylov space), a zero right-hand side,
// and the reported iteration cap.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "rigid/gmres.hpp"
#include "rpyfmm/core/error.hpp"

using rpyfmm::rpy::rigid_detail::gmres;
using rpyfmm::rpy::rigid_detail::GmresResult;
using rpyfmm::rpy::rigid_detail::VectorMap;

namespace {

Eigen::MatrixXd random_matrix(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  Eigen::MatrixXd a(n, n);
  for (auto& v : a.reshaped()) v = g(rng);
  return a;
}

VectorMap map_of(const Eigen::MatrixXd& a) {
  return [&a](const double* x, double* y) {
    Eigen::Map<Eigen::VectorXd>(y, a.rows()) = a * Eigen::Map<const Eigen::VectorXd>(x, a.cols());
  };
}

}  // namespace

// A well-conditioned nonsymmetric system (identity + a small random part): converged to the
// tolerance, the true residual within 10x the estimate, and the same solution whether or not
// GMRES restarts (restart 5 < 60 unknowns).
TEST(Gmres, NonsymmetricSystemWithAndWithoutRestarts) {
  const int n = 60;
  const Eigen::MatrixXd a = Eigen::MatrixXd::Identity(n, n) + 0.3 / std::sqrt(double(n)) * random_matrix(n, 1u);
  const Eigen::VectorXd b = random_matrix(n, 2u).col(0);
  const Eigen::VectorXd exact = a.partialPivLu().solve(b);
  for (int restart : {60, 5}) {
    Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
    const GmresResult r = gmres(n, map_of(a), {}, b.data(), x.data(), 1e-12, 1000, restart);
    EXPECT_TRUE(r.converged) << restart;
    EXPECT_LE(r.residual, 1e-12);
    EXPECT_LE((b - a * x).norm(), 10 * 1e-12 * b.norm()) << restart;
    EXPECT_LE((x - exact).norm(), 1e-10 * exact.norm()) << restart;
    if (restart == 5) {
      EXPECT_GT(r.restarts, 0);
    } else {
      EXPECT_EQ(r.restarts, 0);
    }
  }
}

// An indefinite saddle-point-like system solved with its exact inverse as right preconditioner:
// one iteration; with a nearby preconditioner a few. A nonzero initial guess is honoured.
TEST(Gmres, RightPreconditionerAndInitialGuess) {
  const int n = 40;
  Eigen::MatrixXd a = random_matrix(n, 3u);
  a += a.transpose().eval();  // symmetric indefinite
  a.diagonal().array() += 0.5;
  const Eigen::MatrixXd inverse = a.inverse();
  const Eigen::VectorXd b = random_matrix(n, 4u).col(1);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  GmresResult r = gmres(n, map_of(a), map_of(inverse), b.data(), x.data(), 1e-10, 100, 30);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.iterations, 1);
  EXPECT_LE((a * x - b).norm(), 1e-9 * b.norm());
  const Eigen::MatrixXd nearby = (a + 0.01 * random_matrix(n, 5u)).inverse();
  x = a.partialPivLu().solve(b) + 1e-3 * Eigen::VectorXd::Ones(n);  // close to the solution
  r = gmres(n, map_of(a), map_of(nearby), b.data(), x.data(), 1e-10, 100, 30);
  EXPECT_TRUE(r.converged);
  EXPECT_LE(r.iterations, 10);
  EXPECT_LE((a * x - b).norm(), 1e-9 * b.norm());
}

// b in a 2-dimensional invariant subspace: GMRES breaks down after 2 products with the exact
// solution; b = 0 gives x = 0 without products; an iteration cap is reported, not hidden.
TEST(Gmres, BreakdownZeroRightHandSideAndCap) {
  const int n = 30;
  Eigen::VectorXd d = Eigen::VectorXd::LinSpaced(n, 1.0, 3.0);
  const Eigen::MatrixXd a = d.asDiagonal();
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
  b(3) = 1.0;
  b(17) = -2.0;
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  GmresResult r = gmres(n, map_of(a), {}, b.data(), x.data(), 1e-14, 100, 20);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.iterations, 2);
  EXPECT_LE((a * x - b).norm(), 1e-14 * b.norm());
  Eigen::VectorXd zero = Eigen::VectorXd::Zero(n);
  x.setConstant(5.0);
  r = gmres(n, map_of(a), {}, zero.data(), x.data(), 1e-10, 100, 20);
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(x.norm(), 0.0);
  const Eigen::MatrixXd hard = random_matrix(n, 6u);
  b = Eigen::VectorXd::Ones(n);
  x.setZero();
  r = gmres(n, map_of(hard), {}, b.data(), x.data(), 1e-14, 7, 5);
  EXPECT_FALSE(r.converged);
  EXPECT_LE(r.iterations, 7);
  EXPECT_GT(r.residual, 1e-14);
}

// A right-hand side whose norm overflows (entries of 1e300): |b| = inf made every convergence test
// pass (inf <= inf) and x = 0 came back as converged; it is refused, while b = 1e150 (|b| finite)
// still gives the solution, scaled (linearity; 1e-10 relative, as for the unscaled system above).
TEST(Gmres, RightHandSideWhoseNormOverflowsIsRefused) {
  const int n = 20;
  const Eigen::MatrixXd a = Eigen::MatrixXd::Identity(n, n) + 0.3 / std::sqrt(double(n)) * random_matrix(n, 3u);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  const Eigen::VectorXd huge = Eigen::VectorXd::Constant(n, 1e300);
  EXPECT_THROW((void)gmres(n, map_of(a), {}, huge.data(), x.data(), 1e-12, 1000, 60), rpyfmm::Error);
  const Eigen::VectorXd big = Eigen::VectorXd::Constant(n, 1e150);
  x.setZero();
  const GmresResult r = gmres(n, map_of(a), {}, big.data(), x.data(), 1e-12, 1000, 60);
  EXPECT_TRUE(r.converged);
  const Eigen::VectorXd exact = a.partialPivLu().solve(Eigen::VectorXd::Constant(n, 1.0));
  EXPECT_LE((x / 1e150 - exact).norm(), 1e-10 * exact.norm());
}
