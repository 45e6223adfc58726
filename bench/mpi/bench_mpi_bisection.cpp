// The block preconditioner's blocks across ranks (docs/mpi.md, "Brownian displacements"): the
// distributed bisection (mpi/src/distributed_bisection.hpp, what the samplers build) against the
// gather of the whole set to every rank followed by the serial rpy::bisect_blocks and the owners,
// kept here only as the baseline. Run under mpiexec by bench_mpi_ranks (bench/mpi/CMakeLists.txt).
//
// usage: bench_mpi_bisection --n N [--reps 5] [--block 32] [--order slabs|random]
//   (bench_mpi_common.hpp: N in all, uniform in the unit cube, contiguous shares in rank order;
//   --block: the blocks' size, 32 the samplers' automatic size from N = 2048 on; --order slabs:
//   the particles numbered by their x coordinate, so each rank's share is a slab, as a spatial
//   partition gives; random: numbered as drawn, every rank's share spread over the whole cube).
// Prints one JSON line (rank 0): per path, "seconds" (the median over reps of the slowest rank's
// time of one build of the blocks) and "bytes_max" / "bytes_min" (the bytes a rank received from
// the others in one build, the largest and smallest over the ranks); "same" whether the gathered
// path's blocks and owners are those of the distributed one (every rank's owned blocks compared).
#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <string>
#include <vector>

#include "bd_gather.hpp"
#include "bench_mpi_common.hpp"
#include "distributed_bisection.hpp"
#include "rpyfmm/rpy/block_factors.hpp"

