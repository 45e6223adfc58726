// rpyfmm — DistributedRigidBodies: the mobility of rigid bodies built from beads
// (rpyfmm/rpy/rigid_bodies.hpp, docs/theory/rigid.md) with the bodies distributed over the ranks of
// an MPI communicator (docs/mpi.md, "Rigid bodies across ranks").
//
// Each rank owns whole bodies: its beads are those of its bodies, body after body, and its share
// of the saddle-point vector [lambda; Y] is its beads' forces and its bodies' velocities. The bead
// products M lambda run across the ranks by the distributed operator it is given
// (DistributedDirectRpy, DistributedFmmRpy, or DistributedPseRpy in a periodic box: the global
// bead order is the ranks' beads in rank order). K Y, K^T lambda, the lever-arm scaling and the
// body-block preconditioner (a dense Cholesky factor per body) are the serial RigidBodies' own code
// on each rank's bodies, with no communication: blocks never straddle ranks. In a periodic box the
// lever arms are minimum images in the bead operator's box, as RigidBodies takes them from
// PseRpy's geometry, so a body may straddle the box. GMRES is the serial solver's with every inner
// product the sum of the ranks' partial sums, added in rank order on every rank (one
// MPI_Allgather of one double per rank), so every rank takes the same steps.
//
// With DistributedDirectRpy (bit for bit DirectRpy's products) the iterates differ from the serial
// RigidBodies with DirectRpy on the whole set only by the order in which the inner products are
// summed; on one rank they are its bits. Every public call is collective and fails collectively
// (communicator.hpp): a bad input on one rank makes every rank throw the same rpyfmm::Error.
#pragma once

#include <cstddef>
#include <memory>
#include <span>
#include <variant>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::mpi {

class DistributedRigidBodies {
 public:
  /// Collective. `beads` computes the bead products across the ranks (not owned: it must outlive
  /// this object; set_configuration sets its positions, and nothing else may change them before
  /// apply). Throws rpyfmm::Error on every rank on bad options on any rank or options that differ
  /// between the ranks.
  DistributedRigidBodies(DistributedDirectRpy& beads, rpy::RigidBodyOptions options = {});
  DistributedRigidBodies(DistributedFmmRpy& beads, rpy::RigidBodyOptions options = {});
  /// The bodies in DistributedPseRpy's periodic box: lever arms r_i - q_k are minimum images in
  /// its box, and bead products and the bead noise are the distributed PSE's (equal radii only: a
  /// set_configuration with different radii fails every rank, as DistributedPseRpy::set_positions
  /// refuses them).
  DistributedRigidBodies(DistributedPseRpy& beads, rpy::RigidBodyOptions options = {});
  ~DistributedRigidBodies();
  DistributedRigidBodies(const DistributedRigidBodies&) = delete;
  DistributedRigidBodies& operator=(const DistributedRigidBodies&) = delete;

  /// Collective. This rank's beads (3 n_local positions, body after body) and their radii
  /// (n_local), its body offsets (m_local + 1 entries from 0 to n_local; {0} on a rank without
  /// bodies) and its bodies' reference points (3 m_local; empty: each of its bodies' bead
  /// centroids). Plans the bead operator and factors this rank's body blocks. Throws rpyfmm::Error
  /// on every rank when any rank's input is bad (as RigidBodies::set_configuration: sizes, NaN/Inf,
  /// bodies of fewer than three non-collinear beads, ...; and what the bead operator refuses, e.g.
  /// no bead on any rank).
  void set_configuration(std::span<const double> local_bead_positions, std::span<const double> local_radii,
                         std::span<const std::size_t> local_body_offsets,
                         std::span<const double> local_reference_points = {});

  /// Collective. Y = N W for this rank's bodies: forces and torques and velocities of 6 m_local
  /// entries each, optionally the bead forces lambda of its beads (3 n_local, or empty on every
  /// rank). Throws rpyfmm::Error on every rank for wrong sizes or NaN/Inf on any rank, before
  /// set_configuration, and when GMRES does not converge within max_iterations.
  rpy::RigidBodyReport apply(std::span<const double> local_forces_torques, std::span<double> local_velocities,
                             std::span<double> local_bead_forces = {}) const;

