// Separate targets in DistributedLaplaceFmm partitioned by their own balanced cuts against the
// sources' cuts (DistributedFmmOptions::targets_follow_sources; docs/mpi.md "Distributed Laplace
// FMM"), on the same input and ranks, run under mpiexec by the launcher bench_mpi_ranks
// (bench/mpi/CMakeLists.txt).
//
// usage: bench_mpi_targets --n N --eps E [--points uniform|clustered] [--reps 3]
//   N sources in all (strong scaling), uniform in the unit cube with zero-mean charges, every rank
//   drawing its contiguous share of the global sequence (bench_mpi_common.hpp); N targets, each the
//   reflection 1 - x of a source through the cube's centre (uniform too). clustered: the targets
//   whose third coordinate has a fractional part of 1e6 x below 0.9 (about 90 %) are moved into
//   the cube [0.6, 0.7]^3, a density contrast of about 900.
// Prints one JSON line per partition of the targets (rank 0): the largest number of owned sources
// and owned targets, the halo particles received by all ranks and by the largest receiver, the
// equivalent nodes received by all ranks, the largest essential set (own + halo + nodes,
// DistributedLaplaceFmm::essential_size), the plan's time, the median over reps of one evaluate
// (one density, potential and gradient; the slowest rank's, after a barrier) and, of the last
// evaluate, the slowest rank's seconds in the essential charges' exchange and in the serial FMM.
// The two partitions' evaluations alternate rep by rep, so that the machine's load falls on both
// alike.
#include <mpi.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "bench_mpi_common.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"

namespace {

using bench_mpi::max_over_ranks;
using bench_mpi::sum_over_ranks;

// The targets of the usage above from this rank's sources.
std::vector<double> targets_of(const std::vector<double>& x, bool clustered) {
  std::vector<double> y(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) y[i] = 1.0 - x[i];
  if (!clustered) return y;
  for (std::size_t i = 0; i < y.size(); i += 3) {
    double whole = 0.0;
    if (std::modf(y[i + 2] * 1e6, &whole) >= 0.9) continue;
    for (std::size_t d = 0; d < 3; ++d) y[i + d] = 0.6 + 0.1 * y[i + d];
  }
  return y;
}

std::string option_value(int argc, char** argv, const std::string& name, const std::string& fallback) {
  for (int i = 1; i + 1 < argc; ++i) {
    if (argv[i] == name) return argv[i + 1];
  }
  return fallback;
}

// One partition of the targets: its plan and evaluate times.
struct Run {
  bool follow = false;
  rpyfmm::mpi::DistributedLaplaceFmm fmm;
  double plan_s = 0.0;
  std::vector<double> eval_times;
};

double stage(const rpyfmm::StageTimes& times, const char* name) {
  const auto it = times.find(name);
  return max_over_ranks(it == times.end() ? 0.0 : it->second);
}

void print(const Run& r, std::uint64_t n, int ranks, double eps, const std::string& points, int rank) {
  const rpyfmm::mpi::FmmCommunication& t = r.fmm.communication();
  const auto count = [](auto v) { return static_cast<double>(v); };
  // Every value is reduced on every rank (collective), then printed by rank 0.
  const std::pair<const char*, double> fields[] = {
      {"owned_max", max_over_ranks(count(r.fmm.owned_size()))},
      {"owned_targets_max", max_over_ranks(count(r.fmm.owned_target_size()))},
      {"halo", sum_over_ranks(count(t.halo_received))},
      {"halo_max", max_over_ranks(count(t.halo_received))},
      {"nodes", sum_over_ranks(count(t.nodes_received))},
      {"essential_max", max_over_ranks(count(r.fmm.essential_size()))},
      {"plan_s", r.plan_s},
      {"eval_s", bench_mpi::median(r.eval_times)},
      {"eval_comm_essential_s", stage(t.evaluate_seconds, "essential")},
      {"eval_work_fmm_s", stage(t.compute_seconds, "fmm")},
  };
  if (rank != 0) return;
  std::printf("{\"method\":\"fmm_targets\",\"targets_follow_sources\":%d,\"points\":\"%s\",\"ranks\":%d,\"N\":%llu",
              r.follow ? 1 : 0, points.c_str(), ranks, static_cast<unsigned long long>(n));
  std::printf(",\"eps\":%g", eps);
  for (const auto& [name, value] : fields) std::printf(",\"%s\":%.10g", name, value);
  std::printf("}\n");
}

}  // namespace

int main(int argc, char** argv) {
  const auto [rank, ranks] = bench_mpi::start(&argc, &argv);
  const bench_mpi::Args a = bench_mpi::parse(argc, argv);
  const bench_mpi::Share share = bench_mpi::make_share(a, rank, ranks, 1);
  const std::string points = option_value(argc, argv, "--points", "uniform");
  const std::vector<double> targets = targets_of(share.x, points == "clustered");

  std::vector<Run> runs;
  for (bool follow : {false, true}) {
    rpyfmm::mpi::DistributedFmmOptions options;
    options.fmm.tolerance = a.eps;
    options.targets_follow_sources = follow;
    runs.push_back(Run{follow, rpyfmm::mpi::DistributedLaplaceFmm(MPI_COMM_WORLD, options), 0.0, {}});
    runs.back().plan_s = bench_mpi::median_seconds(1, [&] { runs.back().fmm.set_points(share.x, targets); });
  }
  std::vector<double> results(targets.size() / 3 * rpyfmm::fmm::result_width);
  for (int r = 0; r < a.reps; ++r) {
    for (Run& run : runs) {
      run.eval_times.push_back(bench_mpi::median_seconds(
          1, [&] { run.fmm.evaluate(share.q, 1, rpyfmm::fmm::potential | rpyfmm::fmm::gradient, results); }));
    }
  }
  for (const Run& run : runs) print(run, share.total, ranks, a.eps, points, rank);
  MPI_Finalize();
  return 0;
}
