// rpyfmm — the serial block preconditioner's blocks across ranks (global_blocks.hpp).
#include "global_blocks.hpp"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <utility>

#include "distributed_bisection.hpp"
#include "stage_timer.hpp"

namespace rpyfmm::mpi::detail {
namespace {

constexpr const char* kWhere = "rpyfmm::mpi::sqrt_apply (block preconditioner)";

/// rpy::block_scale_exponent over the radii of all ranks (collective): every rank factors its
/// blocks times the same power of two, the one the serial preconditioner uses on the whole set, so
/// that blocks of extreme eta a fit single precision.
int global_block_scale_exponent(const Communicator& comm, std::span<const double> local_radii, double viscosity) {
  double extremes[2] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  for (const double a : local_radii) {  // {min a, -max a}: one MPI_MIN reduces both
    extremes[0] = std::min(extremes[0], a);
    extremes[1] = std::min(extremes[1], -a);
  }
  double global[2];
  check_mpi(MPI_Allreduce(extremes, global, 2, MPI_DOUBLE, MPI_MIN, comm.get()), "MPI_Allreduce");
  if (!std::isfinite(global[0])) return 0;  // no particle on any rank
  return rpy::block_scale_exponent(global[0], -global[1], viscosity);
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
  const auto me = static_cast<std::size_t>(comm.rank());
  std::size_t offset = 0;
  for (std::size_t r = 0; r < me && r < counts.size(); ++r) offset += counts[r];
  DistributedBlocks partition;
  timed(build_cost_.gather_seconds,
        [&] { partition = distributed_bisection(comm, offset, local_positions, local_radii, max_block, kWhere); });
  build_cost_.gather_bytes_received = partition.bytes_received;
  blocks_ = partition.blocks();
  // The members' exchange delivered each owned block's rows in the order an IndexExchange with the
  // same lists does, so its arrival rows are the block rows' places in forward()'s result.
  exchange_.self = comm.rank();
  exchange_.send = std::move(partition.send);
  exchange_.recv_counts = std::move(partition.recv_counts);
  gather_ = std::move(partition.arrived);
  owned_ = std::move(partition.owned_offsets);
  for (std::size_t k = 0; k + 1 < owned_.size(); ++k)
    factor_offset_.push_back(factor_offset_.back() + rpy::packed_entries(dofs_ * (owned_[k + 1] - owned_[k])));
  factors_.assign(factor_offset_.back(), 0.0f);
  std::vector<std::size_t> rows(partition.radii.size());  // the members' rows in partition.positions
  std::iota(rows.begin(), rows.end(), std::size_t{0});
  const int scale_exponent = global_block_scale_exponent(comm, local_radii, viscosity);
  const std::size_t owned = owned_blocks();
#pragma omp parallel for schedule(dynamic)
  for (std::size_t k = 0; k < owned; ++k) {
    const std::span<const std::size_t> block(rows.data() + owned_[k], owned_[k + 1] - owned_[k]);
    rpy::factor_block(partition.positions, partition.radii, viscosity, rpy::Geometry::open(), block, matrix,
                      factors_.data() + factor_offset_[k], scale_exponent);
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
