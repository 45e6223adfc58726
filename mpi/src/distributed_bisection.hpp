// rpyfmm — the block preconditioner's spatial blocks of particles distributed over MPI ranks by a
// distributed median bisection (private to rpyfmm::mpi; global_blocks.hpp, docs/mpi.md "Brownian
// displacements"): the blocks of rpy::bisect_blocks on the whole set in the global order, without
// any rank holding more than its own particles, the members of the blocks it owns and O(blocks)
// bookkeeping (the parts' sizes and owners, and per selection round a few samples of every rank per
// part still split across ranks).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::mpi::detail {

/// The blocks on this rank: the count of every block, the owner of every block, and the members of
/// the blocks this rank owns.
struct DistributedBlocks {
  /// Block b has global_offsets[b + 1] - global_offsets[b] members, in rpy::bisect_blocks' order
  /// of blocks (depth first, lower part first).
  std::vector<std::size_t> global_offsets{0};
  /// The rank that owns block b: the rank holding most of its members, the lowest such rank on a tie.
  std::vector<int> owner;
  /// The blocks this rank owns, ascending; owned block k's members are the entries
  /// owned_offsets[k] .. owned_offsets[k + 1] of the arrays below, in ascending global index.
  std::vector<std::size_t> owned;
  std::vector<std::size_t> owned_offsets{0};
  std::vector<std::uint64_t> members;  // global indices
  std::vector<double> positions;       // 3 per member
  std::vector<double> radii;
  /// Each member's row in the members' exchange as received (rank after rank in rank order, each
  /// rank's rows in send[this rank]'s order): what an IndexExchange with these lists delivers.
  std::vector<std::size_t> arrived;
  /// send[r]: this rank's particles (local indices) in blocks owned by rank r, by block, then index.
  std::vector<std::vector<std::uint32_t>> send;
  /// recv_counts[r]: the members this rank received from rank r.
  std::vector<std::size_t> recv_counts;
  /// The bytes this rank received from the other ranks while building: each MPI_Allreduce counted
  /// by the size of its result, each MPI_Allgather by the other ranks' parts, and the members'
  /// MPI_Alltoallv (6 doubles per member: index, block, position, radius) by what came from others.
  std::uint64_t bytes_received = 0;
  /// The tree levels split and the selection rounds (each one MPI_Allgather and one MPI_Allreduce).
  std::size_t levels = 0;
  std::size_t rounds = 0;

  [[nodiscard]] std::size_t blocks() const { return global_offsets.size() - 1; }
};

/// Collective. The blocks of at most max(max_block, 1) particles of the whole set whose global
/// order is the ranks' shares one after another in rank order: this rank holds the particles
/// `offset` .. offset + radii.size() - 1 (3 positions each). Every level of the bisection tree
/// splits all its parts in lock step: per part, the bounding box by one MPI_Allreduce (min over
/// the ranks of lo and -hi, exact), the axis as rpy::widest_axis, and the element of rank
/// floor(n / 2) in the order rpy::bisection_less by a distributed selection: rounds of sampled
/// pivots (a few of each rank's candidates, one MPI_Allgather) counted below by one MPI_Allreduce
/// of integer counts, each round keeping only the candidates between the pivots around the wanted
/// element. A part that one rank holds whole is split by that rank alone with rpy::bisect_blocks
/// (the other ranks know its blocks' sizes from its size), so deep levels of a spatial partition
/// cost no communication. The parts are exactly those of rpy::bisect_blocks on the gathered set,
/// for any number of ranks and any distribution. Then the owners (one MPI_Allreduce with
/// MPI_MAXLOC of the members per rank) and the members to them (one MPI_Alltoallv). Failures
/// (shares that do not follow each other, too many particles for MPI's int counts or for 32-bit
/// local indices) are collective.
[[nodiscard]] DistributedBlocks distributed_bisection(const Communicator& comm, std::size_t offset,
                                                      std::span<const double> positions, std::span<const double> radii,
                                                      std::size_t max_block, const char* where);

}  // namespace rpyfmm::mpi::detail
