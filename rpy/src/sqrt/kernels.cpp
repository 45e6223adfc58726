// rpyfmm — thread-count-independent vector kernels for the square-root solvers.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "detail.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::sqrt_detail {

namespace {
constexpr std::size_t kChunk = kReductionChunk;
}  // namespace

double dot(const double* x, const double* y, std::size_t n) {
  const std::size_t nchunks = (n + kChunk - 1) / kChunk;
  if (nchunks <= 1) {
    double s = 0.0;
    for (std::size_t i = 0; i < n; ++i) s += x[i] * y[i];
    return s;
  }
  std::vector<double> partial(nchunks);
  const auto nc = static_cast<std::int64_t>(nchunks);
#pragma omp parallel for schedule(static) if (n > 4 * kChunk)
  for (std::int64_t c = 0; c < nc; ++c) {
    const std::size_t lo = static_cast<std::size_t>(c) * kChunk;
    const std::size_t hi = std::min(n, lo + kChunk);
    double s = 0.0;
    for (std::size_t i = lo; i < hi; ++i) s += x[i] * y[i];
    partial[static_cast<std::size_t>(c)] = s;
  }
  double s = 0.0;
  for (double p : partial) s += p;
  return s;
}

double norm2(const double* x, std::size_t n) {
  return std::sqrt(dot(x, x, n));
}

void axpy(double a, const double* x, double* y, std::size_t n) {
  const auto nn = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static) if (n > 4 * kChunk)
  for (std::int64_t i = 0; i < nn; ++i) y[i] += a * x[i];
}

void scale(double a, double* x, std::size_t n) {
  const auto nn = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static) if (n > 4 * kChunk)
  for (std::int64_t i = 0; i < nn; ++i) x[i] *= a;
}

namespace {
std::vector<const double*> pointers(const std::vector<std::vector<double>>& v) {
  std::vector<const double*> p(v.size());
  for (std::size_t q = 0; q < v.size(); ++q) p[q] = v[q].data();
  return p;
}
}  // namespace

void dots(const std::vector<std::vector<double>>& v, const double* y, std::size_t n, double* h) {
  dots(pointers(v).data(), v.size(), y, n, h);
}

void subtract_combination(const std::vector<std::vector<double>>& v, const double* h, double* y, std::size_t n) {
  subtract_combination(pointers(v).data(), v.size(), h, y, n);
}

void dots(const double* const* v, std::size_t m, const double* y, std::size_t n, double* h) {
  const std::size_t nchunks = std::max<std::size_t>(1, (n + kChunk - 1) / kChunk);
  std::vector<double> partial(nchunks * m);
  const auto nc = static_cast<std::int64_t>(nchunks);
#pragma omp parallel for schedule(static) if (n > 4 * kChunk)
  for (std::int64_t c = 0; c < nc; ++c) {
    const std::size_t lo = static_cast<std::size_t>(c) * kChunk;
    const std::size_t hi = std::min(n, lo + kChunk);
    for (std::size_t q = 0; q < m; ++q) {  // the chunk of y stays in L1 across the vectors
      const double* x = v[q];
      double s = 0.0;
      for (std::size_t i = lo; i < hi; ++i) s += x[i] * y[i];
      partial[static_cast<std::size_t>(c) * m + q] = s;
    }
  }
  for (std::size_t q = 0; q < m; ++q) {
    double s = 0.0;
    for (std::size_t c = 0; c < nchunks; ++c) s += partial[c * m + q];
    h[q] = s;
  }
}

void subtract_combination(const double* const* v, std::size_t m, const double* h, double* y, std::size_t n) {
  const std::size_t nchunks = (n + kChunk - 1) / kChunk;
  const auto nc = static_cast<std::int64_t>(nchunks);
#pragma omp parallel for schedule(static) if (n > 4 * kChunk)
  for (std::int64_t c = 0; c < nc; ++c) {
    const std::size_t lo = static_cast<std::size_t>(c) * kChunk;
    const std::size_t hi = std::min(n, lo + kChunk);
    for (std::size_t q = 0; q < m; ++q) {
      const double* x = v[q];
      const double a = h[q];
      for (std::size_t i = lo; i < hi; ++i) y[i] -= a * x[i];
    }
  }
}

void apply_checked(const LinearOperatorView& op, const double* x, double* y, std::size_t nrhs, SqrtReport& report,
                   const char* where) {
  op.apply(std::span<const double>(x, op.n * nrhs), std::span<double>(y, op.n * nrhs), nrhs);
  ++report.operator_applications;
  report.vector_products += static_cast<long long>(nrhs);
  require_finite_product(y, op.n, nrhs, where, report.operator_applications);
}

void require_finite_product(const double* y, std::size_t n, std::size_t nrhs, const char* where, long long product) {
  for (std::size_t i = 0; i < n * nrhs; ++i) {
    if (!std::isfinite(y[i])) {
      fail(ErrorCode::numerical_failure, where,
           "the operator returned a non-finite value (entry " + std::to_string(i % n) + " of right-hand side " +
               std::to_string(i / n) + ") at product " + std::to_string(product));
    }
  }
}

}  // namespace rpyfmm::rpy::sqrt_detail
