// The cuts' search of SfcPartition (rpyfmm/mpi/partition.hpp; docs/mpi.md "Space-filling-curve
// partition"): one construction with the default budget of sums per round (up to 256 ways per
// round) against the same with one sum per round (the bisection, 2 ways), on the same input and
// ranks, run under mpiexec by the launcher bench_mpi_ranks (bench/mpi/CMakeLists.txt).
//
// usage: bench_mpi_partition --n N [--reps 5]
//   N uniform particles in the unit cube in all, unit weights, every rank drawing its contiguous
//   share of the global sequence (bench_mpi_common.hpp).
// Prints one JSON line per search (rank 0): its ways at the start, its rounds (MPI_Allreduce calls),
// the median over reps of one construction (the slowest rank's, after a barrier), the median of the
// same number of MPI_Allreduce calls of its first round's size replayed alone (allreduce_s: the
// search's communication without its local counting), and whether its splitters equal the other
// search's. The two searches alternate rep by rep, so that the
// machine's load falls on both alike.
#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "bench_mpi_common.hpp"
#include "rpyfmm/mpi/partition.hpp"

namespace {

using rpyfmm::mpi::SfcKey;
using rpyfmm::mpi::SfcPartition;

struct Search {
  const char* name;
  std::size_t sums_per_round;
  int rounds = 0;
  std::vector<SfcKey> splitters;
  std::vector<double> times;
};

// The ways of the search's first round (all cuts open; partition.hpp).
std::size_t ways_at_start(std::size_t sums_per_round, std::size_t cuts) {
  return std::max<std::size_t>(2, 1 + std::min(sums_per_round / cuts, rpyfmm::mpi::kCutMaxWays - 1));
}

// The median over reps of `rounds` MPI_Allreduce calls of `sums` integers alone (the slowest
// rank's): the communication of a search with that many rounds of its first round's size.
double replay_allreduces(int rounds, std::size_t sums, int reps) {
  std::vector<std::uint64_t> local(sums, 1), global(sums);
  return bench_mpi::median_seconds(reps, [&] {
    for (int r = 0; r < rounds; ++r) {
      MPI_Allreduce(local.data(), global.data(), static_cast<int>(sums), MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
    }
  });
}

}  // namespace

int main(int argc, char** argv) {
  const auto [rank, ranks] = bench_mpi::start(&argc, &argv);
  bench_mpi::Args a = bench_mpi::parse(argc, argv);
  if (a.reps == 3) a.reps = 5;  // bench_mpi::parse's default; a construction is short
  const bench_mpi::Share share = bench_mpi::make_share(a, rank, ranks, 0);

  std::vector<Search> searches{{"bisection", 1, 0, {}, {}}, {"multiway", rpyfmm::mpi::kCutSumsPerRound, 0, {}, {}}};
  for (int r = 0; r < a.reps; ++r) {
    for (Search& s : searches) {
      s.times.push_back(bench_mpi::median_seconds(1, [&] {
        const SfcPartition p(MPI_COMM_WORLD, share.x, {}, rpyfmm::mpi::SfcCurve::morton, s.sums_per_round);
        s.rounds = p.cut_rounds();
        s.splitters.assign(p.splitters().begin(), p.splitters().end());
      }));
    }
  }
  const bool same = searches[0].splitters == searches[1].splitters;
  const auto cuts = static_cast<std::size_t>(std::max(ranks - 1, 1));
  for (const Search& s : searches) {
    const std::size_t ways = ways_at_start(s.sums_per_round, cuts);
    const double allreduce_s = replay_allreduces(s.rounds, cuts * (ways - 1), a.reps);
    if (rank == 0) {
      std::printf(
          "{\"method\":\"sfc_partition\",\"search\":\"%s\",\"ranks\":%d,\"N\":%llu,\"ways\":%zu,\"rounds\":%d,"
          "\"construct_s\":%.6g,\"allreduce_s\":%.6g,\"same_splitters\":%s}\n",
          s.name, ranks, static_cast<unsigned long long>(share.total), ways, s.rounds, bench_mpi::median(s.times),
          allreduce_s, same ? "true" : "false");
    }
  }
  MPI_Finalize();
  return same ? 0 : 1;
}
