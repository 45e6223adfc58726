// rpyfmm — the mobility of rigid bodies built from beads ("bead-shell" / rigid multiblob models):
// forces and torques on m rigid bodies -> their linear and angular velocities, with full
// hydrodynamic interactions among all beads through any MobilityOperator (direct, FMM, PSE).
//
// Body k is a set of beads i at positions r_i (radius a_i) moving rigidly with a reference
// point q_k: u_i = U_k + Omega_k x (r_i - q_k), i.e. u = K Y (Guan, dissertation, ch. 4, the
// bead-shell model; docs/theory/rigid.md; the "rigid multiblob" formulation of Balboa Usabiaga et al., Commun. Appl.
// Math. Comput. Sci. 11, 217 (2016)). The beads exert forces lambda on the fluid with M lambda = K Y (no slip, M the
// RPY bead mobility) and sum to the body's force and torque, K^T lambda = W = (F_k, T_k). So
//     [ M   -K ] [lambda]   [ 0]
//     [-K^T  0 ] [  Y   ] = [-W],    Y = N W,   N = (K^T M^{-1} K)^{-1}  (the body mobility).
// The saddle-point system is solved matrix-free by restarted GMRES, with one bead product
// M lambda per iteration, right-preconditioned by the same system without the hydrodynamic
// coupling between different bodies (per body: a dense Cholesky of its bead block M_kk and
// the 6x6 N_k = (K_k^T M_kk^{-1} K_k)^{-1}). For well-separated bodies that preconditioner is
// nearly exact; iterations grow slowly with the volume fraction (docs/theory/rigid.md).
//
// Conventions. Bead positions 3N as everywhere; bodies are contiguous runs of beads given by
// offsets (body k holds beads offsets[k] .. offsets[k+1] - 1; offsets[0] = 0, offsets[m] = N).
// Forces/torques and velocities are 6 per body: (F_x, F_y, F_z, T_x, T_y, T_z) ->
// (U_x, U_y, U_z, Omega_x, Omega_y, Omega_z). In a periodic geometry lever arms r_i - q_k
// are minimum images, so a body may straddle the box. Each body needs at least three beads
// not on one line (else its rotation about that line is undefined: rpyfmm::Error).
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::rpy {

namespace rigid_detail {
struct BodySystem;  // the bodies' frames and preconditioner (internal, rpy/src/rigid/body_system.hpp)
}

struct RigidBodyOptions {
  /// GMRES stops at ||r|| <= tolerance ||b||: r the residual of the saddle-point system above,
  /// b its right-hand side (W, and apply_with_noise's random slip), with each body's torque and
  /// angular velocity scaled by its RMS lever arm l_k (T_k / l_k, Omega_k l_k: forces and
  /// torques weigh alike) and the system in units of the mobility scale (bead forces and the
  /// body rows times a power of two near 1 / (6 pi eta a_max): the same tolerance means the same
  /// in any units, docs/theory/rigid.md Sec. 2). The relative error of the
  /// velocities is then within a few times the tolerance (docs/theory/rigid.md); in (0, 1).
  double tolerance = 1e-6;
  /// Most GMRES iterations (bead products) in all; not converging then throws
  /// ErrorCode::numerical_failure.
  int max_iterations = 500;
  /// Krylov vectors kept before a restart (memory: min(restart, max_iterations) x (3N + 6m) doubles;
  /// a basis that does not fit is refused with out_of_memory).
  int restart = 60;
  /// The body-block preconditioner (true: the recommended solver; false: plain GMRES, for
  /// comparison only: it needs many more iterations).
  bool precondition = true;
  /// Refuse (before allocating) a preconditioner whose dense body blocks exceed this many bytes
  /// in all (a body of n beads needs 72 n^2 bytes).
  std::size_t max_preconditioner_bytes = std::size_t{1} << 31;
};

struct RigidBodyReport {
  int iterations = 0;          ///< GMRES iterations = bead products M lambda
  int restarts = 0;            ///< GMRES restarts
  double residual = 0.0;       ///< final ||r|| / ||b|| as GMRES's recurrence estimates it
  double seconds_setup = 0.0;  ///< set_configuration: bead plan + body factorizations
  double seconds_solve = 0.0;  ///< the GMRES solve of apply / apply_with_noise
  SqrtReport sqrt;             ///< apply_with_noise: the bead noise B z (B B^T = M)
  double seconds_sqrt = 0.0;   ///< apply_with_noise: time of the bead noise
};

class RigidBodies {
 public:
  /// `beads` computes bead products (not owned: it must outlive this object; set_configuration
  /// sets its positions, and nothing else may change them before apply). Throws rpyfmm::Error
  /// on bad options.
  explicit RigidBodies(MobilityOperator& beads, RigidBodyOptions options = {});

  /// Bead positions (3N) and one radius or N radii, body offsets (m + 1 entries), and the
  /// bodies' reference points q_k (3m; empty = each body's bead centroid). Plans the bead
  /// operator and factors the body blocks. Throws rpyfmm::Error naming the problem (sizes,
  /// NaN/Inf, empty bodies, fewer than three non-collinear beads, coincident beads in a body,
  /// preconditioner too large).
  void set_configuration(std::span<const double> bead_positions, std::span<const double> radii,
                         std::span<const std::size_t> body_offsets, std::span<const double> reference_points = {});
  void set_configuration(std::span<const double> bead_positions, double radius,
                         std::span<const std::size_t> body_offsets, std::span<const double> reference_points = {});

  /// Y = N W: velocities (6m) from forces and torques (6m). Optionally also the bead forces
  /// lambda (3N) that hold the bodies rigid. Throws rpyfmm::Error on wrong sizes, NaN/Inf, a
  /// call before set_configuration, or no convergence within max_iterations.
  RigidBodyReport apply(std::span<const double> forces_torques, std::span<double> velocities,
                        std::span<double> bead_forces = {}) const;

  /// apply() with GMRES started from a guess instead of zero: the velocities (6m) and bead
  /// forces (3N) of a nearby problem, e.g. the same forces and torques on a slightly moved
  /// configuration (RigidBodyDynamics' second RFD solve). The result meets the same tolerance,
  /// in fewer iterations the better the guess. Throws as apply, and on guesses of the wrong
  /// size or with NaN/Inf.
  RigidBodyReport apply_from(std::span<const double> forces_torques, std::span<const double> guess_velocities,
                             std::span<const double> guess_bead_forces, std::span<double> velocities,
                             std::span<double> bead_forces = {}) const;

  /// Velocities with Brownian noise for a time step: Y = N W + noise_scale N K^T M^{-1} B z, where
  /// B z (B B^T = M) is the bead operator's square root of the bead noise z (3N standard normal
  /// values; `sqrt_options` as for MobilityOperator::apply_sqrt, the block preconditioner
  /// included). The noise part has covariance noise_scale^2 N, so with noise_scale =
  /// sqrt(2 kT / dt) the displacements Y dt carry the bodies' Brownian motion: a random slip
  /// on the beads (Sprinkle, Balboa Usabiaga, Patankar & Donev, J. Chem. Phys. 147, 244103
  /// (2017)). One bead square root and one GMRES solve. The thermal drift kT div N of a full
  /// BD step is not included. Throws as apply, and on a bad z or noise_scale < 0.
  RigidBodyReport apply_with_noise(std::span<const double> forces_torques, double noise_scale,
                                   std::span<const double> z, std::span<double> velocities,
                                   const SqrtOptions& sqrt_options = {}, std::span<double> bead_forces = {}) const;

  /// The body mobility matrix N (6m x 6m, row-major; rows and columns (U, Omega) / (F, T) per
  /// body) by 6m solves with unit forces and torques, symmetrized (N = N^T exactly; the solves
  /// leave an asymmetry of about the tolerance). kT N is the bodies' grand diffusion tensor,
  /// e.g. translational and rotational diffusion of a bead model of a macromolecule. Throws
  /// for more than `max_bodies` bodies (the cost is 6m solves).
  [[nodiscard]] std::vector<double> mobility_matrix(std::size_t max_bodies = 200) const;

  [[nodiscard]] std::size_t bodies() const;
  [[nodiscard]] std::size_t beads() const { return beads_.size(); }
  /// Reference points q_k (3m) in use.
  [[nodiscard]] std::span<const double> reference_points() const;
  [[nodiscard]] const RigidBodyOptions& options() const { return options_; }
  /// Time spent in the last set_configuration.
  [[nodiscard]] double seconds_setup() const { return seconds_setup_; }

 private:
  void check_call(std::span<const double> forces_torques, std::span<double> velocities,
                  std::span<double> bead_forces) const;
  /// GMRES on the saddle-point system with bead rows b[0, 3N) given (the slip) and the body rows
  /// from forces_torques; velocities and bead forces from its solution.
  RigidBodyReport solve(std::span<const double> forces_torques, std::vector<double>& b, std::span<double> velocities,
                        std::span<double> bead_forces, std::span<const double> guess_velocities = {},
                        std::span<const double> guess_bead_forces = {}) const;

  MobilityOperator& beads_;
  RigidBodyOptions options_;
  std::shared_ptr<const rigid_detail::BodySystem> system_;  // null until set_configuration succeeds
  double seconds_setup_ = 0.0;
};

/// Bead-shell model of a sphere: beads on the unit sphere at the vertices of an icosahedron
/// subdivided `subdivisions` times (0 ... 6: 12, 42, 162, 642, 2562, ... = 10 4^s + 2 beads),
/// 3 coordinates per bead; multiply by the sphere's radius. Throws rpyfmm::Error outside 0 ... 6.
std::vector<double> icosphere_beads(int subdivisions);
/// Radius of touching beads on that unit shell: half the smallest bead-to-bead distance
/// (0.526 / 0.273 / 0.138 / 0.0691 for 0 ... 3 subdivisions).
double icosphere_bead_radius(int subdivisions);

}  // namespace rpyfmm::rpy
