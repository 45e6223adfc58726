// rpyfmm — bonds in distributed Brownian dynamics (rpyfmm/mpi/brownian_dynamics.hpp, docs/mpi.md
// "Brownian dynamics across ranks"): which of a rank's particles other ranks need as the bond
// partners of their own particles, found through a directory of owners, and the bonds of a rank's
// part (own and halo particles) with their ends as rows of the part.
//
// Every rank holds the force field's whole bond list (it is part of the force field, the same on
// every rank). A bond's partner may lie anywhere (a harmonic bond has no maximum length), so the
// partners are not found by distance: each particle's owner is registered at its home rank (the
// block of global indices [r N / P, (r + 1) N / P) that holds its index), a rank asks the home ranks
// for the partners it lacks, and the home ranks forward the requests to the owners. The owners
// then send those particles with the halo, every step until the next rebuild.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::mpi::detail {

/// The bonds of each particle of the whole system (indices into the bond list, in bond order).
class BondIndex {
 public:
  BondIndex(std::span<const bd::Bond> bonds, std::uint64_t particles);
  [[nodiscard]] std::span<const std::uint32_t> of(std::uint64_t id) const {
    return {entries_.data() + offsets_[id], entries_.data() + offsets_[id + 1]};
  }
  [[nodiscard]] std::span<const bd::Bond> bonds() const { return bonds_; }
  [[nodiscard]] bool empty() const { return bonds_.empty(); }

 private:
  std::vector<bd::Bond> bonds_;
  std::vector<std::uint64_t> offsets_;
  std::vector<std::uint32_t> entries_;
};

/// Collective: for each rank, this rank's particles (indices into `ids`, increasing) that the rank
/// needs as bond partners of its own particles and does not own. ids: this rank's particles'
/// global indices, increasing; total: N. Three MPI_Alltoallv: registration at the home ranks, the
/// requests to them, and their forwarding to the owners.
[[nodiscard]] std::vector<std::vector<std::uint32_t>> bond_partners_wanted(const Communicator& comm,
                                                                           const BondIndex& index,
                                                                           std::span<const std::uint64_t> ids,
                                                                           std::uint64_t total);

/// The bonds that touch the owned particles of a part, in bond order, with their ends as rows of
/// the part (part_ids: the part's global indices, increasing, holding every partner), and each
/// bond's index in the whole list.
struct PartBonds {
  std::vector<bd::Bond> bonds;
  std::vector<std::uint64_t> names;
};
[[nodiscard]] PartBonds part_bonds(const BondIndex& index, std::span<const std::uint64_t> owned_ids,
                                   std::span<const std::uint64_t> part_ids);

}  // namespace rpyfmm::mpi::detail
