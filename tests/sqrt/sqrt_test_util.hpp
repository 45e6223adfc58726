// Test helpers for the square-root solvers: a plain dense RPY matrix
// (docs/theory/rpy.md; Zuk et al., J. Fluid Mech. 741, R5 (2014)), random
// suspensions, and wrappers of dense matrices as LinearOperatorView.
#pragma once

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace sqrt_test {

/// 3x3 RPY block between spheres i and j (viscosity eta), written plainly
/// from docs/theory/rpy.md (all three regimes; self term when r = 0 and a_i = a_j).
inline Eigen::Matrix3d rpy_pair(const Eigen::Vector3d& xi, const Eigen::Vector3d& xj, double ai, double aj,
                                double eta) {
  const double pi = std::numbers::pi;
  const Eigen::Vector3d rv = xi - xj;
  const double r = rv.norm();
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  if (r <= std::abs(ai - aj) || r == 0.0) return I / (6 * pi * eta * std::max(ai, aj));
  const Eigen::Vector3d rh = rv / r;
  const Eigen::Matrix3d RR = rh * rh.transpose();
  if (r > ai + aj) {
    const double s = (ai * ai + aj * aj) / (r * r);
    return ((1 + s / 3) * I + (1 - s) * RR) / (8 * pi * eta * r);
  }
  const double d2 = (ai - aj) * (ai - aj);
  const double r3 = r * r * r;
  const double cI = (16 * r3 * (ai + aj) - std::pow(d2 + 3 * r * r, 2)) / (32 * r3);
  const double cR = 3 * std::pow(d2 - r * r, 2) / (32 * r3);
  return (cI * I + cR * RR) / (6 * pi * eta * ai * aj);
}

/// Dense 3N x 3N RPY mobility (particle-major), viscosity 1.
inline Eigen::MatrixXd rpy_matrix(const std::vector<double>& x, const std::vector<double>& a) {
  const auto N = static_cast<Eigen::Index>(a.size());
  Eigen::MatrixXd M(3 * N, 3 * N);
  for (Eigen::Index i = 0; i < N; ++i)
    for (Eigen::Index j = 0; j < N; ++j) {
      const Eigen::Vector3d xi(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
      const Eigen::Vector3d xj(x[3 * j], x[3 * j + 1], x[3 * j + 2]);
      M.block<3, 3>(3 * i, 3 * j) = i == j
                                        ? Eigen::Matrix3d(Eigen::Matrix3d::Identity() / (6 * std::numbers::pi * a[i]))
                                        : rpy_pair(xi, xj, a[i], a[j], 1.0);
    }
  return M;
}

/// N uniform random points in a cube sized for volume fraction phi (radius 1
/// spheres), so that overlaps occur; fixed seed.
inline std::vector<double> random_points(std::size_t N, double phi, std::uint32_t seed) {
  const double L = std::cbrt(N * 4.0 / 3.0 * std::numbers::pi / phi);
  std::mt19937_64 gen(seed);
  std::uniform_real_distribution<double> u(0.0, L);
  std::vector<double> x(3 * N);
  for (auto& v : x) v = u(gen);
  return x;
}

/// Radii: all 1 (mixed = false) or uniform in [0.5, 2] (mixed = true).
inline std::vector<double> radii(std::size_t N, bool mixed, std::uint32_t seed) {
  std::vector<double> a(N, 1.0);
  if (mixed) {
    std::mt19937_64 gen(seed);
    std::uniform_real_distribution<double> u(0.5, 2.0);
    for (auto& v : a) v = u(gen);
  }
  return a;
}

/// An operator's dense matrix (assemble_dense; row-major there, M symmetric anyway).
inline Eigen::MatrixXd dense_of(const rpyfmm::rpy::MobilityOperator& op) {
  const auto n = static_cast<Eigen::Index>(3 * op.size());
  const std::vector<double> d = op.assemble_dense();
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(d.data(), n, n);
}

/// Wraps a dense symmetric matrix (kept alive by the caller).
inline rpyfmm::rpy::LinearOperatorView view_of(const Eigen::MatrixXd& M) {
  rpyfmm::rpy::LinearOperatorView op;
  op.n = static_cast<std::size_t>(M.rows());
  op.apply = [&M](std::span<const double> x, std::span<double> y, std::size_t nrhs) {
    const auto n = M.rows();
    Eigen::Map<const Eigen::MatrixXd> X(x.data(), n, static_cast<Eigen::Index>(nrhs));
    Eigen::Map<Eigen::MatrixXd> Y(y.data(), n, static_cast<Eigen::Index>(nrhs));
    Y.noalias() = M * X;
  };
  return op;
}

/// Principal square root via the symmetric eigensolver (the reference).
inline Eigen::MatrixXd principal_sqrt(const Eigen::MatrixXd& M) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M);
  return es.eigenvectors() * es.eigenvalues().cwiseSqrt().asDiagonal() * es.eigenvectors().transpose();
}

/// The grand mobility [U; W] = M [F; T] as a dense 6N x 6N matrix, rows and columns ordered
/// [translation (3N); rotation (3N)], one column per unit force or torque.
inline Eigen::MatrixXd grand_dense(const rpyfmm::rpy::MobilityOperator& op) {
  const std::size_t n = 3 * op.size();
  Eigen::MatrixXd M(2 * n, 2 * n);
  std::vector<double> f(n), t(n), u(n), w(n);
  for (std::size_t col = 0; col < 2 * n; ++col) {
    std::fill(f.begin(), f.end(), 0.0);
    std::fill(t.begin(), t.end(), 0.0);
    (col < n ? f[col] : t[col - n]) = 1.0;
    op.apply(f, t, u, w);
    for (std::size_t k = 0; k < n; ++k) {
      M(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(col)) = u[k];
      M(static_cast<Eigen::Index>(n + k), static_cast<Eigen::Index>(col)) = w[k];
    }
  }
  return M;
}

/// The diagonal of S = diag(I_3N, a_i I_3) (the scaling documented in mobility.hpp).
inline Eigen::VectorXd scaling(const std::vector<double>& a) {
  const auto n = static_cast<Eigen::Index>(3 * a.size());
  Eigen::VectorXd s = Eigen::VectorXd::Ones(2 * n);
  for (Eigen::Index k = 0; k < n; ++k) s(n + k) = a[static_cast<std::size_t>(k / 3)];
  return s;
}

/// |S (w - ref)| / |S ref|: the relative error in the norm the tolerance refers to.
inline double scaled_error(const Eigen::VectorXd& w, const Eigen::VectorXd& ref, const Eigen::VectorXd& s) {
  return (s.asDiagonal() * (w - ref)).norm() / (s.asDiagonal() * ref).norm();
}

/// Standard normal vector from a fixed-seed std generator (test-only).
inline Eigen::VectorXd gaussian(Eigen::Index n, std::uint32_t seed) {
  std::mt19937_64 gen(seed);
  std::normal_distribution<double> g;
  Eigen::VectorXd z(n);
  for (auto& v : z) v = g(gen);
  return z;
}

/// Kolmogorov-Smirnov statistic of `v` against N(0,1).
inline double ks_statistic_normal(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const double n = static_cast<double>(v.size());
  double d = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const double F = 0.5 * std::erfc(-v[i] / std::numbers::sqrt2);
    d = std::max({d, F - i / n, (i + 1) / n - F});
  }
  return d;
}

}  // namespace sqrt_test
