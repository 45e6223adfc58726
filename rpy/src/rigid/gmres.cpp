// rpyfmm — restarted, right-preconditioned GMRES (see gmres.hpp).
#include "gmres.hpp"

#include <algorithm>
#include <cmath>
#include <new>
#include <string>
#include <vector>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::rigid_detail {

double sequential_dot(const double* a, const double* b, std::size_t n) {
  double s = 0.0;
  for (std::size_t i = 0; i < n; ++i) s += a[i] * b[i];
  return s;
}

namespace {

/// The workspace of one GMRES cycle of at most m columns on vectors of length n.
struct Cycle {
  Cycle(std::size_t size, std::size_t columns, const InnerProduct& inner_product)
      : inner(inner_product),
        n(size),
        m(columns),
        basis(m + 1, std::vector<double>(n)),
        h((m + 1) * m, 0.0),
        cs(m),
        sn(m),
        g(m + 1),
        y(m),
        z(n),
        w(n) {}
  [[nodiscard]] double* column(std::size_t j) { return h.data() + j * (m + 1); }
  /// <a, b> by the hook, or sequentially without one.
  [[nodiscard]] double dot(const double* a, const double* b) const {
    return inner ? inner(a, b, n) : sequential_dot(a, b, n);
  }

  const InnerProduct& inner;
  std::size_t n, m;
  std::vector<std::vector<double>> basis;
  std::vector<double> h;  // Hessenberg matrix, column j at h[j * (m + 1)]
  std::vector<double> cs, sn, g, y, z, w;
};

/// Column j of the Arnoldi process: w = A P^{-1} v_j orthogonalised against v_0 .. v_j by
/// modified Gram-Schmidt, v_{j+1} = w / |w|. Returns true on breakdown (|w| = 0: the Krylov
/// space holds the solution).
bool arnoldi_column(Cycle& c, std::size_t j, const VectorMap& apply, const VectorMap& precondition) {
  const std::size_t n = c.n;
  if (precondition) {
    precondition(c.basis[j].data(), c.z.data());
    apply(c.z.data(), c.w.data());
  } else {
    apply(c.basis[j].data(), c.w.data());
  }
  double* hj = c.column(j);
  for (std::size_t i = 0; i <= j; ++i) {
    hj[i] = c.dot(c.w.data(), c.basis[i].data());
    for (std::size_t k = 0; k < n; ++k) c.w[k] -= hj[i] * c.basis[i][k];
  }
  hj[j + 1] = std::sqrt(c.dot(c.w.data(), c.w.data()));
  const bool breakdown = hj[j + 1] == 0.0;
  if (!breakdown)
    for (std::size_t k = 0; k < n; ++k) c.basis[j + 1][k] = c.w[k] / hj[j + 1];
  return breakdown;
}

/// Givens rotations keep H upper triangular: the earlier ones applied to column j, a new one
/// zeroing h_{j+1,j}; afterwards |g[j + 1]| is the residual norm.
void rotate_column(Cycle& c, std::size_t j) {
  double* hj = c.column(j);
  for (std::size_t i = 0; i < j; ++i) {
    const double t = c.cs[i] * hj[i] + c.sn[i] * hj[i + 1];
    hj[i + 1] = -c.sn[i] * hj[i] + c.cs[i] * hj[i + 1];
    hj[i] = t;
  }
  const double r = std::hypot(hj[j], hj[j + 1]);
  c.cs[j] = hj[j] / r;
  c.sn[j] = hj[j + 1] / r;
  hj[j] = r;
  hj[j + 1] = 0.0;
  c.g[j + 1] = -c.sn[j] * c.g[j];
  c.g[j] = c.cs[j] * c.g[j];
}

/// After j columns: y = H^{-1} g (upper triangular) and x += P^{-1} V y.
void update_solution(Cycle& c, std::size_t j, const VectorMap& precondition, double* x) {
  const std::size_t n = c.n, m = c.m;
  for (std::size_t i = j; i-- > 0;) {
    double s = c.g[i];
    for (std::size_t k = i + 1; k < j; ++k) s -= c.h[k * (m + 1) + i] * c.y[k];
    c.y[i] = s / c.h[i * (m + 1) + i];
  }
  std::fill(c.w.begin(), c.w.end(), 0.0);
  for (std::size_t i = 0; i < j; ++i)
    for (std::size_t k = 0; k < n; ++k) c.w[k] += c.y[i] * c.basis[i][k];
  if (precondition) {
    precondition(c.w.data(), c.z.data());
  } else {
    std::copy(c.w.begin(), c.w.end(), c.z.begin());
  }
  for (std::size_t k = 0; k < n; ++k) x[k] += c.z[k];
}

/// The cycle's workspace: at most max_iterations columns (a longer cycle never runs; the results
/// are the same), allocated up front. A basis that does not fit (restart = 2^31 - 1 ended in
/// std::bad_alloc) is refused by name.
Cycle make_cycle(std::size_t n, int max_iterations, int restart, const InnerProduct& inner_product) {
  const auto m = static_cast<std::size_t>(std::max(1, std::min(restart, max_iterations)));
  try {
    return Cycle(n, m, inner_product);
  } catch (const std::bad_alloc&) {
    fail(ErrorCode::out_of_memory, "GMRES",
         "a cycle of " + std::to_string(m) + " iterations needs " +
             format_number(8.0 * static_cast<double>(m + 1) * static_cast<double>(n + m) / 1e9) +
             " GB for its Krylov basis; lower restart (RigidBodyOptions::restart)");
  }
}

}  // namespace

