// rpyfmm — DistributedRigidBodyDynamics: Brownian dynamics of rigid bodies made of beads
// (rpyfmm/bd/rigid_dynamics.hpp, docs/theory/rigid.md) with the bodies distributed over the ranks
// of an MPI communicator (docs/mpi.md, "Rigid bodies across ranks").
//
// Each rank owns whole bodies for the whole run: the global body order is the ranks' bodies in rank
// order, and the global bead order the ranks' beads in rank order (the bead operator's). One step is
// bd::RigidBodyDynamics's, with the serial stage code (bd/src/rigid/rigid_stages.hpp) on each rank's
// bodies and the solves across the ranks by DistributedRigidBodies:
//   1. forces and torques of this rank's bodies from the user's function of its own bodies' state;
//   2. Y = N W + sqrt(2 kT / dt) N K^T M^{-1} B z by DistributedRigidBodies::apply_with_noise, the
//      bead noise z keyed by (seed, step, stream 0, global bead index) as the serial engine keys it
//      (mpi::fill_normal);
//   3. the RFD drift: w keyed by (seed, step, stream 1) over the global body order (two triples per
//      body, as the serial engine's w of 6m entries), both perturbed configurations planned across
//      the ranks and solved (the second from the first's solution, as in serial);
//   4. the quaternion update and its blow-up guard, agreed over the ranks before any rank commits.
// With DistributedDirectRpy (bit for bit DirectRpy's products) and a sampler whose inner products
// are summed in the serial order (SqrtOptions preconditioner none or automatic: mpi::sqrt_apply's
// principal root, bit for bit the serial sampler's), the trajectory differs from the serial
// engine's with DirectRpy and preconditioner none only by the order of GMRES's inner-product sums;
// on one rank it is the serial trajectory bit for bit. The block preconditioner is that of each
// rank's beads (mpi/sqrt.hpp), so its noise depends on the partition.
//
// With DistributedPseRpy beads the bodies live in its periodic box as bd::RigidBodyDynamics's do
// with PseRpy: reference points and beads are never wrapped (the bead operator wraps its positions,
// DistributedRigidBodies takes the lever arms as minimum images), so a body may straddle the box,
// and the bead noise is the split sampler of DistributedPseRpy::apply_sqrt (PseRpy::apply_sqrt's;
// options.sqrt method automatic or split, not the block preconditioner). The trajectory agrees
// with the serial engine's with PseRpy (double wave grids) to the round-off of the PSE sums
// (docs/mpi.md "Rigid-body Brownian dynamics across ranks").
//
// Bead force fields (set_bead_forces, as RigidBodyDynamics::set_bead_forces) are evaluated at the
// start of each step (not in the RFD configurations, as in serial): every rank sums the forces on
// its own beads over them and the other ranks' beads within the list radius (a halo, found again
// when a bead has moved more than half the skin, as the serial list is rebuilt) in the serial order,
// bit for bit the serial bead forces, then its bodies' forces and torques as the serial engine sums
// them (force callbacks take the whole system, gathered on every rank). Every public call is
// collective and fails collectively (communicator.hpp).
#pragma once

#include <concepts>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <utility>
#include <variant>
#include <vector>

#include "rpyfmm/bd/rigid_dynamics.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/mpi/rigid_bodies.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::mpi {

namespace detail {
class RigidBeadForces;  // mpi/src/rigid_bead_forces.hpp
}  // namespace detail

class DistributedRigidBodyDynamics {
 public:
  /// Collective; `beads` a DistributedDirectRpy, DistributedFmmRpy or DistributedPseRpy. This rank's bodies, as
  /// bd::RigidBodyDynamics takes all of them: `local_shape`
  /// (3 n_local body-frame bead positions, body after body), `local_radii` (one or n_local; one
  /// radius is spread over this rank's beads), `local_body_offsets` (m_local + 1 entries from 0 to
  /// n_local; {0} on a rank without bodies), `local_positions` (3 m_local reference points),
  /// `local_orientations` (4 m_local quaternions, or empty for the identity). `beads` computes the
  /// bead products across the ranks (not owned: it must outlive this object). `forces` is called on
  /// every rank, also one without bodies, with the state of its own bodies, and writes their
  /// 6 m_local forces and torques. Every rank must pass the
  /// same options. Throws rpyfmm::Error on every rank when any rank's input is bad (as the serial
  /// engine: sizes, NaN/Inf, options, bodies RigidBodies refuses; and options that differ between
  /// the ranks, no body on any rank).
  template <class BeadOperator>
  requires(std::same_as<BeadOperator, DistributedDirectRpy> || std::same_as<BeadOperator, DistributedFmmRpy> ||
           std::same_as<BeadOperator, DistributedPseRpy>)
      DistributedRigidBodyDynamics(BeadOperator& beads, std::vector<double> local_shape,
                                   std::vector<double> local_radii, std::vector<std::size_t> local_body_offsets,
                                   std::vector<double> local_positions, std::vector<double> local_orientations,
                                   bd::RigidDynamicsOptions options, bd::BodyForceFunction forces = {})
      : DistributedRigidBodyDynamics(Operator(&beads), beads.communicator(), std::move(local_shape),
                                     std::move(local_radii), std::move(local_body_offsets), std::move(local_positions),
                                     std::move(local_orientations), options, std::move(forces)) {}
  ~DistributedRigidBodyDynamics();
  DistributedRigidBodyDynamics(const DistributedRigidBodyDynamics&) = delete;
  DistributedRigidBodyDynamics& operator=(const DistributedRigidBodyDynamics&) = delete;

