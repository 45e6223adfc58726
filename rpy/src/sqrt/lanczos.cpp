// rpyfmm — Krylov (Lanczos) square root, block over right-hand sides.
//
// Ando, Chow & Saad, J. Chem. Phys. 137, 064106 (2012), eqs. (9)-(10):
//   M^{1/2} z ~ |z| V_m T_m^{1/2} e_1,
// with V_m the Lanczos basis of the Krylov space K_m(M, z) and T_m = V_m^T M V_m
// tridiagonal. T_m^{1/2} e_1 = Q diag(sqrt(theta)) Q^T e_1 from the eigen-
// decomposition of T_m. Stopping test (their sec. II.B): the relative 2-norm
// change of successive iterates, |w_m - w_{m-1}| / |w_m| < tol; with an
// orthonormal basis this equals |c_m - [c_{m-1}; 0]| / |c_m| in coefficient space,
// so the basis is combined only once, at the end.
//
// Block variant: every right-hand side keeps its own Krylov space; each
// iteration multiplies the current basis vectors of all not-yet-converged
// right-hand sides in ONE call of op.apply (the operator's several-densities mode).
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "detail.hpp"
#include "krylov.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/random.hpp"

namespace rpyfmm::rpy::sqrt_detail {

namespace {

constexpr const char* kWhere = "sqrt_apply(lanczos)";

/// c = |z| T^{1/2} e_1; throws if a Ritz value is <= 0 (M not SPD).
Eigen::VectorXd sqrt_coefficients(const LanczosProcess& p, double znorm, std::size_t rhs) {
  const int m = p.size();
  const auto es = tridiagonal_eigen(p.alpha(), p.beta(), m);
  const Eigen::VectorXd& theta = es.eigenvalues();
  if (!(theta[0] > 0.0)) {
    std::ostringstream msg;
    msg << "the operator is not positive definite: Ritz value " << theta[0] << " <= 0 at Lanczos iteration " << m - 1
        << " (alpha_" << m - 1 << " = " << p.alpha().back();
    if (m > 1) msg << ", beta_" << m - 2 << " = " << p.beta()[static_cast<std::size_t>(m - 2)];
    msg << ", right-hand side " << rhs << ")";
    fail(ErrorCode::numerical_failure, kWhere, msg.str());
  }
  const Eigen::MatrixXd& Q = es.eigenvectors();
  const Eigen::VectorXd weights = theta.cwiseSqrt().cwiseProduct(Q.row(0).transpose());
  return znorm * (Q * weights);
}

}  // namespace

void conclude_lanczos_step(LanczosRhs& s, bool breakdown, int it, int max_it, const SqrtOptions& options, std::size_t k,
                           double* w, SqrtReport& report) {
  Eigen::VectorXd c = sqrt_coefficients(s.process, s.znorm, k);
  if (s.coeff.size() > 0) {
    Eigen::VectorXd prev = Eigen::VectorXd::Zero(c.size());
    prev.head(s.coeff.size()) = s.coeff;
    s.change = (c - prev).norm() / c.norm();
  }
  s.coeff = std::move(c);
  report.iterations = std::max(report.iterations, it + 1);
  const bool converged = breakdown || (it > 0 && s.change < options.tolerance);
  if (breakdown) {
    s.breakdown = true;
    s.change = 0.0;  // invariant subspace: the result is exact (up to rounding)
  }
  if (converged || it + 1 == max_it) {
    s.process.combine(s.coeff, w);
    s.active = false;
    if (!converged) {
      report.converged = false;
      if (options.throw_if_not_converged) {
        std::ostringstream msg;
        msg << "no convergence in " << max_it << " iterations (right-hand side " << k << ": last relative change "
            << s.change << " > tolerance " << options.tolerance << "); raise max_iterations or the tolerance";
        fail(ErrorCode::numerical_failure, kWhere, msg.str());
      }
    }
  }
}

namespace {

/// After the product y = M v_j of right-hand side k at iteration `it`: one Lanczos step, then
/// conclude_lanczos_step.
void advance(LanczosRhs& s, double* y, int it, int max_it, const SqrtOptions& options, std::size_t k, double* w,
             SqrtReport& report) {
  conclude_lanczos_step(s, s.process.step(y, kWhere, k), it, max_it, options, k, w, report);
}

}  // namespace

int lanczos_max_iterations(const SqrtOptions& options, std::size_t n) {
  return options.max_iterations > 0 ? options.max_iterations : static_cast<int>(std::min<std::size_t>(n, 500));
}

SqrtReport lanczos_sqrt_in_space(KrylovSpace& space, const KrylovProduct& product, const double* z, double* w,
                                 const SqrtOptions& options, const double* first_product) {
  SqrtReport report;
  report.method = SqrtMethod::lanczos;
  const int max_it = lanczos_max_iterations(options, space.n());
  LanczosRhs s{LanczosProcess(space, options.reorthogonalize), 0.0, {}, 0.0, true, false};
  s.znorm = s.process.start(z);
  if (s.znorm == 0.0) {  // M^{1/2} 0 = 0 exactly
    space.combine(0, nullptr, w);
    s.active = false;
  }
  double* y = space.work();
  for (int it = 0; it < max_it && s.active; ++it) {
    if (it == 0 && first_product != nullptr) {
      space.scale_into(1.0 / s.znorm, first_product, y);  // M v_1 = (M z) / |z|, as start() scales z
      space.require_finite(y, kWhere, 1);
    } else {
      product(s.process.current(), y);
      ++report.operator_applications;
      ++report.vector_products;
      space.require_finite(y, kWhere, report.operator_applications);
    }
    advance(s, y, it, max_it, options, 0, w, report);
  }
  report.error_estimate = s.change;
  report.breakdown = s.breakdown;
  return report;
}

SqrtReport lanczos_sqrt(const LinearOperatorView& op, std::span<const double> z, std::span<double> w, std::size_t nrhs,
                        const SqrtOptions& options, std::span<const double> first_product) {
  const std::size_t n = op.n;
  if (nrhs == 1) {  // one right-hand side: the iteration of any Krylov space, here on host vectors
    HostKrylovSpace space(n);
    return lanczos_sqrt_in_space(
        space,
        [&op](const double* x, double* y) {
          op.apply(std::span<const double>(x, op.n), std::span<double>(y, op.n), 1);
        },
        z.data(), w.data(), options, first_product.empty() ? nullptr : first_product.data());
  }
  SqrtReport report;
  report.method = SqrtMethod::lanczos;
  const int max_it = lanczos_max_iterations(options, n);

  std::vector<LanczosRhs> state;
  state.reserve(nrhs);
  for (std::size_t k = 0; k < nrhs; ++k) {
    state.push_back(LanczosRhs{LanczosProcess(n, options.reorthogonalize), 0.0, {}, 0.0, true, false});
    state[k].znorm = state[k].process.start(&z[k * n]);
    if (state[k].znorm == 0.0) {  // M^{1/2} 0 = 0 exactly
      std::fill(&w[k * n], &w[k * n] + n, 0.0);
      state[k].active = false;
    }
  }

  std::vector<double> x, y;
  std::vector<std::size_t> active;
  for (int it = 0; it < max_it; ++it) {
    active.clear();
    for (std::size_t k = 0; k < nrhs; ++k)
      if (state[k].active) active.push_back(k);
    if (active.empty()) break;
    // One operator call for every right-hand side still iterating.
    // (One right-hand side: its basis vector is multiplied in place, without the copy.)
    y.resize(active.size() * n);
    const double* input = state[active[0]].process.current();
    if (active.size() > 1) {
      x.resize(active.size() * n);
      for (std::size_t a = 0; a < active.size(); ++a) std::copy_n(state[active[a]].process.current(), n, &x[a * n]);
      input = x.data();
    }
    apply_checked(op, input, y.data(), active.size(), report, kWhere);
    for (std::size_t a = 0; a < active.size(); ++a) {
      const std::size_t k = active[a];
      advance(state[k], &y[a * n], it, max_it, options, k, &w[k * n], report);
    }
  }
  for (const auto& s : state) {
    report.error_estimate = std::max(report.error_estimate, s.change);
    report.breakdown = report.breakdown || s.breakdown;
  }
  return report;
}

void fill_bound_start(std::span<double> start, std::size_t first_entry) {
  // Fixed pseudo-random start vector: reproducible, and almost surely not
  // deficient in any eigenvector (unlike e.g. the noise vector itself).
  for (std::size_t i = 0; i < start.size(); ++i) {
    const std::size_t e = first_entry + i;
    double g[3];
    normal3(0x5eedb0cdULL, 0, 0x7fffffffu, e / 3, g);
    start[i] = g[e % 3];
  }
}

SpectrumBounds estimate_spectrum_bounds_in_space(KrylovSpace& space, const KrylovProduct& product, const double* start,
                                                 int iterations) {
  constexpr const char* where = "estimate_spectrum_bounds";
  LanczosProcess p(space, true);
  p.start(start);
  double* y = space.work();
  bool breakdown = false;
  const int steps = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(iterations), space.n()));
  for (int it = 0; it < steps && !breakdown; ++it) {
    product(p.current(), y);
    space.require_finite(y, where, it + 1);
    breakdown = p.step(y, where, 0);
  }
  const int m = p.size();
  const auto es = tridiagonal_eigen(p.alpha(), p.beta(), m);
  const Eigen::VectorXd& theta = es.eigenvalues();
  if (!(theta[0] > 0.0)) {
    std::ostringstream msg;
    msg << "the operator is not positive definite: Ritz value " << theta[0] << " <= 0 after " << m << " Lanczos steps";
    fail(ErrorCode::numerical_failure, where, msg.str());
  }
  SpectrumBounds b;
  b.iterations = m;
  b.ritz_min = theta[0];
  b.ritz_max = theta[m - 1];
  // Residual of the top Ritz pair: |M y - theta y| = beta_m |s_m| (Saad, Prop. 6.8).
  const double resid = breakdown ? 0.0 : p.beta().back() * std::abs(es.eigenvectors()(m - 1, m - 1));
  b.lambda_max = 1.01 * (b.ritz_max + resid);
  b.lambda_min = 0.5 * b.ritz_min;
  return b;
}

}  // namespace rpyfmm::rpy::sqrt_detail

namespace rpyfmm::rpy {

SpectrumBounds estimate_spectrum_bounds(const LinearOperatorView& op, int iterations) {
  constexpr const char* where = "estimate_spectrum_bounds";
  require(op.n > 0 && static_cast<bool>(op.apply), ErrorCode::invalid_argument, where,
          "the operator is empty (n = 0 or no apply function)");
  require(iterations >= 2, ErrorCode::invalid_argument, where,
          "iterations must be >= 2, got " + std::to_string(iterations));
  std::vector<double> start(op.n);
  sqrt_detail::fill_bound_start(start, 0);
  sqrt_detail::HostKrylovSpace space(op.n);
  return sqrt_detail::estimate_spectrum_bounds_in_space(
      space,
      [&op](const double* x, double* y) { op.apply(std::span<const double>(x, op.n), std::span<double>(y, op.n), 1); },
      start.data(), iterations);
}

}  // namespace rpyfmm::rpy
