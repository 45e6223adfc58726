// rpyfmm — square roots of symmetric positive definite operators:
// w = M^{1/2} z for Brownian displacements (MATH.md §4).
//
// The solvers need only products with M ("apply M"), so they serve every
// mobility operator (direct, FMM, PSE) alike. They live in rpyfmm::rpy rather
// than rpyfmm::bd because the PSE operator's split sampler uses Lanczos on its
// real-space part; rpyfmm::bd re-exports them for BD users.
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

struct SqrtOptions {
  SqrtMethod method = SqrtMethod::automatic;
  /// Relative tolerance: Lanczos stops when successive iterates differ by less
  /// than tol * |iterate|; Chebyshev picks its degree from it. In (0, 1).
  double tolerance = 1e-3;
  /// Maximum Lanczos iterations / Chebyshev degree (0 = automatic).
  int max_iterations = 0;
  /// Full reorthogonalization of the Lanczos basis (costs O(n m) memory and time per step).
  bool reorthogonalize = true;
  /// Chebyshev eigenvalue bounds; both 0 = estimate with a few Lanczos steps (padded).
  double lambda_min = 0.0;
  double lambda_max = 0.0;
};

struct SqrtReport {
  SqrtMethod method = SqrtMethod::automatic;  ///< method actually used
  int iterations = 0;                         ///< Lanczos steps / Chebyshev degree / 0 for dense
  double error_estimate = 0.0;                ///< last relative change (Lanczos) or bound (Chebyshev)
  int operator_applications = 0;              ///< number of products with M
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
SqrtReport sqrt_apply(const LinearOperatorView& op, std::span<const double> z, std::span<double> w,
                      std::size_t nrhs, const SqrtOptions& options);

}  // namespace rpyfmm::rpy
