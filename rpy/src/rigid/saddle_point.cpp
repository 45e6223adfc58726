// rpyfmm — the rigid-body saddle-point system on the beads of whole bodies: K Y, K^T lambda, the
// operator given a bead product, the body-block preconditioner and the GMRES solve
// (body_system.hpp; docs/theory/rigid.md).
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>

#include "body_system.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::rigid_detail {
namespace {

using MatrixX = Eigen::MatrixXd;

/// bead = K Y: the bead velocities of the bodies' rigid motions (U_k, Omega_k l_k).
void rigid_velocities(const BodySystem& s, const double* body, double* bead) {
  const std::size_t m = s.bodies();
#pragma omp parallel for schedule(static)
  for (std::size_t k = 0; k < m; ++k) {
    const double* u = body + 6 * k;
    const double* w = u + 3;
    for (std::size_t i = s.offsets[k]; i < s.offsets[k + 1]; ++i) {
      const double* a = s.arms.data() + 3 * i;
      bead[3 * i + 0] = u[0] + w[1] * a[2] - w[2] * a[1];
      bead[3 * i + 1] = u[1] + w[2] * a[0] - w[0] * a[2];
      bead[3 * i + 2] = u[2] + w[0] * a[1] - w[1] * a[0];
    }
  }
}

/// body = K^T lambda: each body's force and torque / l_k from its bead forces.
void forces_and_torques(const BodySystem& s, const double* bead, double* body) {
  const std::size_t m = s.bodies();
#pragma omp parallel for schedule(static)
  for (std::size_t k = 0; k < m; ++k) {
    double f6[6] = {0, 0, 0, 0, 0, 0};
    for (std::size_t i = s.offsets[k]; i < s.offsets[k + 1]; ++i) {
      const double* a = s.arms.data() + 3 * i;
      const double* f = bead + 3 * i;
      f6[0] += f[0];
      f6[1] += f[1];
      f6[2] += f[2];
      f6[3] += a[1] * f[2] - a[2] * f[1];  // arm x force
      f6[4] += a[2] * f[0] - a[0] * f[2];
      f6[5] += a[0] * f[1] - a[1] * f[0];
    }
    std::copy_n(f6, 6, body + 6 * k);
  }
}

/// y[i] = 2^e x[i] for i < n (exact unless it overflows or underflows).
void scale_by_power_of_two(const double* x, std::size_t n, int e, double* y) {
  for (std::size_t i = 0; i < n; ++i) y[i] = std::ldexp(x[i], e);
}

/// y = [M 2^-e lambda' - K Y; -K^T lambda'] for x = [lambda'; Y]: the saddle-point system in units
/// of the mobility scale 2^e (bead forces lambda' = 2^e lambda, the body rows times 2^e; see
/// solve_saddle_point).
void saddle_apply(const BodySystem& s, const BeadProduct& beads, const double* x, double* y) {
  const std::size_t n3 = 3 * s.beads();
  std::vector<double> k_y(n3), lambda(n3);
  scale_by_power_of_two(x, n3, -s.mobility_exponent, lambda.data());
  beads(std::span<const double>(lambda), std::span<double>(y, n3));
  rigid_velocities(s, x + n3, k_y.data());
  for (std::size_t i = 0; i < n3; ++i) y[i] -= k_y[i];
  forces_and_torques(s, x, y + n3);
  for (std::size_t i = 0; i < 6 * s.bodies(); ++i) y[n3 + i] = -y[n3 + i];
}

/// The body-block preconditioner: per body, the saddle-point system without inter-body coupling,
///   Y_k = -N_k (b_k + K_k^T M_kk^{-1} a_k),  lambda_k = M_kk^{-1} a_k + (M_kk^{-1} K_k) Y_k
/// (two triangular solves; M_kk^{-1} K_k is stored), for x = [a; b] in the units of the mobility
/// scale 2^e as saddle_apply: b is divided by 2^e on entry and lambda multiplied by 2^e on exit.
void precondition(const BodySystem& s, const double* x, double* y) {
  const std::size_t n3 = 3 * s.beads();
  const std::size_t m = s.bodies();
#pragma omp parallel for schedule(dynamic)
  for (std::size_t k = 0; k < m; ++k) {
    const std::size_t first = s.offsets[k], count = s.offsets[k + 1] - first;
    const auto rows = static_cast<Eigen::Index>(3 * count);
    const Eigen::Map<const MatrixX> l(s.factors.data() + s.factor_offset[k], rows, rows);
    const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 6>> minvk(s.minv_k.data() + 18 * first, rows, 6);
    const Eigen::Map<const Eigen::VectorXd> a(x + 3 * first, rows);
    Eigen::Matrix<double, 6, 1> b;
    scale_by_power_of_two(x + n3 + 6 * k, 6, -s.mobility_exponent, b.data());
    const Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>> nk(s.body_mobility.data() + 36 * k);
    Eigen::VectorXd minv_a = l.triangularView<Eigen::Lower>().solve(a);
    l.triangularView<Eigen::Lower>().transpose().solveInPlace(minv_a);
    // K_k^T M_kk^{-1} a_k = (M_kk^{-1} K_k)^T a_k (M_kk symmetric)
    const Eigen::Matrix<double, 6, 1> yk = -(nk * (b + minvk.transpose() * a));
    const Eigen::VectorXd lambda = minv_a + minvk * yk;
    scale_by_power_of_two(lambda.data(), std::size_t(rows), s.mobility_exponent, y + 3 * first);
    Eigen::Map<Eigen::Matrix<double, 6, 1>>(y + n3 + 6 * k) = yk;
  }
}

/// Rotations in length units (docs/theory/rigid.md): entry c of body k's six in the saddle-point
/// vector is Omega l_k or T / l_k for c >= 3; this is the factor l_k there, 1 for c < 3.
double lever_factor(const BodySystem& s, std::size_t k, std::size_t c) {
  return c < 3 ? 1.0 : s.scale[k];
}

}  // namespace

