// rpyfmm — RigidBodies: the body mobility N = (K^T M^{-1} K)^{-1} by preconditioned GMRES on
// the saddle-point system (see the header).
#include "rpyfmm/rpy/rigid_bodies.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>

#include "gmres.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"

namespace rpyfmm::rpy {
namespace {

constexpr const char* kWhere = "RigidBodies";

using MatrixX = Eigen::MatrixXd;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

/// Minimum image of d in a periodic geometry (unchanged in an open one).
void minimum_image(const Geometry& geometry, double d[3]) {
  if (!geometry.is_periodic()) return;
  const auto box = geometry.box();
  for (int c = 0; c < 3; ++c) d[c] -= box[c] * std::nearbyint(d[c] / box[c]);
}

/// K_k (3n x 6) of one body: bead i moves with U + Omega x arm_i = U - [arm_i]_x Omega.
MatrixX rigid_map(const double* arms, std::size_t n) {
  MatrixX k = MatrixX::Zero(static_cast<Eigen::Index>(3 * n), 6);
  for (std::size_t i = 0; i < n; ++i) {
    const auto r = static_cast<Eigen::Index>(3 * i);
    const double x = arms[3 * i], y = arms[3 * i + 1], z = arms[3 * i + 2];
    k.block<3, 3>(r, 0).setIdentity();
    // Omega x arm = -[arm]_x Omega, [a]_x = [[0, -z, y], [z, 0, -x], [-y, x, 0]]
    k(r + 0, 4) = z;
    k(r + 0, 5) = -y;
    k(r + 1, 3) = -z;
    k(r + 1, 5) = x;
    k(r + 2, 3) = y;
    k(r + 2, 4) = -x;
  }
  return k;
}

/// Throws invalid_input unless the beads (3 coordinates each), the body offsets (0 to N, at least
/// 3 beads per body) and the reference points (3 per body, or none) fit together.
void require_body_layout(std::span<const double> bead_positions, std::size_t n,
                         std::span<const std::size_t> body_offsets, std::span<const double> reference_points) {
  require(bead_positions.size() == 3 * n, ErrorCode::invalid_input, kWhere,
          "bead positions have " + std::to_string(bead_positions.size()) + " entries for " + std::to_string(n) +
              " radii (expected 3 per bead)");
  require(body_offsets.size() >= 2, ErrorCode::invalid_input, kWhere,
          "body offsets need at least 2 entries (0 and N), got " + std::to_string(body_offsets.size()));
  require(body_offsets.front() == 0 && body_offsets.back() == n, ErrorCode::invalid_input, kWhere,
          "body offsets must start at 0 and end at the number of beads " + std::to_string(n));
  const std::size_t m = body_offsets.size() - 1;
  for (std::size_t k = 0; k < m; ++k) {
    require(body_offsets[k + 1] > body_offsets[k], ErrorCode::invalid_input, kWhere,
            "body " + std::to_string(k) + " has no beads (body offsets must increase strictly)");
    require(body_offsets[k + 1] - body_offsets[k] >= 3, ErrorCode::invalid_input, kWhere,
            "body " + std::to_string(k) + " has " + std::to_string(body_offsets[k + 1] - body_offsets[k]) +
                " beads; a rigid body needs at least 3 not on one line");
  }
  require(reference_points.empty() || reference_points.size() == 3 * m, ErrorCode::invalid_input, kWhere,
          "reference points have " + std::to_string(reference_points.size()) + " entries for " + std::to_string(m) +
              " bodies (expected 3 per body, or none for the centroids)");
  require_finite(reference_points, kWhere, "reference points", 3);
}

/// Throws out_of_memory when the dense body blocks of the preconditioner exceed `max_bytes`.
void require_preconditioner_memory(std::span<const std::size_t> body_offsets, std::size_t max_bytes) {
  double bytes = 0.0;
  for (std::size_t k = 0; k + 1 < body_offsets.size(); ++k)
    bytes += 72.0 * std::pow(double(body_offsets[k + 1] - body_offsets[k]), 2);
  require(bytes <= double(max_bytes), ErrorCode::out_of_memory, kWhere,
          "the body preconditioner needs " + std::to_string(static_cast<long long>(bytes / 1048576.0)) +
              " MiB of dense body blocks (72 n^2 bytes per body of n beads), above max_preconditioner_bytes");
}

/// Each body's reference point (3 per body) and each bead's arm from it (3 per bead).
struct BodyFrames {
  std::vector<double> reference, arms;
};

/// Reference points (given, or the centroids of the minimum images relative to each body's first
/// bead) and the arms (minimum images) of the beads from them.
BodyFrames body_frames(std::span<const double> x, std::span<const std::size_t> body_offsets,
                       std::span<const double> reference_points, const Geometry& geometry) {
  const std::size_t m = body_offsets.size() - 1;
  BodyFrames f{std::vector<double>(3 * m), std::vector<double>(3 * body_offsets.back())};
  for (std::size_t k = 0; k < m; ++k) {
    const std::size_t first = body_offsets[k], count = body_offsets[k + 1] - first;
    if (!reference_points.empty()) {
      std::copy_n(reference_points.begin() + static_cast<std::ptrdiff_t>(3 * k), 3, f.reference.begin() + 3 * k);
    } else {
      double sum[3] = {0.0, 0.0, 0.0};
      for (std::size_t i = first; i < first + count; ++i) {
        double d[3];
        for (int c = 0; c < 3; ++c) d[c] = x[3 * i + c] - x[3 * first + c];
        minimum_image(geometry, d);
        for (int c = 0; c < 3; ++c) sum[c] += d[c];
      }
      for (int c = 0; c < 3; ++c) f.reference[3 * k + c] = x[3 * first + c] + sum[c] / double(count);
    }
    for (std::size_t i = first; i < first + count; ++i) {
      double d[3];
      for (int c = 0; c < 3; ++c) d[c] = x[3 * i + c] - f.reference[3 * k + c];
      minimum_image(geometry, d);
      std::copy_n(d, 3, f.arms.begin() + static_cast<std::ptrdiff_t>(3 * i));
    }
  }
  return f;
}

/// Throws when a body's beads lie on one line: the second moment of its arms about their mean
/// has rank 1, so the rotation about that line is undefined.
void require_not_on_one_line(const std::vector<double>& arms, std::span<const std::size_t> body_offsets) {
  for (std::size_t k = 0; k + 1 < body_offsets.size(); ++k) {
    const std::size_t first = body_offsets[k], count = body_offsets[k + 1] - first;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::size_t i = first; i < first + count; ++i) mean += Eigen::Map<const Eigen::Vector3d>(&arms[3 * i]);
    mean /= double(count);
    Eigen::Matrix3d moment = Eigen::Matrix3d::Zero();
    for (std::size_t i = first; i < first + count; ++i) {
      const Eigen::Vector3d d = Eigen::Map<const Eigen::Vector3d>(&arms[3 * i]) - mean;
      moment += d * d.transpose();
    }
    const Eigen::Vector3d ev =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(moment, Eigen::EigenvaluesOnly).eigenvalues();
    require(ev(1) > 1e-12 * ev(2), ErrorCode::invalid_input, kWhere,
            "body " + std::to_string(k) +
                ": its beads lie on one line (or coincide), so its rotation about that line is undefined (a rigid "
                "body needs at least 3 beads not on one line)");
  }
}

/// Rotations in length units: each body's angular velocity and torque enter the system as
/// Omega_k l_k and T_k / l_k, with l_k its RMS lever arm, so K's rotational columns hold the
/// arms / l_k (dimensionless, O(1)) and the residual weighs forces and torques alike. Divides
/// the arms by l_k in place and returns the l_k.
std::vector<double> scale_to_lever_arms(std::vector<double>& arms, std::span<const std::size_t> body_offsets) {
  const std::size_t m = body_offsets.size() - 1;
  std::vector<double> lever(m);
  for (std::size_t k = 0; k < m; ++k) {
    double sum = 0.0;
    for (std::size_t i = 3 * body_offsets[k]; i < 3 * body_offsets[k + 1]; ++i) sum += arms[i] * arms[i];
    lever[k] = std::sqrt(sum / double(body_offsets[k + 1] - body_offsets[k]));
    for (std::size_t i = 3 * body_offsets[k]; i < 3 * body_offsets[k + 1]; ++i) arms[i] /= lever[k];
  }
  return lever;
}

/// The preconditioner's per-body data (empty without the preconditioner).
struct BodyBlocks {
  std::vector<std::size_t> factor_offset;  // factors of body k start here (m + 1 entries)
  std::vector<double> factors;             // Cholesky factors L_k of the bead blocks M_kk
  std::vector<double> minv_k;              // M_kk^{-1} K_k, 3 n_k x 6 per body
  std::vector<double> mobility;            // N_k = (K_k^T M_kk^{-1} K_k)^{-1}, 36 per body
};

/// M_kk of one body: the RPY tensors (docs/theory/rpy.md) between its beads, whose separations
/// are differences of their (unscaled) arms.
MatrixX bead_block(const double* arms, const double* radii, std::size_t count, double eta) {
  const auto rows = static_cast<Eigen::Index>(3 * count);
  MatrixX block(rows, rows);
  for (std::size_t q = 0; q < count; ++q) {
    for (std::size_t p = q; p < count; ++p) {
      double d[3], t[9];
      for (int c = 0; c < 3; ++c) d[c] = arms[3 * p + c] - arms[3 * q + c];
      rpy_tensor(d, radii[p], radii[q], eta, t);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          block(Eigen::Index(3 * p) + r, Eigen::Index(3 * q) + c) = t[3 * r + c];
          block(Eigen::Index(3 * q) + c, Eigen::Index(3 * p) + r) = t[3 * r + c];
        }
    }
  }
  return block;
}

