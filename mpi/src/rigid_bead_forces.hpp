// rpyfmm — the bead force field of DistributedRigidBodyDynamics (rpyfmm/mpi/rigid_dynamics.hpp,
// docs/mpi.md "Rigid-body Brownian dynamics across ranks"): bd::RigidBodyDynamics::set_bead_forces's
// forces on a rank's own beads, from the beads of the other bodies on all ranks.
//
// A rank sums the rows of its own beads (bd::ForceField::compute_rows, the serial compute's order)
// over the part of the system that DistributedBd sums over (mpi/src/bd_halo.hpp): its own beads
// and the other ranks' beads within the list radius r_c + skin of them, and the bond partners of
// its beads, in increasing global index, with a neighbour list over the part. The halo is found
// again (and the list rebuilt) when any bead has moved more than skin/2 since the last build, the
// serial list's test (Tran et al. (2015), Algorithm 1), else only the halo's positions are
// exchanged; no pair within the cut-off is then missed, so each own bead's force is the serial one
// bit for bit at the same positions. The energy is summed in the global bead order along the ranks
// (the serial sum's bits). Force callbacks take the whole system: with them every rank gathers all
// bead positions and the forces of the other terms (O(N) per rank), as ForceField::compute calls
// them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bd_bonds.hpp"
#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::mpi::detail {

/// This rank's beads: the global index of its first body and first bead, its body offsets
/// (m_local + 1 entries from 0) and the number of beads on all ranks.
struct RankBeads {
  std::size_t first_body = 0, first_bead = 0, total_beads = 0;
  std::span<const std::size_t> offsets;
};

class RigidBeadForces {
 public:
  /// Collective: the field (the same on every rank) for the beads of all ranks, with `local_types`
  /// this rank's beads' types (n_local, or empty for type 0). Throws rpyfmm::Error on every rank,
  /// naming `where`, as the serial engine does: bad types or bonds, a periodic box smaller than twice
  /// the list radius; and a field or neighbour options that differ between the ranks.
  RigidBeadForces(const Communicator& comm, bd::ForceField field, std::vector<std::uint32_t> local_types,
                  const RankBeads& beads, const rpy::Geometry& geometry, const bd::NeighbourOptions& neighbours,
                  const char* where);
  ~RigidBeadForces();
  RigidBeadForces(const RigidBeadForces&) = delete;
  RigidBeadForces& operator=(const RigidBeadForces&) = delete;

  struct Result {
    double energy = 0.0;   ///< the whole system's, summed in the serial engine's order
    bool rebuilt = false;  ///< the halo and the neighbour list were rebuilt (the serial list's test)
  };
  /// Collective: the forces (3 n_local) on this rank's beads at `local_positions` (3 n_local), from
  /// the pair terms with the beads of other bodies, the per-bead terms, the bonds and the callbacks.
  /// Fails on every rank with the lowest failing rank's error (a hard-core overlap names the serial
  /// engine's beads).
  Result compute(const Communicator& comm, std::span<const double> local_positions, std::uint64_t step,
                 std::span<double> forces);

 private:
  /// Collective: whether the halo and the list are due (first call, fixed interval, or any bead on
  /// any rank moved more than skin/2 since the last build).
  bool rebuild_due(const Communicator& comm, std::span<const double> local_positions) const;
  /// Collective: the part (own beads and halo) at `local_positions`, its bodies and its list.
  void rebuild(const Communicator& comm, std::span<const double> local_positions);
  /// Collective: the callbacks on the whole system (gathered), adding to this rank's forces.
  void add_callback_forces(const Communicator& comm, std::span<const double> local_positions, std::uint64_t step,
                           std::span<double> forces) const;

  bd::ForceField field_;  // without its callbacks: compute_rows sums a part of the forces
  std::vector<bd::ForceCallback> callbacks_;
  BondIndex bonds_;
  rpy::Geometry geometry_;
  bd::NeighbourOptions neighbours_;
  std::vector<std::uint32_t> types_;  // this rank's beads'
  std::vector<double> bodies_;        // this rank's beads' global body indices (exact as doubles)
  std::vector<std::uint64_t> ids_;    // this rank's beads' global indices
  std::uint64_t total_ = 0;
  std::unique_ptr<DistributedBd::Halo> halo_;
  std::vector<std::uint32_t> part_bodies_;  // the body of each bead of the part
  std::vector<double> reference_;           // this rank's bead positions at the last build
  double skin_ = 0.0;
  std::uint64_t steps_since_build_ = 0;
  std::vector<double> energies_;  // this rank's beads' shares of the energy
  const char* where_;
};

}  // namespace rpyfmm::mpi::detail
