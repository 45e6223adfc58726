// rpyfmm — sqrt_apply(): validation (once, here) and dispatch to the
// Lanczos, Chebyshev and dense square-root solvers.
#include <algorithm>
#include <cmath>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "../load_scaling.hpp"
#include "detail.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::rpy::sqrt_detail {

void require_chebyshev_bounds(const SqrtOptions& options, const char* where) {
  const double a = options.lambda_min, b = options.lambda_max;
  if (a == 0.0 && b == 0.0) {
    require(options.bound_estimate_iterations >= 2, ErrorCode::invalid_argument, where,
            "bound_estimate_iterations must be >= 2, got " + std::to_string(options.bound_estimate_iterations));
  } else if (!(std::isfinite(a) && std::isfinite(b) && a > 0.0 && b > a)) {
    std::ostringstream msg;
    msg << "Chebyshev eigenvalue bounds must satisfy 0 < lambda_min < lambda_max (or both 0 = estimate), got [" << a
        << ", " << b << "]";
    fail(ErrorCode::invalid_argument, where, msg.str());
  }
}

}  // namespace rpyfmm::rpy::sqrt_detail

namespace rpyfmm::rpy {

const char* to_string(SqrtMethod method) {
  switch (method) {
    case SqrtMethod::automatic:
      return "automatic";
    case SqrtMethod::lanczos:
      return "lanczos";
    case SqrtMethod::chebyshev:
      return "chebyshev";
    case SqrtMethod::cholesky:
      return "cholesky";
    case SqrtMethod::eigen:
      return "eigen";
    case SqrtMethod::split:
      return "split";
  }
  return "unknown";
}

SqrtMethod sqrt_method_from_string(const std::string& name) {
  for (auto m : {SqrtMethod::automatic, SqrtMethod::lanczos, SqrtMethod::chebyshev, SqrtMethod::cholesky,
                 SqrtMethod::eigen, SqrtMethod::split}) {
    if (name == to_string(m)) return m;
  }
  fail(ErrorCode::invalid_argument, "sqrt method",
       "unknown method '" + name + "' (expected automatic, lanczos, chebyshev, cholesky, eigen or split)");
}

const char* to_string(SqrtPreconditioner preconditioner) {
  switch (preconditioner) {
    case SqrtPreconditioner::none:
      return "none";
    case SqrtPreconditioner::block:
      return "block";
    case SqrtPreconditioner::automatic:
      return "automatic";
  }
  return "unknown";
}

SqrtPreconditioner sqrt_preconditioner_from_string(const std::string& name) {
  for (auto p : {SqrtPreconditioner::none, SqrtPreconditioner::block, SqrtPreconditioner::automatic}) {
    if (name == to_string(p)) return p;
  }
  fail(ErrorCode::invalid_argument, "sqrt preconditioner",
       "unknown preconditioner '" + name + "' (expected none, block or automatic)");
}

namespace {

/// The sampler of `options` on validated arguments.
SqrtReport sample_dispatch(const LinearOperatorView& op, std::span<const double> z, std::span<double> w,
                           std::size_t nrhs, const SqrtOptions& options, std::span<const double> first_product) {
  constexpr const char* where = "sqrt_apply";
  switch (options.method) {
    case SqrtMethod::automatic:
    case SqrtMethod::lanczos:
      return sqrt_detail::lanczos_sqrt(op, z, w, nrhs, options, first_product);
    case SqrtMethod::chebyshev:
      sqrt_detail::require_chebyshev_bounds(options, where);
      return sqrt_detail::chebyshev_sqrt(op, z, w, nrhs, options);
    case SqrtMethod::cholesky:
    case SqrtMethod::eigen:
      return sqrt_detail::dense_sqrt(op, z, w, nrhs, options);
    case SqrtMethod::split:
      fail(ErrorCode::not_supported, where, "the split sampler is only available for the PSE operator");
  }
  fail(ErrorCode::invalid_argument, where, "unknown square-root method");
}

}  // namespace

SqrtReport sqrt_apply(const LinearOperatorView& op, std::span<const double> z, std::span<double> w, std::size_t nrhs,
                      const SqrtOptions& options, std::span<const double> first_product) {
  constexpr const char* where = "sqrt_apply";
  require(op.n > 0, ErrorCode::invalid_input, where, "the operator has size 0");
  require(static_cast<bool>(op.apply), ErrorCode::invalid_argument, where, "the operator has no apply function");
  require(nrhs > 0, ErrorCode::invalid_argument, where, "number of right-hand sides must be > 0");
  const double tol = options.tolerance;
  if (!(std::isfinite(tol) && tol > 0.0 && tol < 1.0)) {
    std::ostringstream msg;
    msg << "tolerance must lie in (0, 1), got " << tol;
    fail(ErrorCode::invalid_argument, where, msg.str());
  }
  require(options.max_iterations >= 0, ErrorCode::invalid_argument, where,
          "max_iterations must be >= 0 (0 = automatic), got " + std::to_string(options.max_iterations));
  require_size(z, op.n * nrhs, where, "noise");
  require_size(std::span<const double>(w.data(), w.size()), op.n * nrhs, where, "output");
  require_finite(z, where, "noise");
  require(options.preconditioner != SqrtPreconditioner::block, ErrorCode::invalid_argument, where,
          "the block preconditioner needs the particles: use MobilityOperator::apply_sqrt or "
          "BlockPreconditioner::sample");
  if (!first_product.empty()) {
    require(nrhs == 1 && (options.method == SqrtMethod::lanczos || options.method == SqrtMethod::automatic),
            ErrorCode::invalid_argument, where, "a given first product serves Lanczos on one right-hand side only");
    require_size(first_product, op.n, where, "first product");
  }

  // Each noise vector whose largest entry lies outside [2^-100, 2^100] is sampled as 2^-k z and the
  // result scaled back (the samplers are linear in z, the scaling exact): entries of 1e300 overflowed
  // |z| to infinity, and Lanczos reported the operator as not positive definite.
  std::vector<int> exponents(nrhs);
  for (std::size_t j = 0; j < nrhs; ++j) exponents[j] = detail::load_scale_exponent({z.subspan(j * op.n, op.n)});
  if (std::ranges::all_of(exponents, [](int k) { return k == 0; }))
    return sample_dispatch(op, z, w, nrhs, options, first_product);
  std::vector<double> scaled(z.begin(), z.end()), scaled_product(first_product.begin(), first_product.end());
  for (std::size_t j = 0; j < nrhs; ++j)
    for (double& v : std::span<double>(scaled).subspan(j * op.n, op.n)) v = std::ldexp(v, -exponents[j]);
  for (double& v : scaled_product) v = std::ldexp(v, -exponents[0]);  // nrhs = 1 where given
  const SqrtReport report = sample_dispatch(op, scaled, w, nrhs, options, scaled_product);
  for (std::size_t j = 0; j < nrhs; ++j)
    for (double& v : w.subspan(j * op.n, op.n)) v = std::ldexp(v, exponents[j]);
  return report;
}

}  // namespace rpyfmm::rpy
