// rpyfmm — square roots of symmetric positive definite operators:
// w = M^{1/2} z for Brownian displacements (docs/theory/samplers.md).
//
// The solvers need only products with M ("apply M"), so they serve every
// mobility operator (direct, FMM, PSE) alike. They live in rpyfmm::rpy rather
// than rpyfmm::bd because the PSE operator's split sampler uses Lanczos on its
// real-space part; rpyfmm::bd re-exports them for BD users.
//
// Which method when
// -----------------
// * lanczos (default): adapts to the spectrum and to z; no eigenvalue bounds
//   needed; iterations grow slowly with the condition number (~ sqrt(kappa)
//   at worst, far fewer on RPY matrices). Costs O(n m) memory for the Krylov
//   basis (m = iterations). Best choice in general.
// * chebyshev: a fixed polynomial of the operator; memory O(n) whatever the
//   degree, no inner products (cheap to distribute), and with user-given
//   bounds (estimate_spectrum_bounds once per configuration, reused for many
//   noise vectors) the cost per sample is known in advance. Needs more
//   products than Lanczos for the same accuracy (degree ~ sqrt(kappa) log(1/tol))
//   and is only as good as the bounds: a lambda_min above the true smallest
//   eigenvalue silently degrades the result there.
// * cholesky / eigen: dense, O(n^3), small systems only (n = 3N <= 6000).
//   `cholesky` gives L z with L L^T = M (correct covariance, not the principal
//   root); `eigen` gives the principal root exactly (the tests' reference).
#pragma once

#include <cstddef>
#include <functional>
#include <span>
#include <string>

