// rpyfmm — the serial block preconditioner's blocks across ranks (global_blocks.hpp).
#include "global_blocks.hpp"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>

#include "bd_gather.hpp"
#include "rpyfmm/core/validate.hpp"
#include "stage_timer.hpp"

namespace rpyfmm::mpi::detail {
namespace {

constexpr const char* kWhere = "rpyfmm::mpi::sqrt_apply (block preconditioner)";

// The whole set's positions (3 per particle) and radii in the global order, on every rank.
struct WholeSet {
  std::vector<double> positions;
  std::vector<double> radii;
};

WholeSet gather_whole_set(const Communicator& comm, std::size_t offset, std::size_t total,
                          std::span<const double> local_positions, std::span<const double> local_radii) {
  const std::size_t n = local_radii.size();
  std::vector<std::uint64_t> ids(n);
  std::vector<double> values(4 * n);
  for (std::size_t i = 0; i < n; ++i) {
    ids[i] = offset + i;
    std::copy_n(local_positions.data() + 3 * i, 3, values.data() + 4 * i);
    values[4 * i + 3] = local_radii[i];
  }
  const std::vector<double> all = gather_by_index(comm, ids, values, total, 4, kEveryRank, kWhere);
  WholeSet set{std::vector<double>(3 * total), std::vector<double>(total)};
  for (std::size_t g = 0; g < total; ++g) {
    std::copy_n(all.data() + 4 * g, 3, set.positions.data() + 3 * g);
    set.radii[g] = all[4 * g + 3];
  }
  return set;
}

// The rank of each particle of the global order: starts[r] <= g < starts[r + 1].
struct RankOf {
  std::vector<std::size_t> starts{0};
  explicit RankOf(std::span<const std::size_t> counts) {
    for (const std::size_t c : counts) starts.push_back(starts.back() + c);
  }
  [[nodiscard]] std::size_t operator()(std::size_t g) const {
    return static_cast<std::size_t>(std::upper_bound(starts.begin(), starts.end(), g) - starts.begin()) - 1;
  }
};

// The owner of each block: the rank holding most of its members, the lowest such rank on a tie
// (all of a block's members on one rank: no exchange for it).
std::vector<std::size_t> block_owners(const rpy::BlockPartition& blocks, const RankOf& rank_of, std::size_t ranks) {
  std::vector<std::size_t> owners(blocks.blocks());
  std::vector<std::size_t> members(ranks);
  for (std::size_t b = 0; b < blocks.blocks(); ++b) {
    std::fill(members.begin(), members.end(), std::size_t{0});
    for (std::size_t k = blocks.offsets[b]; k < blocks.offsets[b + 1]; ++k) ++members[rank_of(blocks.order[k])];
    owners[b] = static_cast<std::size_t>(std::max_element(members.begin(), members.end()) - members.begin());
  }
  return owners;
}

}  // namespace

GlobalBlocks::GlobalBlocks(const Communicator& comm, std::span<const std::size_t> counts,
                           std::span<const double> local_positions, std::span<const double> local_radii,
                           double viscosity, std::size_t max_block, rpy::PreconditionedMatrix matrix)
    : comm_(comm),
      viscosity_(viscosity),
      max_block_(max_block),
      matrix_(matrix),
      local_n_(local_radii.size()),
      dofs_(rpy::block_dofs(matrix)) {
  const StopWatch build;
  comm.run([&] {  // the exchanges list this rank's particles by 32-bit index
    require(local_n_ <= std::numeric_limits<std::uint32_t>::max(), ErrorCode::not_supported, kWhere,
            std::to_string(local_n_) + " particles on one rank, more than 2^32 - 1");
  });
  const auto me = static_cast<std::size_t>(comm.rank());
  const auto ranks = static_cast<std::size_t>(comm.size());
  const RankOf rank_of(counts);
  const std::size_t offset = rank_of.starts[me];
  WholeSet set;
  timed(build_cost_.gather_seconds,
        [&] { set = gather_whole_set(comm, offset, rank_of.starts.back(), local_positions, local_radii); });
  // gather_by_index's receipts from the other ranks: one int count each, then 5 doubles (index,
  // position, radius) per particle of theirs.
  build_cost_.gather_bytes_received =
      sizeof(int) * (ranks - 1) + sizeof(double) * 5 * (rank_of.starts.back() - local_n_);
  const rpy::BlockPartition partition = rpy::bisect_blocks(set.positions, max_block);
  blocks_ = partition.blocks();
  const std::vector<std::size_t> owners = block_owners(partition, rank_of, ranks);

  // Every rank walks the blocks in the same order, so what rank s sends to rank r (its members of
  // r's blocks, block after block, in block order) is what r expects from s in the same order.
  exchange_.self = comm.rank();
  exchange_.send.assign(ranks, {});
  exchange_.recv_counts.assign(ranks, 0);
  for (std::size_t b = 0; b < blocks_; ++b) {
    for (std::size_t k = partition.offsets[b]; k < partition.offsets[b + 1]; ++k) {
      const std::size_t g = partition.order[k];
      const std::size_t from = rank_of(g);
      if (from == me) exchange_.send[owners[b]].push_back(static_cast<std::uint32_t>(g - offset));
      if (owners[b] == me) ++exchange_.recv_counts[from];
    }
  }
  std::vector<std::size_t> next(ranks, 0);  // the next received row from each rank
  for (std::size_t r = 1; r < ranks; ++r) next[r] = next[r - 1] + exchange_.recv_counts[r - 1];
  std::vector<std::size_t> members;  // the global indices of the owned blocks' members
  for (std::size_t b = 0; b < blocks_; ++b) {
    if (owners[b] != me) continue;
    for (std::size_t k = partition.offsets[b]; k < partition.offsets[b + 1]; ++k) {
      members.push_back(partition.order[k]);
      gather_.push_back(next[rank_of(partition.order[k])]++);
    }
    owned_.push_back(gather_.size());
    const std::size_t m = dofs_ * (partition.offsets[b + 1] - partition.offsets[b]);
    factor_offset_.push_back(factor_offset_.back() + rpy::packed_entries(m));
  }
  factors_.assign(factor_offset_.back(), 0.0f);
  const std::size_t owned = owned_blocks();
#pragma omp parallel for schedule(dynamic)
  for (std::size_t k = 0; k < owned; ++k) {
    const std::span<const std::size_t> block(members.data() + owned_[k], owned_[k + 1] - owned_[k]);
    rpy::factor_block(set.positions, set.radii, viscosity, rpy::Geometry::open(), block, matrix,
                      factors_.data() + factor_offset_[k]);
  }
  build_cost_.particles_sent = exchange_.sent();
  build_cost_.particles_received = exchange_.received();
  build_cost_.build_seconds = build.seconds();
}

void GlobalBlocks::apply(rpy::BlockOp op, double* x, std::size_t nrhs, BlockExchangeStats& tally) const {
  const IndexExchange::Traffic before = exchange_.traffic;
  const std::size_t column = dofs_ * local_n_;
  const std::size_t width = dofs_ * nrhs;  // values per particle row in the exchanges
  // Row of particle i, component c, in one column: [x_t; x_r] as rpy::BlockPreconditioner's entry().
  const auto entry = [this](std::size_t i, std::size_t c) { return c < 3 ? 3 * i + c : 3 * (local_n_ + i) + c - 3; };
  std::vector<double> rows(width * local_n_);
  for (std::size_t i = 0; i < local_n_; ++i)
    for (std::size_t r = 0; r < nrhs; ++r)
      for (std::size_t c = 0; c < dofs_; ++c) rows[width * i + dofs_ * r + c] = x[column * r + entry(i, c)];
  const std::vector<double> received = exchange_.forward(comm_, rows.data(), width, kWhere, "block rows");
  std::vector<double> results(received.size());
  const std::size_t owned = owned_blocks();
#pragma omp parallel
  {
    std::vector<double> in, out;
#pragma omp for schedule(static)
    for (std::size_t k = 0; k < owned; ++k) {
      const std::size_t count = owned_[k + 1] - owned_[k];
      const std::size_t m = dofs_ * count;
      in.resize(m);
      out.resize(m);
      for (std::size_t r = 0; r < nrhs; ++r) {
        for (std::size_t p = 0; p < count; ++p)
          for (std::size_t c = 0; c < dofs_; ++c)
            in[dofs_ * p + c] = received[width * gather_[owned_[k] + p] + dofs_ * r + c];
        rpy::apply_block_factor(op, factors_.data() + factor_offset_[k], m, in.data(), out.data());
        for (std::size_t p = 0; p < count; ++p)
          for (std::size_t c = 0; c < dofs_; ++c)
            results[width * gather_[owned_[k] + p] + dofs_ * r + c] = out[dofs_ * p + c];
      }
    }
  }
  const std::vector<double> back = exchange_.backward(comm_, results, width, kWhere, "block rows");
  ++tally.applications;
  tally.columns += static_cast<long long>(nrhs);
  tally.seconds += exchange_.traffic.seconds - before.seconds;
  tally.bytes_received += exchange_.traffic.bytes_received - before.bytes_received;
  std::size_t at = 0;
  for (const std::vector<std::uint32_t>& list : exchange_.send) {
    for (const std::uint32_t i : list) {
      for (std::size_t r = 0; r < nrhs; ++r)
        for (std::size_t c = 0; c < dofs_; ++c) x[column * r + entry(i, c)] = back[at + dofs_ * r + c];
      at += width;
    }
  }
}

}  // namespace rpyfmm::mpi::detail