/// Factors body k's blocks into `b`. Returns 0, or 1 for a singular bead block, 2 for a rotation
/// that moves no bead (the 6x6 S_k = K_k^T M_kk^{-1} K_k, checked after Jacobi scaling, is
/// singular).
int factor_body(std::size_t k, const std::vector<double>& arms, const std::vector<double>& karms,
                std::span<const std::size_t> body_offsets, std::span<const double> radii, double eta, BodyBlocks& b) {
  const std::size_t first = body_offsets[k], count = body_offsets[k + 1] - first;
  const Eigen::LLT<MatrixX> llt(bead_block(arms.data() + 3 * first, radii.data() + first, count, eta));
  if (llt.info() != Eigen::Success || !(llt.matrixLLT().diagonal().minCoeff() > 0.0)) return 1;
  const MatrixX kk = rigid_map(karms.data() + 3 * first, count);
  const MatrixX minvk = llt.solve(kk);
  const Matrix6 s = kk.transpose() * minvk;
  const Eigen::Matrix<double, 6, 1> scale = s.diagonal().cwiseSqrt().cwiseInverse();
  const Matrix6 scaled = scale.asDiagonal() * s * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix6> eig(scaled, Eigen::EigenvaluesOnly);
  if (!(eig.eigenvalues()(0) > 1e-10 * eig.eigenvalues()(5))) return 2;
  const Matrix6 nk = s.ldlt().solve(Matrix6::Identity());
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) b.mobility[36 * k + 6 * std::size_t(r) + std::size_t(c)] = 0.5 * (nk(r, c) + nk(c, r));
  const MatrixX l = llt.matrixL();
  std::copy(l.data(), l.data() + l.size(), b.factors.begin() + static_cast<std::ptrdiff_t>(b.factor_offset[k]));
  std::copy(minvk.data(), minvk.data() + minvk.size(), b.minv_k.begin() + static_cast<std::ptrdiff_t>(18 * first));
  return 0;
}