namespace rpyfmm::rpy {

enum class SqrtMethod {
  automatic,  ///< the operator's preferred method (PSE: split sampler; others: Lanczos)
  lanczos,    ///< Krylov / Lanczos (Ando, Chow & Saad 2012)
  chebyshev,  ///< Chebyshev polynomial (Fixman 1986)
  cholesky,   ///< dense Cholesky factor L (L L^T = M), small N only
  eigen,      ///< dense principal square root via the symmetric eigensolver, small N only
  split,      ///< PSE split sampler M_r^{1/2} z1 + M_w^{1/2} z2 (PSE operator only)
};

const char* to_string(SqrtMethod method);
SqrtMethod sqrt_method_from_string(const std::string& name);  // throws rpyfmm::Error naming the value

/// Preconditioning of the Krylov samplers (Lanczos, Chebyshev) of a mobility operator
/// (rpyfmm/rpy/block_preconditioner.hpp).
enum class SqrtPreconditioner {
  none,       ///< w = M^{1/2} z, the principal square root
  block,      ///< w = L (L^{-1} M L^{-T})^{1/2} z with L L^T = M's block diagonal over spatial blocks
              ///< of nearby particles: the same covariance M (w w^T averages to M), fewer products
  automatic,  ///< `block` where the sampler is Lanczos, or Chebyshev with estimated bounds, on a
              ///< mobility operator; `none` otherwise (the BD engine's default)
};

const char* to_string(SqrtPreconditioner preconditioner);
SqrtPreconditioner sqrt_preconditioner_from_string(const std::string& name);  // throws rpyfmm::Error

/// Largest dense system (n = 3N rows) that the cholesky / eigen methods accept.
inline constexpr std::size_t kDenseSqrtMaxRows = 6000;

struct SqrtOptions {
  SqrtMethod method = SqrtMethod::automatic;
  /// Relative tolerance, in (0, 1).
  /// Lanczos: stops when successive iterates differ by less than tol * |iterate|
  ///   (Ando, Chow & Saad 2012, sec. II.B). The change underestimates the error
  ///   left: on RPY suspensions the true relative error is measured at 2-3 x tol
  ///   (docs/theory/samplers.md; the tests require <= 10 x tol). Ask for tol / 3
  ///   if the error itself must stay below a bound.
  /// Chebyshev: the degree is the smallest whose neglected Chebyshev coefficients
  ///   of sqrt on [lambda_min, lambda_max] sum to <= tol * sqrt(lambda_min), which
  ///   bounds the relative error by tol when the bounds enclose the spectrum.
  double tolerance = 1e-3;
  /// Maximum Lanczos iterations / Chebyshev degree (0 = automatic: Lanczos
  /// min(n, 500), Chebyshev 5000).
  int max_iterations = 0;
  /// Full reorthogonalization of the Lanczos basis against all previous vectors
  /// (two classical Gram-Schmidt passes; O(n m) work per step). Keeps the basis
  /// orthonormal, so the convergence test and the breakdown test are reliable.
  bool reorthogonalize = true;
  /// Lanczos: when max_iterations is reached before the tolerance, throw
  /// rpyfmm::Error (numerical_failure) if true; otherwise return the last
  /// iterate with report.converged = false.
  bool throw_if_not_converged = true;
  /// Lanczos and Chebyshev only, and only through a MobilityOperator (it needs the particles):
  /// `block` draws a different but equally valid displacement, B z with B B^T = M, in 1.7-2.6x
  /// fewer products than M^{1/2} z with Lanczos (docs/theory/samplers.md).
  /// With `block`, another method (PSE's split sampler, the dense methods) is an error; `automatic`
  /// quietly falls back to none there, for Chebyshev with given bounds and for sqrt_apply on a
  /// bare operator. Chebyshev with `block` works on A = G M G^T: lambda_min / lambda_max, if
  /// given, must bound A's spectrum (estimate_spectrum_bounds(BlockPreconditioner::precondition(..))).
  SqrtPreconditioner preconditioner = SqrtPreconditioner::none;
  /// Particles per block of the `block` preconditioner (at most; blocks hold half to all of
  /// it); 0 = BlockPreconditioner::automatic_block(N): N / 64, between 16 and 32.
  int preconditioner_block = 0;
  /// Chebyshev eigenvalue bounds; both 0 = estimate with a few Lanczos steps
  /// (see estimate_spectrum_bounds). Otherwise 0 < lambda_min < lambda_max: bounds of M, or of
  /// G M G^T with the `block` preconditioner.
  double lambda_min = 0.0;
  double lambda_max = 0.0;
  /// Lanczos steps used to estimate the Chebyshev bounds (when not given).
  int bound_estimate_iterations = 30;
};

struct SqrtReport {
  SqrtMethod method = SqrtMethod::automatic;  ///< method actually used
  int iterations = 0;                         ///< Lanczos steps (max over rhs) / Chebyshev degree / 0 for dense
  double error_estimate = 0.0;                ///< last relative change (Lanczos, max over rhs) or bound (Chebyshev)
  int operator_applications = 0;              ///< calls of op.apply (one call serves all right-hand sides)
  long long vector_products = 0;              ///< products M x summed over right-hand sides
  bool converged = true;                      ///< false only when throw_if_not_converged = false and it did not
  bool breakdown = false;                     ///< Lanczos found an invariant subspace (result exact)
  double lambda_min = 0.0;                    ///< Chebyshev: bounds used (estimated or given; of G M G^T
                                              ///< when preconditioned)
  double lambda_max = 0.0;
  std::size_t preconditioner_blocks = 0;  ///< blocks of the `block` preconditioner (0: none used)
};

/// A symmetric operator given only by its action on nrhs right-hand sides
/// stored one after another (each of length n).
struct LinearOperatorView {
  std::size_t n = 0;
  std::function<void(std::span<const double> x, std::span<double> y, std::size_t nrhs)> apply;
};

/// w = M^{1/2} z for nrhs right-hand sides (block variant: one operator
/// application per iteration serves all right-hand sides). `z` and `w` hold
/// nrhs vectors of length op.n one after another. Throws rpyfmm::Error on bad
/// options, wrong sizes, or when M is detected not to be positive definite.
/// Results do not depend on the number of OpenMP threads (inner products are
/// summed in a fixed order) provided op.apply does not.
///
/// `first_product`, when not empty, is the product op z, already computed by the caller (the BD
/// engine gets it in one block pass with the drift M F). Lanczos starts from v_1 = z / |z|, so
/// its first product op v_1 = (op z) / |z| then costs no call of op.apply (and is not counted in
/// the report's operator_applications). Lanczos only (method lanczos or automatic), nrhs = 1.
SqrtReport sqrt_apply(const LinearOperatorView& op, std::span<const double> z, std::span<double> w, std::size_t nrhs,
                      const SqrtOptions& options, std::span<const double> first_product = {});

/// Bounds on the spectrum of an SPD operator for the Chebyshev method.
struct SpectrumBounds {
  double lambda_min = 0.0;  ///< padded lower bound (smallest Ritz value / 2)
  double lambda_max = 0.0;  ///< padded upper bound (largest Ritz value + Lanczos residual bound, x 1.01)
  double ritz_min = 0.0;    ///< smallest Ritz value found
  double ritz_max = 0.0;    ///< largest Ritz value found
  int iterations = 0;       ///< Lanczos steps taken
};

/// Estimates the extreme eigenvalues of `op` with `iterations` steps of
/// reorthogonalized Lanczos from a fixed pseudo-random start vector (so the
/// result is reproducible), and pads them: the largest Ritz value converges
/// fast from below, so lambda_max = 1.01 (theta_max + beta_m |s_m|) (Lanczos
/// residual bound, Saad, Numerical Methods for Large Eigenvalue Problems,
/// Prop. 6.8); the smallest converges slowly from above, so lambda_min =
/// theta_min / 2. Compute once per configuration and pass in SqrtOptions.
/// Throws rpyfmm::Error when the operator is found not positive definite.
SpectrumBounds estimate_spectrum_bounds(const LinearOperatorView& op, int iterations = 30);

}  // namespace rpyfmm::rpy
