// rpyfmm — DistributedPseRpy's memory limit per rank (docs/mpi.md, "Distributed PSE"):
// PseOptions::max_memory_bytes bounds what one rank holds, its slab of the wave grid and its
// particles' windows, not the whole grid.
#pragma once

#include <cstddef>

#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace rpyfmm::mpi::detail {

/// The budget the serial parameter choice gets for the whole grid on `ranks` ranks: the limit of
/// every rank together, ranks x per_rank_limit (saturated at the largest size_t). On one rank it is
/// the limit itself, so that the choice is PseRpy's; on more it lets the automatic choice shrink the
/// grid only where all ranks together could not hold it.
[[nodiscard]] std::size_t whole_grid_budget(std::size_t per_rank_limit, int ranks);

/// Collective (one MPI_Allgather): this rank's memory for parameters p and its local_n particles
/// (bytes): its slab of the wave grid (SlabWaveSpace::memory_bytes: FFTW-MPI's local size with its
/// padding, and c(k)) and the windows of its particles as PseRpy's estimate counts them per particle
/// (8 (P_x + P_y + P_z + 8) bytes). Throws the same rpyfmm::Error (out_of_memory) on every rank
/// where any rank's memory exceeds `limit`, naming the rank of the largest need (the
/// lowest of equal ones), its bytes and the limit; returns this rank's bytes otherwise.
std::size_t check_rank_memory(const Communicator& comm, const rpy::pse::PseParameters& p, std::size_t local_n,
                              std::size_t limit, const char* where);

}  // namespace rpyfmm::mpi::detail
