// rpyfmm — dense square roots for small systems (the reference solvers):
// `eigen`: principal root Q diag(sqrt(lambda)) Q^T z (Eigen::SelfAdjointEigenSolver);
// `cholesky`: L z with L L^T = M (Eigen::LLT) — same covariance M, not the principal root.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "detail.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::sqrt_detail {

namespace {

/// Assembles M column block by column block (64 unit vectors per call) and
/// checks symmetry.
Eigen::MatrixXd assemble(const LinearOperatorView& op, SqrtReport& report, const char* where) {
  const std::size_t n = op.n;
  Eigen::MatrixXd M(n, n);
  constexpr std::size_t kBlock = 64;
  std::vector<double> unit, cols;
  for (std::size_t j0 = 0; j0 < n; j0 += kBlock) {
    const std::size_t nb = std::min(kBlock, n - j0);
    unit.assign(nb * n, 0.0);
    cols.resize(nb * n);
    for (std::size_t j = 0; j < nb; ++j) unit[j * n + j0 + j] = 1.0;
    apply_checked(op, unit.data(), cols.data(), nb, report, where);
    M.middleCols(static_cast<Eigen::Index>(j0), static_cast<Eigen::Index>(nb)) =
        Eigen::Map<const Eigen::MatrixXd>(cols.data(), static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(nb));
  }
  const double asym = (M - M.transpose()).norm();
  if (asym > 1e-10 * M.norm()) {
    std::ostringstream msg;
    msg << "the operator is not symmetric: |M - M^T| / |M| = " << asym / M.norm();
    fail(ErrorCode::numerical_failure, where, msg.str());
  }
  return 0.5 * (M + M.transpose());
}

}  // namespace

SqrtReport dense_sqrt(const LinearOperatorView& op, std::span<const double> z, std::span<double> w, std::size_t nrhs,
                      const SqrtOptions& options) {
  const char* where = options.method == SqrtMethod::cholesky ? "sqrt_apply(cholesky)" : "sqrt_apply(eigen)";
  const std::size_t n = op.n;
  if (n > kDenseSqrtMaxRows) {
    fail(ErrorCode::out_of_memory, where,
         "dense square roots are limited to " + std::to_string(kDenseSqrtMaxRows) +
             " rows (N = " + std::to_string(kDenseSqrtMaxRows / 3) + " particles); got " + std::to_string(n) +
             " rows: use lanczos or chebyshev");
  }
  SqrtReport report;
  report.method = options.method;
  const Eigen::MatrixXd M = assemble(op, report, where);
  const auto ni = static_cast<Eigen::Index>(n);
  const auto ri = static_cast<Eigen::Index>(nrhs);
  Eigen::Map<const Eigen::MatrixXd> Z(z.data(), ni, ri);
  Eigen::Map<Eigen::MatrixXd> W(w.data(), ni, ri);
  if (options.method == SqrtMethod::cholesky) {
    const Eigen::LLT<Eigen::MatrixXd> llt(M);
    if (llt.info() != Eigen::Success) {
      fail(ErrorCode::numerical_failure, where, "the operator is not positive definite: Cholesky factorization failed");
    }
    W = llt.matrixL() * Z;
  } else {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M);
    if (es.info() != Eigen::Success) fail(ErrorCode::numerical_failure, where, "the eigensolver did not converge");
    const double lmin = es.eigenvalues()[0];
    if (!(lmin > 0.0)) {
      std::ostringstream msg;
      msg << "the operator is not positive definite: smallest eigenvalue " << lmin << " <= 0";
      fail(ErrorCode::numerical_failure, where, msg.str());
    }
    const Eigen::MatrixXd& Q = es.eigenvectors();
    W = Q * (es.eigenvalues().cwiseSqrt().asDiagonal() * (Q.transpose() * Z));
  }
  return report;
}

}  // namespace rpyfmm::rpy::sqrt_detail
