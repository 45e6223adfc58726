// rpyfmm — what the distributed RPY operators derive alike from the particles every rank holds
// (private): the checks of a rank's share, the agreed viscosity, every rank's count and the whole
// set's bounding box and radius range, from which each rank chooses the serial operators' length
// units (rpy/src/length_units.hpp). Used by DistributedDirectRpy and DistributedFmmRpy.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "length_units.hpp"
#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::mpi::detail {

/// Collective: the viscosity, once every rank has checked its own (finite and > 0) and all ranks
/// agree on one value; throws rpyfmm::Error (invalid_argument) naming `where` on every rank
/// otherwise.
[[nodiscard]] double agreed_viscosity(const Communicator& comm, double viscosity, const char* where);

/// Collective: returns when every rank's number of right-hand sides of a block product is > 0 and
/// all ranks pass the same; throws rpyfmm::Error (invalid_argument) naming `where`
/// on every rank otherwise.
void agree_on_nrhs(const Communicator& comm, std::size_t nrhs, const char* where);

/// Not collective (run it inside Communicator::run): this rank's positions (3n) and radii (n,
/// each finite and > 0) as set_positions requires them; the message names `where`, not the rank.
void check_local_particles(std::span<const double> positions, std::span<const double> radii, const char* where);

/// Collective: one radius for each of this rank's particles (positions: 3n), once every rank has
/// checked its radius (finite and > 0; checked before the positions, so that the message speaks of
/// the radius, not of a radius per particle).
[[nodiscard]] std::vector<double> common_radii(const Communicator& comm, std::span<const double> positions,
                                               double radius, const char* where);

/// Collective: every rank's number of particles, by rank (one MPI_Allgather).
[[nodiscard]] std::vector<std::size_t> gather_counts(const Communicator& comm, std::size_t local_n);

/// The bounding box of all ranks' centres (particle indices global) and their radius range.
struct WholeSet {
  rpy::detail::BoundingBox box;
  rpy::detail::RadiiPiece radii;
};

/// Collective: the whole set's box and radius range from every rank's summary (one MPI_Allgather of
/// 15 doubles per rank), merged in rank order as bounding_box() scans the concatenation, so that the
/// box is bounding_box()'s of the whole set bit for bit. `offset`: the global index of this rank's
/// first particle; radii.first is set to it. At least one rank must hold a particle.
[[nodiscard]] WholeSet gather_whole_set(const Communicator& comm, std::span<const double> x, std::span<const double> a,
                                        std::size_t offset);

}  // namespace rpyfmm::mpi::detail