/// Per body (preconditioner): the Cholesky factor of its bead block M_kk and
/// N_k = (K_k^T M_kk^{-1} K_k)^{-1}, from the arms and the arms / l_k (karms).
BodyBlocks factor_body_blocks(const std::vector<double>& arms, const std::vector<double>& karms,
                              std::span<const std::size_t> body_offsets, std::span<const double> radii, double eta) {
  const std::size_t m = body_offsets.size() - 1;
  BodyBlocks b;
  b.factor_offset.assign(m + 1, 0);
  for (std::size_t k = 0; k < m; ++k) {
    const std::size_t rows = 3 * (body_offsets[k + 1] - body_offsets[k]);
    b.factor_offset[k + 1] = b.factor_offset[k] + rows * rows;
  }
  b.factors.resize(b.factor_offset[m]);
  b.minv_k.resize(18 * body_offsets.back());
  b.mobility.resize(36 * m);
  std::vector<int> failure(m, 0);
#pragma omp parallel for schedule(dynamic)
  for (std::size_t k = 0; k < m; ++k) failure[k] = factor_body(k, arms, karms, body_offsets, radii, eta, b);
  for (std::size_t k = 0; k < m; ++k) {
    require(failure[k] != 1, ErrorCode::invalid_input, kWhere,
            "body " + std::to_string(k) +
                ": its beads' mobility block is singular (coincident beads?), so the body preconditioner "
                "cannot factor it");
    require(failure[k] != 2, ErrorCode::invalid_input, kWhere,
            "body " + std::to_string(k) +
                ": its beads lie on one line, so its rotation about that line is undefined (a rigid body needs "
                "at least 3 beads not on one line)");
  }
  return b;
}

}  // namespace