void require_call(const BodySystem& s, std::span<const double> forces_torques, std::span<double> velocities,
                  std::span<double> bead_forces, std::string_view where) {
  const std::size_t m = s.bodies();
  const std::size_t n3 = 3 * s.beads();
  require_size(forces_torques, 6 * m, where, "forces and torques");
  require_size(std::span<const double>(velocities.data(), velocities.size()), 6 * m, where, "velocities");
  require(bead_forces.empty() || bead_forces.size() == n3, ErrorCode::invalid_input, where,
          "bead forces have " + std::to_string(bead_forces.size()) + " entries, expected " + std::to_string(n3) +
              " (3 per bead) or none");
  require_finite(forces_torques, where, "forces and torques", 6);
}

void require_guesses(const BodySystem& s, std::span<const double> guess_velocities,
                     std::span<const double> guess_bead_forces, std::string_view where) {
  require_size(guess_velocities, 6 * s.bodies(), where, "guess velocities");
  require_finite(guess_velocities, where, "guess velocities", 6);
  require_size(guess_bead_forces, 3 * s.beads(), where, "guess bead forces");
  require_finite(guess_bead_forces, where, "guess bead forces", 3);
}

void require_noise(const BodySystem& s, std::span<const double> z, double noise_scale, std::string_view where) {
  require_size(z, 3 * s.beads(), where, "bead noise z");
  require_finite(z, where, "bead noise z", 3);
  require(std::isfinite(noise_scale) && noise_scale >= 0.0, ErrorCode::invalid_argument, where,
          "noise_scale must be finite and >= 0, got " + format_number(noise_scale));
}

SaddleSolution solve_saddle_point(const BodySystem& s, const BeadProduct& beads, const RigidBodyOptions& options,
                                  std::span<const double> forces_torques, std::vector<double>& b,
                                  std::span<const double> guess_velocities, std::span<const double> guess_bead_forces,
                                  const InnerProduct& inner_product) {
  const std::size_t m = s.bodies();
  const std::size_t n3 = 3 * s.beads();
  // Units of the mobility scale 2^e ~ 1 / (6 pi eta a): bead forces lambda' = 2^e lambda and body
  // rows -2^e (F_k, T_k / l_k), so both blocks of the residual are velocities and the operator is of
  // order 1 in any units (docs/theory/rigid.md Sec. 2, "Units"). Powers of two: exact.
  for (std::size_t k = 0; k < m; ++k)
    for (std::size_t c = 0; c < 6; ++c)
      b[n3 + 6 * k + c] = -std::ldexp(forces_torques[6 * k + c] / lever_factor(s, k, c), s.mobility_exponent);
  SaddleSolution solution{{}, std::vector<double>(n3 + 6 * m, 0.0)};
  std::vector<double>& x = solution.x;
  if (!guess_velocities.empty()) {  // [2^e lambda; U_k, Omega_k l_k], as finish_solve in reverse
    scale_by_power_of_two(guess_bead_forces.data(), n3, s.mobility_exponent, x.data());
    for (std::size_t k = 0; k < m; ++k)
      for (std::size_t c = 0; c < 6; ++c) x[n3 + 6 * k + c] = guess_velocities[6 * k + c] * lever_factor(s, k, c);
  }
  const VectorMap op = [&s, &beads](const double* in, double* out) { saddle_apply(s, beads, in, out); };
  VectorMap pre;
  if (options.precondition) pre = [&s](const double* in, double* out) { precondition(s, in, out); };
  solution.gmres = gmres(b.size(), op, pre, b.data(), x.data(), options.tolerance, options.max_iterations,
                         options.restart, inner_product);
  return solution;
}

RigidBodyReport finish_solve(const BodySystem& s, const SaddleSolution& solution, const RigidBodyOptions& options,
                             std::span<double> velocities, std::span<double> bead_forces, std::string_view where) {
  const GmresResult& g = solution.gmres;
  const std::vector<double>& x = solution.x;
  require(g.converged, ErrorCode::numerical_failure, where,
          "GMRES did not reach the tolerance " + format_number(options.tolerance) + " in " +
              std::to_string(g.iterations) + " iterations (relative residual " + format_number(g.residual) +
              "); raise max_iterations or the tolerance");
  require(std::all_of(x.begin(), x.end(), [](double v) { return std::isfinite(v); }), ErrorCode::numerical_failure,
          where, "GMRES produced non-finite velocities");
  const std::size_t m = s.bodies();
  const std::size_t n3 = 3 * s.beads();
  for (std::size_t k = 0; k < m; ++k)  // (U_k, Omega_k l_k) -> (U_k, Omega_k)
    for (std::size_t c = 0; c < 6; ++c) velocities[6 * k + c] = x[n3 + 6 * k + c] / lever_factor(s, k, c);
  if (!bead_forces.empty()) scale_by_power_of_two(x.data(), n3, -s.mobility_exponent, bead_forces.data());
  RigidBodyReport report;
  report.iterations = g.iterations;
  report.restarts = g.restarts;
  report.residual = g.residual;
  return report;
}

}  // namespace rpyfmm::rpy::rigid_detail