  /// Collective. apply() with GMRES started from a guess, as RigidBodies::apply_from: this rank's
  /// share of the velocities (6 m_local) and bead forces (3 n_local) of a nearby problem. The
  /// result meets the same tolerance, in fewer iterations the better the guess. Throws as apply,
  /// and on every rank for guesses of the wrong size or with NaN/Inf on any rank.
  rpy::RigidBodyReport apply_from(std::span<const double> local_forces_torques,
                                  std::span<const double> local_guess_velocities,
                                  std::span<const double> local_guess_bead_forces, std::span<double> local_velocities,
                                  std::span<double> local_bead_forces = {}) const;

  /// Collective. The body mobility matrix N of all ranks' bodies (6m x 6m, m = the sum of
  /// m_local; row-major, bodies in rank order, rows and columns (U, Omega) / (F, T) per body),
  /// returned whole on every rank with the same bits, as RigidBodies::mobility_matrix: 6m collective
  /// solves, each with a unit force or torque on one body of one rank, the column's shares
  /// gathered on every rank, then symmetrized (N = N^T exactly). Memory 288 m^2 bytes per rank.
  /// Throws on every rank for more than `max_bodies` bodies in all, max_bodies that differ between
  /// the ranks, a call before set_configuration, and as apply.
  [[nodiscard]] std::vector<double> mobility_matrix(std::size_t max_bodies = 200) const;

  /// Collective. Velocities with Brownian noise, as RigidBodies::apply_with_noise: Y = N W +
  /// noise_scale N K^T M^{-1} B z with B z (B B^T = M) by rpyfmm::mpi::sqrt_apply on the bead
  /// operator (`sqrt_options` as there: Lanczos or Chebyshev, the block preconditioner of each
  /// rank's beads; every rank passes the same), or with DistributedPseRpy by its apply_sqrt (the
  /// split sampler PseRpy::apply_sqrt uses in RigidBodies; methods automatic or split), local_z this
  /// rank's beads' share of the bead noise (3 n_local; mpi::fill_normal draws the serial noise by
  /// global index). Throws as apply, and on every rank for a bad z or noise_scale < 0 on any rank,
  /// noise scales that differ between the ranks, and what sqrt_apply or apply_sqrt refuses.
  rpy::RigidBodyReport apply_with_noise(std::span<const double> local_forces_torques, double noise_scale,
                                        std::span<const double> local_z, std::span<double> local_velocities,
                                        const rpy::SqrtOptions& sqrt_options = {},
                                        std::span<double> local_bead_forces = {}) const;

  [[nodiscard]] const Communicator& communicator() const { return comm_; }
  /// This rank's bodies and beads (0 before set_configuration).
  [[nodiscard]] std::size_t local_bodies() const;
  [[nodiscard]] std::size_t local_beads() const;
  /// The reference points q_k (3 m_local) of this rank's bodies in use.
  [[nodiscard]] std::span<const double> local_reference_points() const;
  [[nodiscard]] const rpy::RigidBodyOptions& options() const { return options_; }

 private:
  using Operator = std::variant<DistributedDirectRpy*, DistributedFmmRpy*, DistributedPseRpy*>;
  DistributedRigidBodies(Operator beads, const Communicator& comm, rpy::RigidBodyOptions options);
  /// The collective checks of apply's arguments.
  void check_call(std::span<const double> local_forces_torques, std::span<double> local_velocities,
                  std::span<double> local_bead_forces) const;
  /// GMRES across the ranks with the bead rows b[0, 3 n_local) given (the slip) and the body rows
  /// from the forces and torques; velocities and bead forces from its solution (collective).
  /// Started from the guesses of this rank's velocities and bead forces (empty: zero).
  rpy::RigidBodyReport solve(std::span<const double> local_forces_torques, std::vector<double>& b,
                             std::span<double> local_velocities, std::span<double> local_bead_forces,
                             std::span<const double> local_guess_velocities = {},
                             std::span<const double> local_guess_bead_forces = {}) const;

  Operator beads_;
  Communicator comm_;
  rpy::RigidBodyOptions options_;
  std::shared_ptr<const rpy::rigid_detail::BodySystem> system_;  // null until set_configuration succeeds
  double seconds_setup_ = 0.0;
};

}  // namespace rpyfmm::mpi