RigidBodies::RigidBodies(MobilityOperator& beads, RigidBodyOptions options) : beads_(beads), options_(options) {
  require(options.tolerance > 0.0 && options.tolerance < 1.0, ErrorCode::invalid_argument, kWhere,
          "tolerance must lie in (0, 1), got " + std::to_string(options.tolerance));
  require(options.max_iterations > 0, ErrorCode::invalid_argument, kWhere,
          "max_iterations must be > 0, got " + std::to_string(options.max_iterations));
  require(options.restart > 0, ErrorCode::invalid_argument, kWhere,
          "restart must be > 0, got " + std::to_string(options.restart));
}

void RigidBodies::set_configuration(std::span<const double> bead_positions, double radius,
                                    std::span<const std::size_t> body_offsets,
                                    std::span<const double> reference_points) {
  require_positive(radius, kWhere, "bead radius");
  const std::vector<double> radii(bead_positions.size() / 3, radius);
  set_configuration(bead_positions, radii, body_offsets, reference_points);
}

void RigidBodies::set_configuration(std::span<const double> bead_positions, std::span<const double> radii,
                                    std::span<const std::size_t> body_offsets,
                                    std::span<const double> reference_points) {
  StopWatch watch;
  offsets_.clear();  // unconfigured until everything below succeeds
  require_body_layout(bead_positions, radii.size(), body_offsets, reference_points);
  if (options_.precondition) require_preconditioner_memory(body_offsets, options_.max_preconditioner_bytes);
  // Plans the bead operator; validates positions and radii (NaN/Inf, radius <= 0).
  beads_.set_positions(bead_positions, radii);
  BodyFrames frames = body_frames(bead_positions, body_offsets, reference_points, beads_.geometry());
  require_not_on_one_line(frames.arms, body_offsets);
  std::vector<double> karms(frames.arms);
  std::vector<double> lever = scale_to_lever_arms(karms, body_offsets);
  BodyBlocks blocks = options_.precondition
                          ? factor_body_blocks(frames.arms, karms, body_offsets, beads_.radii(), beads_.viscosity())
                          : BodyBlocks{std::vector<std::size_t>(body_offsets.size(), 0), {}, {}, {}};
  arms_ = std::move(karms);
  scale_ = std::move(lever);
  reference_ = std::move(frames.reference);
  factor_offset_ = std::move(blocks.factor_offset);
  factors_ = std::move(blocks.factors);
  minv_k_ = std::move(blocks.minv_k);
  body_mobility_ = std::move(blocks.mobility);
  offsets_.assign(body_offsets.begin(), body_offsets.end());
  seconds_setup_ = watch.seconds();
}

