// rpyfmm — Chebyshev polynomial square root (Fixman, Macromolecules 19, 1204
// (1986); Ando, Chow & Saad 2012, sec. II.C), block over right-hand sides.
//
// sqrt(lambda) on [a, b] is expanded as sum_k c_k T_k(t), t = (2 lambda - a - b)/(b - a),
// and applied with the three-term recurrence T_{k+1}(X) z = 2 X T_k(X) z - T_{k-1}(X) z,
// X = (2M - (a + b) I)/(b - a): one product with M per degree, memory O(n).
//
// Degree from the tolerance: sqrt is analytic inside the Bernstein ellipse
// through the branch point lambda = 0, rho = (sqrt(b) + sqrt(a))/(sqrt(b) - sqrt(a)),
// so |c_k| = O(rho^{-k}) (Trefethen, Approximation Theory and Approximation
// Practice, Thm. 8.1). We pick the smallest degree d with
//   sum_{k>d} |c_k| <= tol * sqrt(a),
// which bounds |p_d(M) z - M^{1/2} z| <= tol sqrt(a) |z| <= tol |M^{1/2} z| whenever
// the spectrum lies in [a, b] (reported as error_estimate).
#include <cmath>
#include <numbers>
#include <span>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "detail.hpp"
#include "krylov_space.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::sqrt_detail {

namespace {
constexpr const char* kWhere = "sqrt_apply(chebyshev)";
}

std::vector<double> chebyshev_sqrt_coefficients(double a, double b, int K) {
  const int npts = K + 1;
  std::vector<double> f(static_cast<std::size_t>(npts));
  for (int j = 0; j < npts; ++j) {
    const double t = std::cos(std::numbers::pi * (j + 0.5) / npts);
    f[static_cast<std::size_t>(j)] = std::sqrt(0.5 * (b - a) * t + 0.5 * (a + b));
  }
  std::vector<double> c(static_cast<std::size_t>(npts));
  for (int k = 0; k < npts; ++k) {
    double s = 0.0;
    for (int j = 0; j < npts; ++j)
      s += f[static_cast<std::size_t>(j)] * std::cos(std::numbers::pi * k * (j + 0.5) / npts);
    c[static_cast<std::size_t>(k)] = (k == 0 ? 1.0 : 2.0) * s / npts;
  }
  return c;
}

namespace {

// The truncated Chebyshev series of sqrt on [a, b]: coefficients, degree and error bound.
struct ChebyshevSeries {
  std::vector<double> c;
  int degree = 0;
  double error = 0.0;  // sum of the neglected |c_k| over sqrt(a)
};

ChebyshevSeries chebyshev_series(double a, double b, const SqrtOptions& options) {
  const int max_degree = options.max_iterations > 0 ? options.max_iterations : 5000;

  // Degree: coefficients of the interpolant at K+1 points (K a little beyond the
  // geometric-decay estimate, so the tail sum is resolved), then truncation.
  const double rho = (std::sqrt(b) + std::sqrt(a)) / (std::sqrt(b) - std::sqrt(a));
  const double target = options.tolerance * std::sqrt(a);
  const double k_est = std::log(1e3 * std::sqrt(b) / target) / std::log(rho);
  const int K = static_cast<int>(std::min<double>(k_est, 2.0 * max_degree)) + 16;
  std::vector<double> c = chebyshev_sqrt_coefficients(a, b, K);
  int d = K;
  double tail = 0.0;
  while (d > 0 && tail + std::abs(c[static_cast<std::size_t>(d)]) <= target)
    tail += std::abs(c[static_cast<std::size_t>(d--)]);
  if (d > max_degree) {
    std::ostringstream msg;
    msg << "tolerance " << options.tolerance << " needs degree " << d << " > maximum " << max_degree
        << " on the eigenvalue bounds [" << a << ", " << b << "] (condition number " << b / a
        << "); raise max_iterations or the tolerance, or use lanczos";
    fail(ErrorCode::numerical_failure, kWhere, msg.str());
  }

  return {std::move(c), d, tail / std::sqrt(a)};
}

}  // namespace

SqrtReport chebyshev_sqrt_in_space(const ChebyshevProducts& products, const double* z, double* w,
                                   const SqrtOptions& options) {
  SqrtReport report;
  report.method = SqrtMethod::chebyshev;
  double a = options.lambda_min;
  double b = options.lambda_max;
  if (a == 0.0 && b == 0.0) {
    std::vector<double> start(products.segments * products.entries);
    for (std::size_t s = 0; s < products.segments; ++s) {
      fill_bound_start(std::span<double>(start).subspan(s * products.entries, products.entries),
                       products.first_entry + s * products.segment_stride);
    }
    const SpectrumBounds est = estimate_spectrum_bounds_in_space(products.space, products.one, start.data(),
                                                                 options.bound_estimate_iterations);
    a = est.lambda_min;
    b = est.lambda_max;
    report.operator_applications += est.iterations;
    report.vector_products += est.iterations;
  }
  const std::size_t len = products.len;
  const auto product = [&](const double* x, double* y) { products.all(x, y, report); };
  report.lambda_min = a;
  report.lambda_max = b;
  const ChebyshevSeries series = chebyshev_series(a, b, options);
  const std::vector<double>& c = series.c;
  const int d = series.degree;
  report.iterations = d;
  report.error_estimate = series.error;

  // Three-term recurrence, elementwise but for the products (so a rank's share of the vectors
  // recurs as the serial vectors do).
  std::vector<double> t_prev(z, z + len), t_cur(len), mt(len);
  for (std::size_t i = 0; i < len; ++i) w[i] = c[0] * z[i];
  if (d == 0) return report;
  const double s1 = 2.0 / (b - a), s0 = (a + b) / (b - a);
  product(t_prev.data(), mt.data());
  for (std::size_t i = 0; i < len; ++i) t_cur[i] = s1 * mt[i] - s0 * t_prev[i];
  axpy(c[1], t_cur.data(), w, len);
  for (int k = 2; k <= d; ++k) {
    product(t_cur.data(), mt.data());
    // t_next = 2 X t_cur - t_prev, stored over t_prev.
    for (std::size_t i = 0; i < len; ++i) t_prev[i] = 2.0 * (s1 * mt[i] - s0 * t_cur[i]) - t_prev[i];
    std::swap(t_prev, t_cur);
    axpy(c[static_cast<std::size_t>(k)], t_cur.data(), w, len);
  }
  return report;
}

SqrtReport chebyshev_sqrt(const LinearOperatorView& op, std::span<const double> z, std::span<double> w,
                          std::size_t nrhs, const SqrtOptions& options) {
  HostKrylovSpace space(op.n);
  const ChebyshevProducts products{
      space,
      [&op](const double* x, double* y) { op.apply(std::span<const double>(x, op.n), std::span<double>(y, op.n), 1); },
      0,
      op.n,
      [&op, nrhs](const double* x, double* y, SqrtReport& report) { apply_checked(op, x, y, nrhs, report, kWhere); },
      op.n * nrhs};
  return chebyshev_sqrt_in_space(products, z.data(), w.data(), options);
}

}  // namespace rpyfmm::rpy::sqrt_detail