GmresResult gmres(std::size_t n, const VectorMap& apply, const VectorMap& precondition, const double* b, double* x,
                  double tol, int max_iterations, int restart, const InnerProduct& inner_product) {
  GmresResult result;
  Cycle c = make_cycle(n, max_iterations, restart, inner_product);
  const double bnorm = std::sqrt(c.dot(b, b));
  // Entries near 1e154 or larger make |b| infinite, and then every test below passes (inf <= inf)
  // with x = 0 returned as converged. Every rank sees the same reduced norm, so all fail alike.
  require(std::isfinite(bnorm), ErrorCode::numerical_failure, "GMRES",
          "the right-hand side's norm overflows (entries of about 1e154 or larger); scale the forces and torques "
          "down");
  if (bnorm == 0.0) {
    std::fill(x, x + n, 0.0);
    result.converged = true;
    return result;
  }
  bool zero_guess = inner_product ? c.dot(x, x) == 0.0 : std::all_of(x, x + n, [](double v) { return v == 0.0; });
  while (true) {
    if (zero_guess) {  // r = b without a product
      std::copy(b, b + n, c.basis[0].begin());
      zero_guess = false;
    } else {  // r = b - A x
      apply(x, c.w.data());
      for (std::size_t i = 0; i < n; ++i) c.basis[0][i] = b[i] - c.w[i];
      ++result.iterations;
    }
    const double beta = std::sqrt(c.dot(c.basis[0].data(), c.basis[0].data()));
    result.residual = beta / bnorm;
    if (beta <= tol * bnorm) {
      result.converged = true;
      return result;
    }
    if (result.iterations >= max_iterations) return result;
    for (std::size_t i = 0; i < n; ++i) c.basis[0][i] /= beta;
    std::fill(c.g.begin(), c.g.end(), 0.0);
    c.g[0] = beta;
    std::size_t j = 0;  // columns done
    bool done = false;
    while (j < c.m && !done) {
      const bool breakdown = arnoldi_column(c, j, apply, precondition);
      ++result.iterations;
      rotate_column(c, j);
      ++j;
      result.residual = std::abs(c.g[j]) / bnorm;
      done = breakdown || result.residual <= tol || result.iterations >= max_iterations;
    }
    update_solution(c, j, precondition, x);
    if (result.residual <= tol) {
      result.converged = true;
      return result;
    }
    if (result.iterations >= max_iterations) return result;
    ++result.restarts;
  }
}

}  // namespace rpyfmm::rpy::rigid_detail
