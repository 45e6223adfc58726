// rpyfmm — one Lanczos process (a Krylov basis of M from a start vector),
// shared by the Lanczos square root and the spectrum-bound estimate.
// Internal header (not installed).
#pragma once

#include <Eigen/Dense>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "krylov_space.hpp"

namespace rpyfmm::rpy::sqrt_detail {

/// Symmetric Lanczos (Golub & Van Loan, Matrix Computations, Alg. 10.1.1):
/// M V_m = V_m T_m + beta_m v_{m+1} e_m^T with T_m = tridiag(beta, alpha, beta).
/// The basis lives in a KrylovSpace: host vectors of its own, or a space given (device memory);
/// every vector argument is in that space's memory.
class LanczosProcess {
 public:
  LanczosProcess(std::size_t n, bool reorthogonalize)
      : owned_(std::make_unique<HostKrylovSpace>(n)), space_(owned_.get()), n_(n), reorthogonalize_(reorthogonalize) {}
  LanczosProcess(KrylovSpace& space, bool reorthogonalize)
      : space_(&space), n_(space.n()), reorthogonalize_(reorthogonalize) {}

  /// Starts from z; returns |z| (0 means nothing to do: no basis is built).
  double start(const double* z);
  /// The vector v_j to multiply by M next.
  [[nodiscard]] const double* current() const { return space_->vector(space_->basis_size() - 1); }
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
  std::unique_ptr<KrylovSpace> owned_;
  KrylovSpace* space_;
  std::size_t n_;
  bool reorthogonalize_;
  std::vector<double> alpha_, beta_;
  double tnorm_ = 0.0;  // running estimate of |T| (max |alpha| + 2 max beta)
};

/// Eigen-decomposition of the m x m tridiagonal T (alpha: m, beta: >= m-1).
Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> tridiagonal_eigen(const std::vector<double>& alpha,
                                                                 const std::vector<double>& beta, int m);

}  // namespace rpyfmm::rpy::sqrt_detail
