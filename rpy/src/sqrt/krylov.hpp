// rpyfmm — one Lanczos process (a Krylov basis of M from a start vector),
// shared by the Lanczos square root and the spectrum-bound estimate.
// Internal header (not installed).
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <string>
#include <vector>

namespace rpyfmm::rpy::sqrt_detail {

/// Symmetric Lanczos (Golub & Van Loan, Matrix Computations, Alg. 10.1.1):
/// M V_m = V_m T_m + beta_m v_{m+1} e_m^T with T_m = tridiag(beta, alpha, beta).
class LanczosProcess {
 public:
  LanczosProcess(std::size_t n, bool reorthogonalize) : n_(n), reorthogonalize_(reorthogonalize) {}

  /// Starts from z; returns |z| (0 means nothing to do: no basis is built).
  double start(const double* z);
  /// The vector v_j to multiply by M next.
  [[nodiscard]] const double* current() const { return basis_.back().data(); }
  /// Consumes y = M v_j (overwritten): computes alpha_j and beta_j and, unless
  /// an invariant subspace was found, the next basis vector. Throws
  /// numerical_failure if alpha_j <= 0 (M not positive definite), naming
  /// `where`, the iteration and the right-hand side `rhs`.
  /// Returns true on breakdown (beta_j <= breakdown_tol * |T|, or the basis spans R^n).
  bool step(double* y, const std::string& where, std::size_t rhs);

  [[nodiscard]] int size() const { return static_cast<int>(alpha_.size()); }
  [[nodiscard]] const std::vector<double>& alpha() const { return alpha_; }
  [[nodiscard]] const std::vector<double>& beta() const { return beta_; }
  /// out = sum_i coeff[i] v_i over the first coeff.size() basis vectors.
  void combine(const Eigen::VectorXd& coeff, double* out) const;

  /// Relative size of beta_j below which the Krylov space is taken as invariant.
  static constexpr double breakdown_tol = 1e-11;

 private:
  std::size_t n_;
  bool reorthogonalize_;
  std::vector<std::vector<double>> basis_;
  std::vector<double> alpha_, beta_;
  double tnorm_ = 0.0;  // running estimate of |T| (max |alpha| + 2 max beta)
};

/// Eigen-decomposition of the m x m tridiagonal T (alpha: m, beta: >= m-1).
Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> tridiagonal_eigen(const std::vector<double>& alpha,
                                                                const std::vector<double>& beta, int m);

}  // namespace rpyfmm::rpy::sqrt_detail
