// rpyfmm CLI — what the commands across MPI ranks share (docs/mpi.md, "The command-line tool
// under mpirun"): rank 0 holds the whole array it read, every rank a contiguous share of its rows,
// the remainder on the lowest ranks; scatter and gather move rows between the two, and the
// stage times reported by --json are the slowest rank's.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::cli {

/// N rows in P contiguous shares, in entries of `per` values per row: counts and displacements for
/// MPI_Scatterv / MPI_Gatherv. Throws rpyfmm::Error (not_supported) beyond MPI's int counts.
struct Shares {
  std::vector<int> counts, displs;
  /// The entries of rank r's share.
  [[nodiscard]] std::size_t count(int rank) const {
    return static_cast<std::size_t>(counts[static_cast<std::size_t>(rank)]);
  }
};
Shares shares_of(std::size_t n, int ranks, int per);

/// This rank's share of `whole` (read on rank 0 only; ignored elsewhere).
std::vector<double> scatter(const double* whole, const Shares& s, const mpi::Communicator& comm);
/// The shares gathered into `whole` on rank 0 (whole is not touched elsewhere).
void gather(const std::vector<double>& local, const Shares& s, double* whole, const mpi::Communicator& comm);
/// The shares gathered whole on every rank (MPI_Allgatherv).
std::vector<double> all_gather(const std::vector<double>& local, const Shares& s, const mpi::Communicator& comm);

/// Rank 0's `values` on every rank (their number first; ignored elsewhere on entry).
void broadcast(std::vector<std::uint64_t>& values, const mpi::Communicator& comm);

/// The slowest rank's value of each stage, on rank 0 (every rank passes the same stages).
StageTimes slowest(const StageTimes& mine, const mpi::Communicator& comm);
/// The sum over the ranks of each stage, on rank 0.
StageTimes summed(const StageTimes& mine, const mpi::Communicator& comm);

}  // namespace rpyfmm::cli
