// rpyfmm — the Lanczos process shared by the Lanczos square root and the
// Chebyshev bound estimate.
#include "krylov.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "detail.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::sqrt_detail {

double LanczosProcess::start(const double* z) {
  basis_.clear();
  alpha_.clear();
  beta_.clear();
  tnorm_ = 0.0;
  const double nz = norm2(z, n_);
  if (nz == 0.0) return 0.0;
  basis_.emplace_back(z, z + n_);
  scale(1.0 / nz, basis_.back().data(), n_);
  return nz;
}

bool LanczosProcess::step(double* y, const std::string& where, std::size_t rhs) {
  const std::size_t j = alpha_.size();
  const double* v = basis_[j].data();
  // With reorthogonalization, h = V^T y in one pass; its last entry is alpha_j = v_j . y (bit
  // for bit dot(v_j, y)).
  std::vector<double> h(reorthogonalize_ ? basis_.size() : 0);
  if (reorthogonalize_) dots(basis_, y, n_, h.data());
  const double a = reorthogonalize_ ? h[j] : dot(v, y, n_);
  // alpha_j = v_j^T M v_j is a Rayleigh quotient: <= 0 proves M is not SPD.
  if (!(a > 0.0)) {
    std::ostringstream msg;
    msg << "the operator is not positive definite: Lanczos coefficient alpha_" << j << " = v^T M v = " << a
        << " <= 0 at iteration " << j << " (right-hand side " << rhs << ")";
    fail(ErrorCode::numerical_failure, where, msg.str());
  }
  alpha_.push_back(a);
  if (reorthogonalize_) {
    // Full reorthogonalization by classical Gram-Schmidt, twice ("twice is enough": Giraud,
    // Langou & Rozloznik, Comput. Math. Appl. 50 (2005) 1069): the first pass, y -= V (V^T y),
    // holds the three-term step (alpha_j v_j + beta_{j-1} v_{j-1}) and the reorthogonalization
    // against the older vectors at once. Each pass reads y and the basis once for the
    // products and once for the update, against five vector passes per basis vector for
    // modified Gram-Schmidt (bench/README.md, session 13).
    subtract_combination(basis_, h.data(), y, n_);
    dots(basis_, y, n_, h.data());
    subtract_combination(basis_, h.data(), y, n_);
  } else {
    axpy(-a, v, y, n_);
    if (j > 0) axpy(-beta_[j - 1], basis_[j - 1].data(), y, n_);
  }
  const double b = norm2(y, n_);
  tnorm_ = std::max(tnorm_, std::abs(a) + 2.0 * std::max(b, j > 0 ? beta_[j - 1] : 0.0));
  beta_.push_back(b);
  if (b <= breakdown_tol * tnorm_ || j + 1 >= n_) return true;  // invariant subspace: T_m is exact
  basis_.emplace_back(y, y + n_);
  scale(1.0 / b, basis_.back().data(), n_);
  return false;
}

void LanczosProcess::combine(const Eigen::VectorXd& coeff, double* out) const {
  std::fill(out, out + n_, 0.0);
  for (Eigen::Index i = 0; i < coeff.size(); ++i) axpy(coeff[i], basis_[static_cast<std::size_t>(i)].data(), out, n_);
}

Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> tridiagonal_eigen(const std::vector<double>& alpha,
                                                                const std::vector<double>& beta, int m) {
  Eigen::VectorXd d = Eigen::Map<const Eigen::VectorXd>(alpha.data(), m);
  Eigen::VectorXd e(std::max(m - 1, 0));
  for (int i = 0; i + 1 < m; ++i) e[i] = beta[static_cast<std::size_t>(i)];
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es;
  es.computeFromTridiagonal(d, e, Eigen::ComputeEigenvectors);
  return es;
}

}  // namespace rpyfmm::rpy::sqrt_detail
