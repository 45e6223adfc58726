// rpyfmm — the halo of a rank in distributed Brownian dynamics (rpyfmm/mpi/brownian_dynamics.hpp,
// docs/mpi.md "Brownian dynamics across ranks"): the other ranks' particles within the list
// radius of the box of its own particles, and the part of the system its Verlet lists are built on.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::mpi {

/// The axis-aligned box of a rank's particles (in a periodic box, of their wrapped positions).
struct RegionBox {
  std::array<double, 3> lo{0.0, 0.0, 0.0}, hi{0.0, 0.0, 0.0};
  bool empty = true;
};

namespace detail {

/// x wrapped into [0, L) on each axis of a periodic geometry; x itself in an open one.
[[nodiscard]] std::array<double, 3> wrapped(const double* x, const rpy::Geometry& geometry);
/// The box of positions (3n; empty for n = 0), of their wrapped positions in a periodic geometry.
[[nodiscard]] RegionBox region_of(std::span<const double> positions, const rpy::Geometry& geometry);
/// The squared distance from p (wrapped) to the box, over the periodic images of p in a periodic
/// geometry (the minimum image); infinity for an empty box.
[[nodiscard]] double distance2_to(const std::array<double, 3>& p, const RegionBox& box, const rpy::Geometry& geometry);
/// Collective: every rank's region box (one MPI_Allgather).
[[nodiscard]] std::vector<RegionBox> gather_regions(const Communicator& comm, const RegionBox& mine);
/// This rank's particles (indices into positions, 3n) that each other rank needs: those within
/// `radius` of its region (over the periodic images in a periodic geometry); none for radius <= 0.
/// The radius is widened by a relative 1e-12 so that rounding in the wrap and the gaps can only add
/// particles (a larger halo changes no sum: the pair lists keep pairs by their own distances).
[[nodiscard]] std::vector<std::vector<std::uint32_t>> select_halo(const Communicator& comm,
                                                                  std::span<const double> positions,
                                                                  const std::vector<RegionBox>& regions,
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
  bool pairs = false;  // the force field has pair potentials (else no halo and no lists)

  /// Collective: finds the halo of this rank's owned particles (positions 3n, types, ids,
  /// increasing), exchanges it and builds the lists on the part. list_radius: r_c + skin (0: no
  /// pairs, no halo).
  static Halo build(const Communicator& comm, const bd::ForceField& forces, const rpy::Geometry& geometry,
                    const bd::NeighbourOptions& neighbours, std::span<const double> positions,
                    std::span<const std::uint32_t> types, std::span<const std::uint64_t> ids);
  /// Collective: the owned particles' current positions into the part, the halo's from its owners.
  void refresh(const Communicator& comm, std::span<const double> positions);
  /// Each owned particle's neighbour-list entries (its row length), the cost weights of a partition.
  [[nodiscard]] std::vector<double> row_lengths() const;
};

}  // namespace rpyfmm::mpi
