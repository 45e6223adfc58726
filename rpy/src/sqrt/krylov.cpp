// rpyfmm — the Lanczos process shared by the Lanczos square root and the
// Chebyshev bound estimate.
#include "krylov.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "detail.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::sqrt_detail {

double LanczosProcess::start(const double* z, double zz) {
  space_->clear();
  alpha_.clear();
  beta_.clear();
  tnorm_ = 0.0;
  const double nz = std::sqrt(zz);
  if (nz == 0.0) return 0.0;
  space_->scale_into(1.0 / nz, z, space_->push());
  return nz;
}

bool LanczosProcess::step(double* y, const std::string& where, std::size_t rhs) {
  std::vector<double> values;
  for (Need need = begin_step(y); need.kind != Need::none; need = continue_step(values.data(), where, rhs)) {
    values.resize(std::max<std::size_t>(need.k, 1));
    if (need.kind == Need::basis) {
      space_->dots(need.k, y, values.data());
    } else {
      values[0] = space_->dot(need.kind == Need::self ? y : space_->vector(alpha_.size()), y);
    }
  }
  return breakdown_;
}

LanczosProcess::Need LanczosProcess::begin_step(double* y) {
  y_ = y;
  stage_ = Stage::first;
  // With reorthogonalization, h = V^T y in one pass; its last entry is alpha_j = v_j . y (bit
  // for bit dot(v_j, y)).
  if (reorthogonalize_) return {Need::basis, space_->basis_size()};
  return {Need::current, 1};
}

LanczosProcess::Need LanczosProcess::continue_step(const double* values, const std::string& where, std::size_t rhs) {
  const std::size_t j = alpha_.size();
  const std::size_t k = space_->basis_size();  // j + 1
  double* y = y_;
  if (stage_ == Stage::first) {
    const double a = reorthogonalize_ ? values[j] : values[0];
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
      // modified Gram-Schmidt (docs/theory/samplers.md).
      space_->subtract_combination(k, values, y);
      stage_ = Stage::second_pass;
      return {Need::basis, k};
    }
    space_->axpy(-a, space_->vector(j), y);
    if (j > 0) space_->axpy(-beta_[j - 1], space_->vector(j - 1), y);
    stage_ = Stage::norm;
    return {Need::self, 1};
  }
  if (stage_ == Stage::second_pass) {
    space_->subtract_combination(k, values, y);
    stage_ = Stage::norm;
    return {Need::self, 1};
  }
  const std::size_t jj = j - 1;  // alpha_j was pushed in the first stage
  const double a = alpha_.back();
  const double b = std::sqrt(values[0]);
  tnorm_ = std::max(tnorm_, std::abs(a) + 2.0 * std::max(b, jj > 0 ? beta_[jj - 1] : 0.0));
  beta_.push_back(b);
  breakdown_ = b <= breakdown_tol * tnorm_ || jj + 1 >= n_;  // invariant subspace: T_m is exact
  if (!breakdown_) space_->scale_into(1.0 / b, y, space_->push());
  return {};
}

void LanczosProcess::combine(const Eigen::VectorXd& coeff, double* out) const {
  space_->combine(static_cast<std::size_t>(coeff.size()), coeff.data(), out);
}

double* HostKrylovSpace::push() {
  if (count_ == basis_.size()) basis_.push_back(std::make_unique_for_overwrite<double[]>(n_));
  return basis_[count_++].get();
}

double* HostKrylovSpace::work() {
  work_.resize(n_);
  return work_.data();
}

double HostKrylovSpace::dot(const double* x, const double* y) {
  return sqrt_detail::dot(x, y, n_);
}

void HostKrylovSpace::dots(std::size_t k, const double* y, double* h) {
  std::vector<const double*> v(k);
  for (std::size_t q = 0; q < k; ++q) v[q] = basis_[q].get();
  sqrt_detail::dots(v.data(), k, y, n_, h);
}

void HostKrylovSpace::subtract_combination(std::size_t k, const double* h, double* y) {
  std::vector<const double*> v(k);
  for (std::size_t q = 0; q < k; ++q) v[q] = basis_[q].get();
  sqrt_detail::subtract_combination(v.data(), k, h, y, n_);
}

void HostKrylovSpace::axpy(double a, const double* x, double* y) {
  sqrt_detail::axpy(a, x, y, n_);
}

void HostKrylovSpace::scale_into(double a, const double* x, double* out) {
  if (out != x) std::copy_n(x, n_, out);
  sqrt_detail::scale(a, out, n_);
}

void HostKrylovSpace::combine(std::size_t k, const double* c, double* out) {
  std::fill(out, out + n_, 0.0);
  for (std::size_t q = 0; q < k; ++q) sqrt_detail::axpy(c[q], basis_[q].get(), out, n_);
}

void HostKrylovSpace::require_finite(const double* y, const char* where, long long product) {
  require_finite_product(y, n_, 1, where, product);
}

TridiagonalEigen tridiagonal_eigen(const std::vector<double>& alpha, const std::vector<double>& beta, int m) {
  Eigen::VectorXd d = Eigen::Map<const Eigen::VectorXd>(alpha.data(), m);
  Eigen::VectorXd e(std::max(m - 1, 0));
  for (int i = 0; i + 1 < m; ++i) e[i] = beta[static_cast<std::size_t>(i)];
  const double largest = std::max(d.cwiseAbs().maxCoeff(), m > 1 ? e.cwiseAbs().maxCoeff() : 0.0);
  // An even power of two (krylov.hpp): every step of the QR iteration, square roots included,
  // scales exactly; only the deflation test sees the matrix near 1.
  const int k = largest > 0.0 && std::isfinite(largest) && (largest < 0x1p-10 || largest > 0x1p10)
                    ? 2 * (std::ilogb(largest) / 2)
                    : 0;
  if (k != 0) {
    for (double& v : d) v = std::ldexp(v, -k);
    for (double& v : e) v = std::ldexp(v, -k);
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es;
  es.computeFromTridiagonal(d, e, Eigen::ComputeEigenvectors);
  TridiagonalEigen out{es.eigenvalues(), es.eigenvectors()};
  if (k != 0)
    for (double& v : out.values) v = std::ldexp(v, k);
  return out;
}

}  // namespace rpyfmm::rpy::sqrt_detail
