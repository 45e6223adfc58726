// rpyfmm — restarted, right-preconditioned GMRES (see gmres.hpp).
#include "gmres.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace rpyfmm::rpy::rigid_detail {
namespace {

/// Sequential sums: the same result for any thread count.
double dot(const double* a, const double* b, std::size_t n) {
  double s = 0.0;
  for (std::size_t i = 0; i < n; ++i) s += a[i] * b[i];
  return s;
}

}  // namespace

GmresResult gmres(std::size_t n, const VectorMap& apply, const VectorMap& precondition, const double* b, double* x,
                  double tol, int max_iterations, int restart) {
  GmresResult result;
  const double bnorm = std::sqrt(dot(b, b, n));
  if (bnorm == 0.0) {
    std::fill(x, x + n, 0.0);
    result.converged = true;
    return result;
  }
  const auto m = static_cast<std::size_t>(std::max(restart, 1));
  std::vector<std::vector<double>> basis(m + 1, std::vector<double>(n));
  std::vector<double> h((m + 1) * m, 0.0);  // Hessenberg matrix, column j at h[j * (m + 1)]
  std::vector<double> cs(m), sn(m), g(m + 1), y(m), z(n), w(n);
  auto residual_into = [&](double* r) {  // r = b - A x
    apply(x, w.data());
    for (std::size_t i = 0; i < n; ++i) r[i] = b[i] - w[i];
  };

  bool zero_guess = std::all_of(x, x + n, [](double v) { return v == 0.0; });
  while (true) {
    if (zero_guess) {  // r = b without a product
      std::copy(b, b + n, basis[0].begin());
      zero_guess = false;
    } else {
      residual_into(basis[0].data());
      ++result.iterations;
    }
    const double beta = std::sqrt(dot(basis[0].data(), basis[0].data(), n));
    result.residual = beta / bnorm;
    if (beta <= tol * bnorm) {
      result.converged = true;
      return result;
    }
    if (result.iterations >= max_iterations) return result;
    for (std::size_t i = 0; i < n; ++i) basis[0][i] /= beta;
    std::fill(g.begin(), g.end(), 0.0);
    g[0] = beta;
    std::size_t j = 0;  // columns done
    bool done = false;
    while (j < m && !done) {
      // w = A P^{-1} v_j
      if (precondition) {
        precondition(basis[j].data(), z.data());
        apply(z.data(), w.data());
      } else {
        apply(basis[j].data(), w.data());
      }
      ++result.iterations;
      double* hj = h.data() + j * (m + 1);
      for (std::size_t i = 0; i <= j; ++i) {  // modified Gram-Schmidt
        hj[i] = dot(w.data(), basis[i].data(), n);
        for (std::size_t k = 0; k < n; ++k) w[k] -= hj[i] * basis[i][k];
      }
      hj[j + 1] = std::sqrt(dot(w.data(), w.data(), n));
      const bool breakdown = hj[j + 1] == 0.0;  // the Krylov space holds the solution
      if (!breakdown)
        for (std::size_t k = 0; k < n; ++k) basis[j + 1][k] = w[k] / hj[j + 1];
      // Givens rotations keep H upper triangular; |g[j + 1]| is the residual norm.
      for (std::size_t i = 0; i < j; ++i) {
        const double t = cs[i] * hj[i] + sn[i] * hj[i + 1];
        hj[i + 1] = -sn[i] * hj[i] + cs[i] * hj[i + 1];
        hj[i] = t;
      }
      const double r = std::hypot(hj[j], hj[j + 1]);
      cs[j] = hj[j] / r;
      sn[j] = hj[j + 1] / r;
      hj[j] = r;
      hj[j + 1] = 0.0;
      g[j + 1] = -sn[j] * g[j];
      g[j] = cs[j] * g[j];
      ++j;
      result.residual = std::abs(g[j]) / bnorm;
      done = breakdown || result.residual <= tol || result.iterations >= max_iterations;
    }
    // y = H^{-1} g (upper triangular), x += P^{-1} V y.
    for (std::size_t i = j; i-- > 0;) {
      double s = g[i];
      for (std::size_t k = i + 1; k < j; ++k) s -= h[k * (m + 1) + i] * y[k];
      y[i] = s / h[i * (m + 1) + i];
    }
    std::fill(w.begin(), w.end(), 0.0);
    for (std::size_t i = 0; i < j; ++i)
      for (std::size_t k = 0; k < n; ++k) w[k] += y[i] * basis[i][k];
    if (precondition) {
      precondition(w.data(), z.data());
    } else {
      std::copy(w.begin(), w.end(), z.begin());
    }
    for (std::size_t k = 0; k < n; ++k) x[k] += z[k];
    if (result.residual <= tol) {
      result.converged = true;
      return result;
    }
    if (result.iterations >= max_iterations) return result;
    ++result.restarts;
  }
}

}  // namespace rpyfmm::rpy::rigid_detail