namespace {

constexpr const char* kWhere = "bench_mpi_bisection";

// The baseline: every position and radius to every rank (gather_by_index: one MPI_Allgather of the
// counts, one MPI_Allgatherv of 5 doubles per particle), the serial bisection of the whole set and
// each block's owner (most members, lowest rank on a tie); returns the blocks this rank owns.
std::vector<std::size_t> gathered_blocks(const rpyfmm::mpi::Communicator& comm, std::size_t offset, std::size_t total,
                                         const std::vector<double>& x, const std::vector<double>& a, std::size_t block,
                                         const std::vector<std::size_t>& starts) {
  const std::size_t n = a.size();
  std::vector<std::uint64_t> ids(n);
  std::vector<double> values(4 * n);
  for (std::size_t i = 0; i < n; ++i) {
    ids[i] = offset + i;
    std::copy_n(x.data() + 3 * i, 3, values.data() + 4 * i);
    values[4 * i + 3] = a[i];
  }
  const std::vector<double> all =
      rpyfmm::mpi::detail::gather_by_index(comm, ids, values, total, 4, rpyfmm::mpi::detail::kEveryRank, kWhere);
  std::vector<double> positions(3 * total);
  for (std::size_t g = 0; g < total; ++g) std::copy_n(all.data() + 4 * g, 3, positions.data() + 3 * g);
  const rpyfmm::rpy::BlockPartition blocks = rpyfmm::rpy::bisect_blocks(positions, block);
  std::vector<std::size_t> owned, held(starts.size() - 1);
  for (std::size_t b = 0; b < blocks.blocks(); ++b) {
    std::fill(held.begin(), held.end(), std::size_t{0});
    for (std::size_t k = blocks.offsets[b]; k < blocks.offsets[b + 1]; ++k)
      ++held[static_cast<std::size_t>(std::upper_bound(starts.begin(), starts.end(), blocks.order[k]) -
                                      starts.begin()) -
             1];
    if (static_cast<int>(std::max_element(held.begin(), held.end()) - held.begin()) == comm.rank()) owned.push_back(b);
  }
  return owned;
}

// This rank's share of the whole set numbered by x (the set drawn on every rank: bench only).
std::vector<double> slab_share(const bench_mpi::Args& args, int rank, int ranks) {
  const std::vector<double> x = bench_mpi::make_share(args, 0, 1, 0).x;
  std::vector<std::size_t> order(x.size() / 3);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) { return x[3 * i] < x[3 * j]; });
  const bench_mpi::Share mine = bench_mpi::make_share(args, rank, ranks, 0);  // only its size and place
  std::size_t first = 0;
  for (int r = 0; r < rank; ++r) first += bench_mpi::make_share(args, r, ranks, 0).x.size() / 3;
  std::vector<double> out(mine.x.size());
  for (std::size_t k = 0; k < out.size() / 3; ++k) std::copy_n(x.data() + 3 * order[first + k], 3, out.data() + 3 * k);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  const bench_mpi::World world = bench_mpi::start(&argc, &argv);
  const bench_mpi::Args args = bench_mpi::parse(argc, argv);
  std::size_t block = 32;
  std::string order = "slabs";
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::string(argv[i]) == "--block") block = static_cast<std::size_t>(std::atoi(argv[i + 1]));
    if (std::string(argv[i]) == "--order") order = argv[i + 1];
  }
  bench_mpi::Share share = bench_mpi::make_share(args, world.rank, world.ranks, 0);
  if (order == "slabs") share.x = slab_share(args, world.rank, world.ranks);
  const std::size_t n = share.x.size() / 3;
  const std::vector<double> radii(n, 0.001);
  std::vector<std::size_t> starts(static_cast<std::size_t>(world.ranks) + 1, 0);
  std::vector<unsigned long long> counts(static_cast<std::size_t>(world.ranks));
  const unsigned long long mine = n;
  MPI_Allgather(&mine, 1, MPI_UNSIGNED_LONG_LONG, counts.data(), 1, MPI_UNSIGNED_LONG_LONG, MPI_COMM_WORLD);
  for (std::size_t r = 0; r < counts.size(); ++r) starts[r + 1] = starts[r] + counts[r];
  const std::size_t offset = starts[static_cast<std::size_t>(world.rank)];
  const rpyfmm::mpi::Communicator comm(MPI_COMM_WORLD);

  rpyfmm::mpi::detail::DistributedBlocks distributed;
  const double new_s = bench_mpi::median_seconds(args.reps, [&] {
    distributed = rpyfmm::mpi::detail::distributed_bisection(comm, offset, share.x, radii, block, kWhere);
  });
  std::vector<std::size_t> gathered;
  const double old_s = bench_mpi::median_seconds(
      args.reps, [&] { gathered = gathered_blocks(comm, offset, share.total, share.x, radii, block, starts); });
  // gather_by_index's receipts from the other ranks: one int count each, 5 doubles per particle.
  const auto old_bytes = static_cast<double>(sizeof(int) * static_cast<std::size_t>(world.ranks - 1) +
                                             5 * sizeof(double) * (share.total - n));
  const auto new_bytes = static_cast<double>(distributed.bytes_received);
  const int same = gathered == distributed.owned ? 1 : 0;
  int all_same = 0;
  MPI_Allreduce(&same, &all_same, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  const double neg_old = bench_mpi::max_over_ranks(-old_bytes), neg_new = bench_mpi::max_over_ranks(-new_bytes);
  const double old_max = bench_mpi::max_over_ranks(old_bytes), new_max = bench_mpi::max_over_ranks(new_bytes);
  if (world.rank == 0) {
    std::printf(
        "{\"ranks\": %d, \"order\": \"%s\", \"n\": %llu, \"block\": %zu, \"blocks\": %zu, \"levels\": %zu, \"rounds\": "
        "%zu, "
        "\"same\": %s, \"gathered\": {\"seconds\": %.6g, \"bytes_max\": %.0f, \"bytes_min\": %.0f}, "
        "\"distributed\": {\"seconds\": %.6g, \"bytes_max\": %.0f, \"bytes_min\": %.0f}}\n",
        world.ranks, order.c_str(), static_cast<unsigned long long>(share.total), block, distributed.blocks(),
        distributed.levels, distributed.rounds, all_same ? "true" : "false", old_s, old_max, -neg_old, new_s, new_max,
        -neg_new);
  }
  MPI_Finalize();
  return 0;
}
