// rpyfmm — the serial block preconditioner's blocks of the whole set on particles distributed over
// MPI ranks (private to rpyfmm::mpi; sqrt.cpp, docs/mpi.md "Brownian displacements"): the blocks
// rpy::BlockPreconditioner builds on the whole set in the global order (the ranks' shares one after
// another in rank order), each factored by one rank, and G, G^T, G^{-1} applied to a distributed
// vector by gathering each block's entries to that rank and sending the results back. Built once
// per operator positions, block size and matrix, and kept by the operator for later sampler calls
// (rpyfmm/mpi/sampler_blocks.hpp).
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "index_exchange.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "rpyfmm/rpy/block_factors.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"

namespace rpyfmm::mpi::detail {

class GlobalBlocks {
 public:
  /// Collective. The blocks of at most max_block particles of the whole set (counts[r] particles
  /// on rank r; this rank passes its own positions and radii) for `matrix` (translation: 3 rows per
  /// particle; scaled_grand: 6), open geometry. The blocks come from the distributed bisection
  /// (distributed_bisection.hpp: exactly rpy::bisect_blocks' blocks of the whole set, while each
  /// rank holds only its own particles and the members of the blocks it owns); each block is
  /// factored by its owner, the rank holding most of its members (the lowest such rank on a tie),
  /// which keeps only the factors of the blocks it owns. build_cost() reports what the build took.
  GlobalBlocks(const Communicator& comm, std::span<const std::size_t> counts, std::span<const double> local_positions,
               std::span<const double> local_radii, double viscosity, std::size_t max_block,
               rpy::PreconditionedMatrix matrix);

  /// Collective. x <- op(x) (G x, G^T x or G^{-1} x) on nrhs vectors of this rank's share, one
  /// after another, each rows_per_particle() x counts[rank] entries in the layout of
  /// rpy::BlockPreconditioner's vectors restricted to this rank: [x_t; x_r] with rotation. Each
  /// entry's bits are those of the serial BlockPreconditioner's on the whole set (the same
  /// factors, kernels and entry order per block). Two fixed-list exchanges (IndexExchange) for all
  /// nrhs vectors together, their time and bytes added to `tally` (their applications, columns,
  /// seconds and bytes received from other ranks).
  void apply(rpy::BlockOp op, double* x, std::size_t nrhs, BlockExchangeStats& tally) const;

  /// Whether these are the blocks of at most max_block particles for `matrix` and `viscosity` (the
  /// positions are the operator's until its set_positions drops them).
  [[nodiscard]] bool built_for(std::size_t max_block, rpy::PreconditionedMatrix matrix, double viscosity) const {
    return max_block == max_block_ && matrix == matrix_ && viscosity == viscosity_;
  }
  /// What the build cost this rank: build_seconds, gather_seconds and gather_bytes_received (the
  /// distributed bisection with the members sent to the owners), and the exchanges' lists (particles_sent,
  /// particles_received); reused false, no exchange counted.
  [[nodiscard]] const BlockPreconditionerStats& build_cost() const { return build_cost_; }

  /// The blocks of the whole set (the serial count).
  [[nodiscard]] std::size_t blocks() const { return blocks_; }
  /// The blocks this rank owns and factors.
  [[nodiscard]] std::size_t owned_blocks() const { return owned_.size() - 1; }

 private:
  Communicator comm_;
  double viscosity_;
  std::size_t max_block_;
  rpy::PreconditionedMatrix matrix_;
  std::size_t local_n_ = 0;
  std::size_t dofs_ = 3;
  std::size_t blocks_ = 0;
  // Owned block k: its members' positions in the received buffer (particle rows, forward()'s
  // order) gather_[owned_[k] .. owned_[k + 1]), in the serial block order; its packed factor at
  // factors_[factor_offset_[k]].
  std::vector<std::size_t> owned_{0};
  std::vector<std::size_t> gather_;
  std::vector<std::size_t> factor_offset_{0};
  std::vector<float> factors_;
  mutable IndexExchange exchange_;
  BlockPreconditionerStats build_cost_;
};

}  // namespace rpyfmm::mpi::detail
