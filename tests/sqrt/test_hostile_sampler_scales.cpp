// Brownian samplers at extreme but valid scales, and the block preconditioner's own input checks.
// References are dense: the mobility matrix assembled column by column (assemble_dense) and its
// principal square root from the symmetric eigensolver (Eigen), not the samplers under test.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "../common/expect_error.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"

namespace {

using rpyfmm::ErrorCode;
using rpyfmm::rpy::BlockPreconditioner;
using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::SqrtMethod;
using rpyfmm::rpy::SqrtOptions;
using rpyfmm::rpy::SqrtPreconditioner;
using rpyfmm_test::expect_error;

// A cloud of n spheres of radius a, nearest neighbours about 2.5 a apart (a jittered lattice).
std::vector<double> cloud(std::size_t n, double a) {
  std::vector<double> x;
  for (std::size_t i = 0; i < n; ++i) {
    const double j = 0.3 * std::sin(1.7 * static_cast<double>(i));
    x.insert(x.end(), {a * (2.5 * static_cast<double>(i % 4) + j), a * (2.5 * static_cast<double>((i / 4) % 4) - j),
                       a * (2.5 * static_cast<double>(i / 16) + 0.5 * j)});
  }
  return x;
}

Eigen::MatrixXd dense(const DirectRpy& op) {
  const std::size_t n = 3 * op.size();
  const std::vector<double> m = op.assemble_dense();
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      m.data(), static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
}

// The sampler's B (columns B e_j), plain and block-preconditioned, satisfies B B^T = M for
// viscosities and radii whose product eta a is far from 1 (both inside their documented ranges).
// The preconditioner's blocks are factored in single precision: at eta = a = 1e-20 the self
// mobility 1 / (6 pi eta a) ~ 5e38 overflowed float, and every sample failed with "the operator
// returned a non-finite value". At eta = a = 1e30 (M ~ 5e-62) Lanczos stopped after two iterations
// with B B^T 56-74 % away from M (tridiagonal_eigen's deflation test is not scale invariant).
TEST(HostileSamplerScales, CovarianceAtExtremeViscosityTimesRadius) {
  for (const auto& [eta, a] : {std::pair{1e-20, 1e-20}, std::pair{1e-30, 1e-30}, std::pair{1e30, 1e30}})
    for (const auto preconditioner : {SqrtPreconditioner::none, SqrtPreconditioner::block}) {
      DirectRpy op(Geometry::open(), eta);
      op.set_positions(cloud(20, a), a);
      const Eigen::MatrixXd m = dense(op);
      const auto n = static_cast<Eigen::Index>(m.rows());
      Eigen::MatrixXd b(n, n);
      SqrtOptions o;
      o.method = SqrtMethod::lanczos;
      o.preconditioner = preconditioner;
      o.preconditioner_block = 8;
      o.tolerance = 1e-10;
      for (Eigen::Index j = 0; j < n; ++j) {
        std::vector<double> z(static_cast<std::size_t>(n), 0.0), w(static_cast<std::size_t>(n));
        z[static_cast<std::size_t>(j)] = 1.0;
        const auto report = op.apply_sqrt(z, w, o);
        EXPECT_EQ(report.preconditioner_blocks > 0, preconditioner == SqrtPreconditioner::block);
        b.col(j) = Eigen::Map<const Eigen::VectorXd>(w.data(), n);
      }
      const double error = (b * b.transpose() - m).norm() / m.norm();
      EXPECT_LT(error, 1e-6) << "eta = " << eta << ", a = " << a;
    }
}

// Lanczos on diag(s, 2 s, ..., 30 s) against its exact square root: the same accuracy at every
// scale s (at s = 1e-32 the result was 32 % wrong, at 1e-20 1e-7 wrong for a tolerance of 1e-10).
TEST(HostileSamplerScales, LanczosIsScaleInvariant) {
  constexpr std::size_t n = 30;
  for (const double s : {1e-100, 1e-32, 1e-20, 1e20, 1e100}) {
    rpyfmm::rpy::LinearOperatorView op{n, [s](std::span<const double> x, std::span<double> y, std::size_t) {
                                         for (std::size_t i = 0; i < n; ++i)
                                           y[i] = s * static_cast<double>(i + 1) * x[i];
                                       }};
    std::vector<double> z(n, 1.0), w(n);
    rpyfmm::rpy::sqrt_apply(op, z, w, 1, {.method = SqrtMethod::lanczos, .tolerance = 1e-10});
    double error = 0.0, norm = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const double exact = std::sqrt(s * static_cast<double>(i + 1));
      error += (w[i] - exact) * (w[i] - exact);
      norm += exact * exact;
    }
    EXPECT_LT(std::sqrt(error / norm), 1e-9) << "s = " << s;
  }
}

// Noise vectors of 2^+-1000 are sampled as accurately as unit ones (M^{1/2} is linear). Entries of
// 2^1000 overflowed |z| and Lanczos called the operator "not positive definite"; entries of
// 2^-1000 underflowed |z|^2 to 0 and the sample came back as exactly 0.
TEST(HostileSamplerScales, LanczosOnNoiseOfExtremeMagnitude) {
  DirectRpy op;
  op.set_positions(cloud(10, 1.0), 1.0);
  const Eigen::MatrixXd m = dense(op);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(m);
  const Eigen::MatrixXd root =
      eig.eigenvectors() * eig.eigenvalues().cwiseSqrt().asDiagonal() * eig.eigenvectors().transpose();
  std::vector<double> u(30);
  for (std::size_t i = 0; i < u.size(); ++i) u[i] = std::cos(1.0 + 0.7 * static_cast<double>(i));
  const Eigen::VectorXd reference = root * Eigen::Map<const Eigen::VectorXd>(u.data(), 30);
  for (const int e : {1000, -1000}) {
    std::vector<double> z(30), w(30);
    for (std::size_t i = 0; i < z.size(); ++i) z[i] = std::ldexp(u[i], e);
    op.apply_sqrt(z, w, {.method = SqrtMethod::lanczos, .tolerance = 1e-12});
    Eigen::VectorXd unscaled(30);
    for (Eigen::Index i = 0; i < 30; ++i) unscaled(i) = std::ldexp(w[static_cast<std::size_t>(i)], -e);
    EXPECT_LT((unscaled - reference).norm() / reference.norm(), 1e-9) << "2^" << e;
  }
}

// The public constructor checks what it builds the blocks from: NaN positions, a zero radius or a
// NaN viscosity gave NaN factors, and G x = NaN, without an error.
TEST(HostileSamplerScales, BlockPreconditionerRefusesNonFiniteInput) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> x{0, 0, 0, 3, 0, 0}, radii{1.0, 1.0};
  expect_error(
      [&] {
        BlockPreconditioner(std::vector<double>{0, 0, nan, 3, 0, 0}, radii, 1.0, Geometry::open(), 8);
      },
      ErrorCode::invalid_input, "positions entry (0, 2) is NaN");
  expect_error(
      [&] {
        BlockPreconditioner(x, std::vector<double>{0.0, 1.0}, 1.0, Geometry::open(), 8);
      },
      ErrorCode::invalid_argument, "radius of particle 0");
  expect_error(
      [&] {
        BlockPreconditioner(x, std::vector<double>{1.0, 5e-324}, 1.0, Geometry::open(), 8);
      },
      ErrorCode::invalid_argument, "subnormal");
  expect_error([&] { BlockPreconditioner(x, radii, nan, Geometry::open(), 8); }, ErrorCode::invalid_argument,
               "viscosity");
}

}  // namespace