void RigidBodies::rigid_velocities(const double* body, double* bead) const {
  const std::size_t m = bodies();
#pragma omp parallel for schedule(static)
  for (std::size_t k = 0; k < m; ++k) {
    const double* u = body + 6 * k;
    const double* w = u + 3;
    for (std::size_t i = offsets_[k]; i < offsets_[k + 1]; ++i) {
      const double* a = arms_.data() + 3 * i;
      bead[3 * i + 0] = u[0] + w[1] * a[2] - w[2] * a[1];
      bead[3 * i + 1] = u[1] + w[2] * a[0] - w[0] * a[2];
      bead[3 * i + 2] = u[2] + w[0] * a[1] - w[1] * a[0];
    }
  }
}

void RigidBodies::forces_and_torques(const double* bead, double* body) const {
  const std::size_t m = bodies();
#pragma omp parallel for schedule(static)
  for (std::size_t k = 0; k < m; ++k) {
    double s[6] = {0, 0, 0, 0, 0, 0};
    for (std::size_t i = offsets_[k]; i < offsets_[k + 1]; ++i) {
      const double* a = arms_.data() + 3 * i;
      const double* f = bead + 3 * i;
      s[0] += f[0];
      s[1] += f[1];
      s[2] += f[2];
      s[3] += a[1] * f[2] - a[2] * f[1];  // arm x force
      s[4] += a[2] * f[0] - a[0] * f[2];
      s[5] += a[0] * f[1] - a[1] * f[0];
    }
    std::copy_n(s, 6, body + 6 * k);
  }
}

void RigidBodies::saddle_apply(const double* x, double* y) const {
  // [M lambda - K Y; -K^T lambda]
  const std::size_t n3 = 3 * beads_.size();
  std::vector<double> k_y(n3);
  beads_.apply(std::span<const double>(x, n3), std::span<double>(y, n3));
  rigid_velocities(x + n3, k_y.data());
  for (std::size_t i = 0; i < n3; ++i) y[i] -= k_y[i];
  forces_and_torques(x, y + n3);
  for (std::size_t i = 0; i < 6 * bodies(); ++i) y[n3 + i] = -y[n3 + i];
}

void RigidBodies::precondition(const double* x, double* y) const {
  // Per body, the saddle-point system without inter-body coupling:
  //   Y_k = -N_k (b_k + K_k^T M_kk^{-1} a_k),  lambda_k = M_kk^{-1} a_k + (M_kk^{-1} K_k) Y_k
  // (two triangular solves; M_kk^{-1} K_k is stored).
  const std::size_t n3 = 3 * beads_.size();
  const std::size_t m = bodies();
#pragma omp parallel for schedule(dynamic)
  for (std::size_t k = 0; k < m; ++k) {
    const std::size_t first = offsets_[k], count = offsets_[k + 1] - first;
    const auto rows = static_cast<Eigen::Index>(3 * count);
    const Eigen::Map<const MatrixX> l(factors_.data() + factor_offset_[k], rows, rows);
    const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 6>> minvk(minv_k_.data() + 18 * first, rows, 6);
    const Eigen::Map<const Eigen::VectorXd> a(x + 3 * first, rows);
    const Eigen::Map<const Eigen::Matrix<double, 6, 1>> b(x + n3 + 6 * k);
    const Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>> nk(body_mobility_.data() + 36 * k);
    Eigen::VectorXd minv_a = l.triangularView<Eigen::Lower>().solve(a);
    l.triangularView<Eigen::Lower>().transpose().solveInPlace(minv_a);
    // K_k^T M_kk^{-1} a_k = (M_kk^{-1} K_k)^T a_k (M_kk symmetric)
    const Eigen::Matrix<double, 6, 1> yk = -(nk * (b + minvk.transpose() * a));
    Eigen::Map<Eigen::VectorXd>(y + 3 * first, rows) = minv_a + minvk * yk;
    Eigen::Map<Eigen::Matrix<double, 6, 1>>(y + n3 + 6 * k) = yk;
  }
}

