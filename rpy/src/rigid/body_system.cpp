// rpyfmm — the bodies of a rigid-body configuration: layout checks, frames and lever-arm
// scaling, and the body-block preconditioner's factors (body_system.hpp).
#include "body_system.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"

namespace rpyfmm::rpy::rigid_detail {
namespace {

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
                         std::span<const std::size_t> body_offsets, std::span<const double> reference_points,
                         bool allow_no_bodies, std::string_view where) {
  require(bead_positions.size() == 3 * n, ErrorCode::invalid_input, where,
          "bead positions have " + std::to_string(bead_positions.size()) + " entries for " + std::to_string(n) +
              " radii (expected 3 per bead)");
  const std::size_t least = allow_no_bodies ? 1 : 2;
  require(body_offsets.size() >= least, ErrorCode::invalid_input, where,
          "body offsets need at least " + std::to_string(least) + " entries (0 and N), got " +
              std::to_string(body_offsets.size()));
  require(body_offsets.front() == 0 && body_offsets.back() == n, ErrorCode::invalid_input, where,
          "body offsets must start at 0 and end at the number of beads " + std::to_string(n));
  const std::size_t m = body_offsets.size() - 1;
  for (std::size_t k = 0; k < m; ++k) {
    require(body_offsets[k + 1] > body_offsets[k], ErrorCode::invalid_input, where,
            "body " + std::to_string(k) + " has no beads (body offsets must increase strictly)");
    require(body_offsets[k + 1] - body_offsets[k] >= 3, ErrorCode::invalid_input, where,
            "body " + std::to_string(k) + " has " + std::to_string(body_offsets[k + 1] - body_offsets[k]) +
                " beads; a rigid body needs at least 3 not on one line");
  }
  require(reference_points.empty() || reference_points.size() == 3 * m, ErrorCode::invalid_input, where,
          "reference points have " + std::to_string(reference_points.size()) + " entries for " + std::to_string(m) +
              " bodies (expected 3 per body, or none for the centroids)");
  require_finite(reference_points, where, "reference points", 3);
}

/// Throws out_of_memory when the dense body blocks of the preconditioner exceed `max_bytes`.
void require_preconditioner_memory(std::span<const std::size_t> body_offsets, std::size_t max_bytes,
                                   std::string_view where) {
  double bytes = 0.0;
  for (std::size_t k = 0; k + 1 < body_offsets.size(); ++k)
    bytes += 72.0 * std::pow(double(body_offsets[k + 1] - body_offsets[k]), 2);
  require(bytes <= double(max_bytes), ErrorCode::out_of_memory, where,
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

/// The exponent e of the power of two 2^e at or below the largest |arm| of the beads [first, last)
/// (0 where all are 0): arms times 2^-e lie within [1, 2) at most, so their squares neither
/// overflow nor underflow at any length scale.
int arm_exponent(const std::vector<double>& arms, std::size_t first, std::size_t last) {
  double largest = 0.0;
  for (std::size_t i = 3 * first; i < 3 * last; ++i) largest = std::max(largest, std::abs(arms[i]));
  return largest > 0.0 ? std::ilogb(largest) : 0;
}

/// Throws when a body's beads lie on one line: the second moment of its arms about their mean
/// has rank 1, so the rotation about that line is undefined (arms in units of arm_exponent).
void require_not_on_one_line(const std::vector<double>& arms, std::span<const std::size_t> body_offsets,
                             std::string_view where) {
  for (std::size_t k = 0; k + 1 < body_offsets.size(); ++k) {
    const std::size_t first = body_offsets[k], count = body_offsets[k + 1] - first;
    const int e = arm_exponent(arms, first, first + count);
    const auto arm = [&](std::size_t i) {
      return Eigen::Vector3d(std::ldexp(arms[3 * i], -e), std::ldexp(arms[3 * i + 1], -e),
                             std::ldexp(arms[3 * i + 2], -e));
    };
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (std::size_t i = first; i < first + count; ++i) mean += arm(i);
    mean /= double(count);
    Eigen::Matrix3d moment = Eigen::Matrix3d::Zero();
    for (std::size_t i = first; i < first + count; ++i) {
      const Eigen::Vector3d d = arm(i) - mean;
      moment += d * d.transpose();
    }
    const Eigen::Vector3d ev =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(moment, Eigen::EigenvaluesOnly).eigenvalues();
    require(ev(1) > 1e-12 * ev(2), ErrorCode::invalid_input, where,
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
    const int e = arm_exponent(arms, body_offsets[k], body_offsets[k + 1]);
    double sum = 0.0;
    for (std::size_t i = 3 * body_offsets[k]; i < 3 * body_offsets[k + 1]; ++i) {
      const double a = std::ldexp(arms[i], -e);
      sum += a * a;
    }
    lever[k] = std::ldexp(std::sqrt(sum / double(body_offsets[k + 1] - body_offsets[k])), e);
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
                              std::span<const std::size_t> body_offsets, std::span<const double> radii, double eta,
                              std::string_view where) {
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
    require(failure[k] != 1, ErrorCode::invalid_input, where,
            "body " + std::to_string(k) +
                ": its beads' mobility block is singular (coincident beads?), so the body preconditioner "
                "cannot factor it");
    require(failure[k] != 2, ErrorCode::invalid_input, where,
            "body " + std::to_string(k) +
                ": its beads lie on one line, so its rotation about that line is undefined (a rigid body needs "
                "at least 3 beads not on one line)");
  }
  return b;
}

}  // namespace

void require_options(const RigidBodyOptions& options, std::string_view where) {
  require(options.tolerance > 0.0 && options.tolerance < 1.0, ErrorCode::invalid_argument, where,
          "tolerance must lie in (0, 1), got " + format_number(options.tolerance));
  require(options.max_iterations > 0, ErrorCode::invalid_argument, where,
          "max_iterations must be > 0, got " + std::to_string(options.max_iterations));
  require(options.restart > 0, ErrorCode::invalid_argument, where,
          "restart must be > 0, got " + std::to_string(options.restart));
}

void require_bodies(std::span<const double> bead_positions, std::size_t n, std::span<const std::size_t> body_offsets,
                    std::span<const double> reference_points, const RigidBodyOptions& options, bool allow_no_bodies,
                    std::string_view where) {
  require_body_layout(bead_positions, n, body_offsets, reference_points, allow_no_bodies, where);
  if (options.precondition) require_preconditioner_memory(body_offsets, options.max_preconditioner_bytes, where);
}

int mobility_scale_exponent(double eta, double largest_radius) {
  if (!(eta > 0.0 && largest_radius > 0.0)) return 0;  // no bead on any rank: nothing to balance
  const double scale = 1.0 / (6.0 * std::numbers::pi * eta * largest_radius);
  if (!std::isfinite(scale)) return 900;  // eta a underflows
  if (scale == 0.0) return -900;          // eta a overflows
  return std::clamp(std::ilogb(scale), -900, 900);
}

BodySystem make_body_system(std::span<const double> bead_positions, std::span<const double> radii,
                            std::span<const std::size_t> body_offsets, std::span<const double> reference_points,
                            const Geometry& geometry, double eta, double largest_radius, bool precondition,
                            std::string_view where) {
  BodyFrames frames = body_frames(bead_positions, body_offsets, reference_points, geometry);
  require_not_on_one_line(frames.arms, body_offsets, where);
  std::vector<double> karms(frames.arms);
  std::vector<double> lever = scale_to_lever_arms(karms, body_offsets);
  BodyBlocks blocks = precondition ? factor_body_blocks(frames.arms, karms, body_offsets, radii, eta, where)
                                   : BodyBlocks{std::vector<std::size_t>(body_offsets.size(), 0), {}, {}, {}};
  BodySystem s;
  s.arms = std::move(karms);
  s.scale = std::move(lever);
  s.reference = std::move(frames.reference);
  s.factor_offset = std::move(blocks.factor_offset);
  s.factors = std::move(blocks.factors);
  s.minv_k = std::move(blocks.minv_k);
  s.body_mobility = std::move(blocks.mobility);
  s.offsets.assign(body_offsets.begin(), body_offsets.end());
  s.mobility_exponent = mobility_scale_exponent(eta, largest_radius);
  return s;
}

}  // namespace rpyfmm::rpy::rigid_detail
