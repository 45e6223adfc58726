// rpyfmm — the halo of a rank in distributed Brownian dynamics (rpyfmm/mpi/brownian_dynamics.hpp,
// docs/mpi.md "Brownian dynamics across ranks"): the other ranks' particles within the list
// radius of a cover of its own particles by tight boxes, and the part of the system its Verlet
// lists are built on.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "bd_bonds.hpp"
#include "cell_tree.hpp"
#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::mpi {

namespace detail {

/// x wrapped into [0, L) on each axis of a periodic geometry; x itself in an open one.
[[nodiscard]] std::array<double, 3> wrapped(const double* x, const rpy::Geometry& geometry);

/// A rank's particles (3n positions; wrapped in a periodic geometry) in Morton order in the cube
/// of their own wrapped positions, and the tree of cells over them (cell_tree.hpp): the region a
/// rank publishes is a cover of it by tight boxes, and the particles near another rank's region are
/// found by descending it.
struct OwnedCells {
  CellTree tree{};
  std::vector<std::uint32_t> order{};  // the index into the positions of each particle in tree order
  std::vector<double> wrapped{};       // 3 per particle, in tree order
};
[[nodiscard]] OwnedCells owned_cells(std::span<const double> positions, const rpy::Geometry& geometry);

/// The region of a rank: at most 64 tight boxes (region_cover) around its wrapped positions; no box
/// for no particle. A box around all of a rank's particles spans the periodic cell as soon as its
/// Morton range crosses a coarse cell boundary, so one box would make the halo the whole system.
[[nodiscard]] std::vector<Box> region_of(const OwnedCells& cells);
/// The squared distance between two boxes (of wrapped positions), over the periodic images of b in
/// a periodic geometry (the minimum image on each axis).
[[nodiscard]] double distance2(const Box& a, const Box& b, const rpy::Geometry& geometry);
/// Collective: every rank's region (MPI_Allgather of the counts, MPI_Allgatherv of the boxes).
[[nodiscard]] std::vector<std::vector<Box>> gather_regions(const Communicator& comm, const std::vector<Box>& mine);
/// This rank's particles (indices into the positions of `cells`, increasing) that each other rank
/// needs: those within `radius` of a box of its region (over the periodic images in a periodic
/// geometry); none for radius <= 0. The radius is widened by a relative 1e-12 so that rounding in
/// the wrap and the gaps can only add particles (a larger halo changes no sum: the pair lists keep
/// pairs by their own distances).
[[nodiscard]] std::vector<std::vector<std::uint32_t>> select_halo(const Communicator& comm, const OwnedCells& cells,
                                                                  const std::vector<std::vector<Box>>& regions,
                                                                  const rpy::Geometry& geometry, double radius);

}  // namespace detail

/// The part of the system a rank sums forces on: its own particles and its halo, in increasing
/// global index (the order of the serial engine's sums), with their Verlet lists, and the exchange
/// that refreshes the halo's positions.
struct DistributedBd::Halo {
  // the part
  std::vector<double> x{};  // 3m, unwrapped
  std::vector<std::uint32_t> types{};
  std::vector<std::uint64_t> ids{};
  std::vector<std::uint32_t> owned_rows{};  // the part's index of each owned particle, in owned order
  std::vector<std::uint32_t> halo_rows{};   // the part's index of each halo particle, in receive order
  // the exchange: owned particles (indices) sent to each rank, halo particles received from each
  std::vector<std::vector<std::uint32_t>> send{};
  std::vector<std::size_t> recv_counts{};
  bd::NeighbourList list;
  bool pairs = false;      // the force field has pair potentials (else no lists, no rebuild test)
  bool exchanges = false;  // pairs, bonds or complexes: a halo to refresh every step (the same on every rank)
  /// The skin of the rebuild test (a particle moved more than skin/2 since the build): the list's,
  /// or without pair potentials 0.3 x the reach of build() (options.skin where given).
  double skin = 0.0;
  /// With bonds: the force field with the bonds of the owned particles, their ends as part rows.
  std::optional<bd::ForceField> part_forces{};

  /// Collective: finds the halo of this rank's owned particles (positions 3n, types, ids,
  /// increasing): the other ranks' particles within the list radius r_c + skin (none without pair
  /// potentials) or, where larger, `reach` + skin (the SAC scheme's max R_A; 0: none), and the bond
  /// partners of the owned particles; exchanges it and builds the lists and the part's bonds.
  /// total: N.
  static Halo build(const Communicator& comm, const bd::ForceField& forces, const detail::BondIndex& bonds,
                    const rpy::Geometry& geometry, const bd::NeighbourOptions& neighbours,
                    std::span<const double> positions, std::span<const std::uint32_t> types,
                    std::span<const std::uint64_t> ids, std::uint64_t total, double reach = 0.0);
  /// Collective: the owned particles' current positions into the part, the halo's from its owners.
  void refresh(const Communicator& comm, std::span<const double> positions);
  /// Collective: `per` values of each part particle (in part order), the owned particles' from
  /// `owned` (per per owned particle), the halo's from their owners' `owned`.
  [[nodiscard]] std::vector<double> part_values(const Communicator& comm, std::span<const double> owned,
                                                std::size_t per) const;
  /// Each owned particle's neighbour-list entries (its row length), the cost weights of a partition.
  [[nodiscard]] std::vector<double> row_lengths() const;
};

}  // namespace rpyfmm::mpi