  /// Collective. Bead forces from a force field, as bd::RigidBodyDynamics::set_bead_forces (pair
  /// potentials between beads of different bodies, on all ranks; per-type and global constant forces,
  /// trap, bonds between global bead indices, callbacks on the whole system), added to the force
  /// function's forces and torques every step. Every rank passes the same field and neighbour
  /// options; `local_bead_types`: this rank's n_local beads' types (indices into field.types()), or
  /// empty for type 0. Throws rpyfmm::Error on every rank on bad types, a periodic box smaller than
  /// twice the list radius, or a field that differs between the ranks.
  void set_bead_forces(bd::ForceField field, std::vector<std::uint32_t> local_bead_types = {},
                       bd::NeighbourOptions neighbours = {});

  /// Collective. Advances one step. On a blow-up on any rank, a force error or an unconverged solve,
  /// every rank keeps the last good step and throws the same rpyfmm::Error.
  const bd::RigidStepReport& step();
  /// Collective. `count` steps.
  void run(std::uint64_t count);

  [[nodiscard]] const Communicator& communicator() const { return comm_; }
  /// This rank's bodies and beads, and the global indices of its first body and first bead.
  [[nodiscard]] std::size_t local_bodies() const { return offsets_.size() - 1; }
  [[nodiscard]] std::size_t local_beads() const { return radii_.size(); }
  [[nodiscard]] std::size_t first_body() const { return first_body_; }
  [[nodiscard]] std::size_t first_bead() const { return first_bead_; }
  /// The bodies on all ranks.
  [[nodiscard]] std::size_t bodies() const { return total_bodies_; }
  /// This rank's reference points (3 m_local), orientations (4 m_local), bead positions (3 n_local)
  /// and lever arms (m_local).
  [[nodiscard]] std::span<const double> local_positions() const { return q_; }
  [[nodiscard]] std::span<const double> local_orientations() const { return quat_; }
  [[nodiscard]] std::span<const double> local_bead_positions() const { return beads_now_; }
  [[nodiscard]] std::span<const double> local_lever_arms() const { return lever_; }
  /// The step number (first_step + steps taken), the same on every rank.
  [[nodiscard]] std::uint64_t step_count() const { return step_; }
  [[nodiscard]] double time() const { return static_cast<double>(step_) * options_.dt; }
  [[nodiscard]] const bd::RigidDynamicsOptions& options() const { return options_; }
  /// The last step's report (iterations: the same on every rank) and the totals, with this rank's
  /// seconds per stage (as bd::RigidDynamicsTotals names them).
  [[nodiscard]] const bd::RigidStepReport& last_report() const { return report_; }
  [[nodiscard]] const bd::RigidDynamicsTotals& totals() const { return totals_; }

 private:
  using Operator = std::variant<DistributedDirectRpy*, DistributedFmmRpy*, DistributedPseRpy*>;
  DistributedRigidBodyDynamics(Operator beads, const Communicator& comm, std::vector<double> local_shape,
                               std::vector<double> local_radii, std::vector<std::size_t> local_body_offsets,
                               std::vector<double> local_positions, std::vector<double> local_orientations,
                               bd::RigidDynamicsOptions options, bd::BodyForceFunction forces);
  /// The stages of step(), in order (bd::RigidBodyDynamics's).
  void gather_forces_and_torques();
  void solve_velocities();
  void estimate_drift();
  void update_bodies();
  /// The RFD configuration Q + sign delta/2 S w planned on rfd_solver_ and its solve into out
  /// (warm: GMRES from the other side's solution). Returns GMRES iterations.
  int perturbed_solve(double sign, std::span<double> out, bool warm);

  Communicator comm_;
  rpy::Geometry geometry_ = rpy::Geometry::open();  // the bead operator's (the bead force field's box)
  bd::RigidDynamicsOptions options_;
  bd::BodyForceFunction forces_;
  std::vector<double> shape_, radii_;
  std::vector<std::size_t> offsets_;
  std::vector<double> q_, quat_, lever_;
  std::size_t first_body_ = 0, first_bead_ = 0, total_bodies_ = 0, total_beads_ = 0;
  std::unique_ptr<DistributedRigidBodies> solver_, rfd_solver_;
  std::unique_ptr<detail::RigidBeadForces> bead_field_;
  std::vector<double> bead_forces_;  // 3 n_local
  std::uint64_t step_ = 0;
  bd::RigidStepReport report_;
  bd::RigidDynamicsTotals totals_;
  // work arrays
  std::vector<double> beads_now_, w_, y_, drift_, z_, rfd_w_, rfd_v_, rfd_plus_, rfd_minus_, rfd_lambda_, q_work_,
      quat_work_, beads_work_;
};

}  // namespace rpyfmm::mpi
