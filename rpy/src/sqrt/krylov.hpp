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
  double start(const double* z) { return start(z, space_->dot(z, z)); }
  /// The same with zz = z . z computed by the caller (as the space's dot gives it).
  double start(const double* z, double zz);
  /// The vector v_j to multiply by M next.
  [[nodiscard]] const double* current() const { return space_->vector(space_->basis_size() - 1); }
  /// Consumes y = M v_j (overwritten): computes alpha_j and beta_j and, unless
  /// an invariant subspace was found, the next basis vector. Throws
  /// numerical_failure if alpha_j <= 0 (M not positive definite), naming
  /// `where`, the iteration and the right-hand side `rhs`.
  /// Returns true on breakdown (beta_j <= breakdown_tol * |T|, or the basis spans R^n).
  bool step(double* y, const std::string& where, std::size_t rhs);

  /// The inner products a step needs next, all against its y: v_q . y for q < k (basis, as the
  /// space's dots gives them), v_j . y (current, as its dot) or y . y (self, as its dot); none:
  /// the step is done.
  struct Need {
    enum Kind { none, basis, current, self } kind = none;
    std::size_t k = 0;  // basis: how many
  };
  /// step() cut at its inner products, so that several processes can compute theirs together
  /// (rpyfmm::mpi's samplers of several right-hand sides reduce all of them in one exchange):
  /// begin_step(y) returns the first need; continue_step(values) takes its values and returns the
  /// next. step() is these calls with the space's own inner products, bit for bit.
  Need begin_step(double* y);
  Need continue_step(const double* values, const std::string& where, std::size_t rhs);
  /// Whether the last completed step found an invariant subspace (step()'s return value).
  [[nodiscard]] bool broke_down() const { return breakdown_; }

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
  // The step under way: its y, the stage reached (which inner products it waits for) and the
  // breakdown test of the last step.
  double* y_ = nullptr;
  enum class Stage { first, second_pass, norm } stage_ = Stage::first;
  bool breakdown_ = false;
};

/// One right-hand side of the Lanczos square root (lanczos.cpp): its process, the coefficients
/// c_m = |z| T_m^{1/2} e_1 of its iterate and the stopping test's last relative change.
struct LanczosRhs {
  LanczosProcess process;
  double znorm = 0.0;
  Eigen::VectorXd coeff;
  double change = 0.0;
  bool active = true;
  bool breakdown = false;
};

/// The Lanczos square root's iteration limit: options.max_iterations, or min(n, 500).
int lanczos_max_iterations(const SqrtOptions& options, std::size_t n);

/// After the Lanczos step of right-hand side k at iteration `it` (`breakdown`: what the step
/// returned): the new coefficients and the stopping test (Ando, Chow & Saad 2012, sec. II.B). When
/// this right-hand side is done (converged, broken down or out of iterations), writes its w (in the
/// process's memory) and marks it inactive; throws numerical_failure where it did not converge
/// and options.throw_if_not_converged.
void conclude_lanczos_step(LanczosRhs& s, bool breakdown, int it, int max_it, const SqrtOptions& options, std::size_t k,
                           double* w, SqrtReport& report);

/// Eigenvalues (ascending) and eigenvectors of a tridiagonal matrix.
struct TridiagonalEigen {
  Eigen::VectorXd values;
  Eigen::MatrixXd vectors;
  [[nodiscard]] const Eigen::VectorXd& eigenvalues() const { return values; }
  [[nodiscard]] const Eigen::MatrixXd& eigenvectors() const { return vectors; }
};

/// Eigen-decomposition of the m x m tridiagonal T (alpha: m, beta: >= m-1). Eigen's
/// computeFromTridiagonal deflates a subdiagonal entry e where (e / epsilon)^2 <= |d_i| + |d_i+1|,
/// a test that is not scale invariant: on T of magnitude 1e-32 (the mobility of eta a = 1e30) it
/// zeroed every e and the Lanczos square root was 30 % wrong after two iterations (1e-7 at 1e-20).
/// T whose largest entry lies outside [2^-10, 2^10] is therefore decomposed as 4^-k T with that
/// entry near 1 (exact, and so is the square root of 4^k), and the eigenvalues scaled back; others
/// as they are, bit for bit.
TridiagonalEigen tridiagonal_eigen(const std::vector<double>& alpha, const std::vector<double>& beta, int m);

}  // namespace rpyfmm::rpy::sqrt_detail