void RigidBodies::check_call(std::span<const double> forces_torques, std::span<double> velocities,
                             std::span<double> bead_forces) const {
  require(!offsets_.empty(), ErrorCode::invalid_input, kWhere, "apply before set_configuration");
  require(beads_.size() == offsets_.back(), ErrorCode::invalid_input, kWhere,
          "the bead operator now holds " + std::to_string(beads_.size()) + " particles, not the " +
              std::to_string(offsets_.back()) + " beads of set_configuration (its positions were set elsewhere)");
  const std::size_t m = bodies();
  const std::size_t n3 = 3 * beads_.size();
  require_size(forces_torques, 6 * m, kWhere, "forces and torques");
  require_size(std::span<const double>(velocities.data(), velocities.size()), 6 * m, kWhere, "velocities");
  require(bead_forces.empty() || bead_forces.size() == n3, ErrorCode::invalid_input, kWhere,
          "bead forces have " + std::to_string(bead_forces.size()) + " entries, expected " + std::to_string(n3) +
              " (3 per bead) or none");
  require_finite(forces_torques, kWhere, "forces and torques", 6);
}

RigidBodyReport RigidBodies::solve(std::span<const double> forces_torques, std::vector<double>& b,
                                   std::span<double> velocities, std::span<double> bead_forces,
                                   std::span<const double> guess_velocities,
                                   std::span<const double> guess_bead_forces) const {
  const std::size_t m = bodies();
  const std::size_t n3 = 3 * beads_.size();
  StopWatch watch;
  for (std::size_t k = 0; k < m; ++k)  // -(F_k, T_k / l_k)
    for (std::size_t c = 0; c < 6; ++c) b[n3 + 6 * k + c] = -forces_torques[6 * k + c] / (c < 3 ? 1.0 : scale_[k]);
  std::vector<double> x(n3 + 6 * m, 0.0);
  if (!guess_velocities.empty()) {  // [lambda; U_k, Omega_k l_k], as below in reverse
    std::copy(guess_bead_forces.begin(), guess_bead_forces.end(), x.begin());
    for (std::size_t k = 0; k < m; ++k)
      for (std::size_t c = 0; c < 6; ++c) x[n3 + 6 * k + c] = guess_velocities[6 * k + c] * (c < 3 ? 1.0 : scale_[k]);
  }
  const rigid_detail::VectorMap op = [this](const double* in, double* out) { saddle_apply(in, out); };
  rigid_detail::VectorMap pre;
  if (options_.precondition) pre = [this](const double* in, double* out) { precondition(in, out); };
  const rigid_detail::GmresResult g = rigid_detail::gmres(b.size(), op, pre, b.data(), x.data(), options_.tolerance,
                                                          options_.max_iterations, options_.restart);
  require(g.converged, ErrorCode::numerical_failure, kWhere,
          "GMRES did not reach the tolerance " + std::to_string(options_.tolerance) + " in " +
              std::to_string(g.iterations) + " iterations (relative residual " + std::to_string(g.residual) +
              "); raise max_iterations or the tolerance");
  require(std::all_of(x.begin(), x.end(), [](double v) { return std::isfinite(v); }), ErrorCode::numerical_failure,
          kWhere, "GMRES produced non-finite velocities");
  for (std::size_t k = 0; k < m; ++k)  // (U_k, Omega_k l_k) -> (U_k, Omega_k)
    for (std::size_t c = 0; c < 6; ++c) velocities[6 * k + c] = x[n3 + 6 * k + c] / (c < 3 ? 1.0 : scale_[k]);
  if (!bead_forces.empty()) std::copy_n(x.begin(), n3, bead_forces.begin());
  RigidBodyReport report;
  report.iterations = g.iterations;
  report.restarts = g.restarts;
  report.residual = g.residual;
  report.seconds_setup = seconds_setup_;
  report.seconds_solve = watch.seconds();
  return report;
}

