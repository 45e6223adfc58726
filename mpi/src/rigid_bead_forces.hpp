// rpyfmm — the bead force field of DistributedRigidBodyDynamics (rpyfmm/mpi/rigid_dynamics.hpp,
// docs/mpi.md "Rigid-body Brownian dynamics across ranks"): bd::RigidBodyDynamics::set_bead_forces's
// forces on a rank's own beads, from every bead of the other bodies on all ranks.
//
// Every rank holds the whole system's bead positions each step (one MPI_Allgatherv, in the global
// bead order), the types and body of every bead, and a neighbour list over all beads, as the serial
// engine does; it sums the rows of its own beads (bd::ForceField::compute_rows, the serial compute's
// order, so its own beads' forces are the serial ones bit for bit). Memory, traffic and the list's
// upkeep are O(N) per rank: a halo of the beads within the cutoff of a rank's bodies is not done.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
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
  /// naming `where`, as the serial engine does: bad types, a periodic box smaller than twice the list
  /// radius; and a field or neighbour options that differ between the ranks.
  RigidBeadForces(const Communicator& comm, bd::ForceField field, std::vector<std::uint32_t> local_types,
                  const RankBeads& beads, const rpy::Geometry& geometry, const bd::NeighbourOptions& neighbours,
                  const char* where);

  struct Result {
    double energy = 0.0;   ///< the whole system's, summed in the serial engine's order
    bool rebuilt = false;  ///< the neighbour list was rebuilt
  };
  /// Collective: the forces (3 n_local) on this rank's beads at `local_positions` (3 n_local), from
  /// the pair terms with the beads of other bodies, the per-bead terms and the callbacks (called on
  /// every rank with the whole system, as ForceField::compute calls them). Fails on every rank with
  /// the lowest failing rank's error (a hard-core overlap names the serial engine's bead).
  Result compute(const Communicator& comm, std::span<const double> local_positions, std::uint64_t step,
                 std::span<double> forces);

 private:
  bd::ForceField field_;  // without its callbacks: compute_rows sums a part of the forces
  std::vector<bd::ForceCallback> callbacks_;
  std::vector<std::uint32_t> types_, bodies_, rows_;  // every bead's type and body; this rank's rows
  std::vector<std::uint64_t> ids_, local_ids_;        // every bead's global index; this rank's
  std::optional<bd::NeighbourList> list_;             // built once the field is checked
  std::vector<double> x_, energies_;                  // the whole system's positions; this rank's beads' energies
  const char* where_;
};

}  // namespace rpyfmm::mpi::detail
