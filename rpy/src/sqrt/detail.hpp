// rpyfmm — internals shared by the square-root solvers (not installed).
//
// Vector kernels whose results do not depend on the number of OpenMP threads:
// reductions are split into fixed-size chunks (independent of the thread
// count), summed per chunk in parallel and then over chunks in order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::rpy::sqrt_detail {

/// Fixed chunk length of the reductions: the summation order depends on n only, never on threads.
/// Each chunk is summed in index order from 0, then the chunk sums in order (dots: always; dot:
/// when there are several). rpyfmm::mpi's Krylov space reproduces this order across ranks.
inline constexpr std::size_t kReductionChunk = 4096;

/// Deterministic inner product x . y (length n).
double dot(const double* x, const double* y, std::size_t n);
/// Deterministic 2-norm.
double norm2(const double* x, std::size_t n);
/// y += a x (elementwise, parallel).
void axpy(double a, const double* x, double* y, std::size_t n);
/// x *= a.
void scale(double a, double* x, std::size_t n);
/// h[q] = v_q . y for every vector v_q of `v` (length n each) in one pass over y; h[q] equals
/// dot(v_q.data(), y, n) bit for bit (the same chunks, summed in the same order).
void dots(const std::vector<std::vector<double>>& v, const double* y, std::size_t n, double* h);
void dots(const double* const* v, std::size_t m, const double* y, std::size_t n, double* h);
/// y -= sum_q h[q] v_q in one pass over y (classical Gram-Schmidt's update).
void subtract_combination(const std::vector<std::vector<double>>& v, const double* h, double* y, std::size_t n);
void subtract_combination(const double* const* v, std::size_t m, const double* h, double* y, std::size_t n);

/// Throws numerical_failure naming `where`, the entry, the right-hand side and `product` if one of
/// the nrhs vectors y (n each) holds NaN/Inf.
void require_finite_product(const double* y, std::size_t n, std::size_t nrhs, const char* where, long long product);

/// Applies `op` to `nrhs` vectors and counts the call in `report`; throws
/// numerical_failure if the result holds NaN/Inf (names `where`).
void apply_checked(const LinearOperatorView& op, const double* x, double* y, std::size_t nrhs, SqrtReport& report,
                   const char* where);

/// Throws invalid_argument naming `where` unless options.lambda_min / lambda_max are both 0 (then
/// bound_estimate_iterations >= 2) or finite with 0 < lambda_min < lambda_max.
void require_chebyshev_bounds(const SqrtOptions& options, const char* where);

/// Solvers; inputs are already validated by sqrt_apply().
/// lanczos_sqrt: `first_product` = op z (nrhs = 1) or empty, as in sqrt_apply.
SqrtReport lanczos_sqrt(const LinearOperatorView& op, std::span<const double> z, std::span<double> w, std::size_t nrhs,
                        const SqrtOptions& options, std::span<const double> first_product = {});
SqrtReport chebyshev_sqrt(const LinearOperatorView& op, std::span<const double> z, std::span<double> w,
                          std::size_t nrhs, const SqrtOptions& options);
SqrtReport dense_sqrt(const LinearOperatorView& op, std::span<const double> z, std::span<double> w, std::size_t nrhs,
                      const SqrtOptions& options);

/// Coefficients c_0..c_K of the Chebyshev interpolant of sqrt on [a, b] at
/// K+1 Chebyshev points of the first kind (sqrt(x) = sum c_k T_k(t), with
/// t = (2x - a - b)/(b - a)); exposed for the tests.
std::vector<double> chebyshev_sqrt_coefficients(double a, double b, int K);

}  // namespace rpyfmm::rpy::sqrt_detail