RigidBodyReport RigidBodies::apply(std::span<const double> forces_torques, std::span<double> velocities,
                                   std::span<double> bead_forces) const {
  check_call(forces_torques, velocities, bead_forces);
  std::vector<double> b(3 * beads_.size() + 6 * bodies(), 0.0);  // no slip
  return solve(forces_torques, b, velocities, bead_forces);
}

RigidBodyReport RigidBodies::apply_from(std::span<const double> forces_torques,
                                        std::span<const double> guess_velocities,
                                        std::span<const double> guess_bead_forces, std::span<double> velocities,
                                        std::span<double> bead_forces) const {
  check_call(forces_torques, velocities, bead_forces);
  require_size(guess_velocities, 6 * bodies(), kWhere, "guess velocities");
  require_finite(guess_velocities, kWhere, "guess velocities", 6);
  require_size(guess_bead_forces, 3 * beads_.size(), kWhere, "guess bead forces");
  require_finite(guess_bead_forces, kWhere, "guess bead forces", 3);
  std::vector<double> b(3 * beads_.size() + 6 * bodies(), 0.0);  // no slip
  return solve(forces_torques, b, velocities, bead_forces, guess_velocities, guess_bead_forces);
}

RigidBodyReport RigidBodies::apply_with_noise(std::span<const double> forces_torques, double noise_scale,
                                              std::span<const double> z, std::span<double> velocities,
                                              const SqrtOptions& sqrt_options, std::span<double> bead_forces) const {
  check_call(forces_torques, velocities, bead_forces);
  const std::size_t n3 = 3 * beads_.size();
  require_size(z, n3, kWhere, "bead noise z");
  require_finite(z, kWhere, "bead noise z", 3);
  require(std::isfinite(noise_scale) && noise_scale >= 0.0, ErrorCode::invalid_argument, kWhere,
          "noise_scale must be finite and >= 0, got " + std::to_string(noise_scale));
  StopWatch watch;
  // Random slip s = -c B z with B B^T = M: Y = N W + c N K^T M^{-1} B z, whose noise part has
  // covariance c^2 N K^T M^{-1} M M^{-1} K N = c^2 N (Sprinkle et al., J. Chem. Phys. 147, 244103 (2017)).
  std::vector<double> b(n3 + 6 * bodies(), 0.0), w(n3);
  const SqrtReport sqrt_report = beads_.apply_sqrt(z, w, sqrt_options);
  for (std::size_t i = 0; i < n3; ++i) b[i] = -noise_scale * w[i];
  const double seconds_sqrt = watch.seconds();
  RigidBodyReport report = solve(forces_torques, b, velocities, bead_forces);
  report.sqrt = sqrt_report;
  report.seconds_sqrt = seconds_sqrt;
  return report;
}

std::vector<double> RigidBodies::mobility_matrix(std::size_t max_bodies) const {
  require(!offsets_.empty(), ErrorCode::invalid_input, kWhere, "mobility_matrix before set_configuration");
  const std::size_t m = bodies();
  require(m <= max_bodies, ErrorCode::invalid_argument, kWhere,
          "mobility_matrix of " + std::to_string(m) + " bodies needs " + std::to_string(6 * m) +
              " solves; raise max_bodies (" + std::to_string(max_bodies) + ") to allow it");
  const std::size_t n = 6 * m;
  std::vector<double> matrix(n * n), unit(n, 0.0), column(n);
  for (std::size_t c = 0; c < n; ++c) {
    unit[c] = 1.0;
    apply(unit, column);
    unit[c] = 0.0;
    for (std::size_t r = 0; r < n; ++r) matrix[r * n + c] = column[r];
  }
  for (std::size_t r = 0; r < n; ++r)
    for (std::size_t c = r + 1; c < n; ++c)
      matrix[r * n + c] = matrix[c * n + r] = 0.5 * (matrix[r * n + c] + matrix[c * n + r]);
  return matrix;
}

}  // namespace rpyfmm::rpy
