// Scaling benchmark of DistributedLaplaceFmm (rpyfmm/mpi/laplace_fmm.hpp, docs/mpi.md "Scaling and
// a performance model"), run under mpiexec by the launcher bench_mpi_ranks (bench/mpi/
// CMakeLists.txt) for bench/run.py's group "mpi".
//
// usage: bench_mpi_fmm --n N --eps E [--scaling strong|weak] [--reps 3] [--measured-weights 1]
//                      [--overlap-exchange 1] [--gather-all-regions 1]
//   strong: N sources in all; weak: N sources per rank (N x P in all). Uniform in the unit cube,
//   zero-mean charges; every rank draws its own contiguous share of the global sequence (fixed
//   seed), so the input does not depend on P beyond its size.
// Prints one JSON line (rank 0): the plan (set_points) time, the median over reps of one evaluate
// (one density, potential and gradient), each the slowest rank's after a barrier, and per stage
// of the plan and of the last evaluate the slowest rank's exchange seconds, the bytes received by
// all ranks together, the slowest rank's local work and the largest essential set. With
// --measured-weights 1, the plan is then rebuilt with the measured per-leaf weights of the last
// evaluation (DistributedLaplaceFmm::measured_weights) and timed again: eval_measured_s and
// essential_measured_max. With --overlap-exchange 1, a second plan with
// DistributedFmmOptions::overlap_exchange (the serial FMM split to run during the exchanges) is
// timed alternately with the first, rep by rep: eval_s and eval_overlap_s, medians of the same reps.
// The regions' exchange: the largest and the mean number of ranks whose covers a rank received
// (region_neighbours_max, _mean) and the covers' bytes received by all ranks (region_MB); with
// --gather-all-regions 1 every cover is gathered on every rank (the reference all-gather).
#include <mpi.h>

#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "bench_mpi_common.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"

namespace {

using bench_mpi::max_over_ranks;
using bench_mpi::sum_over_ranks;

// `prefix`<stage>_s: the slowest rank's seconds of each stage.
void print_stages(const char* prefix, const rpyfmm::StageTimes& stages) {
  for (const auto& [stage, seconds] : stages) std::printf(",\"%s%s_s\":%.6g", prefix, stage.c_str(), seconds);
}

// The slowest rank's sum over the stages.
double slowest_total(const rpyfmm::StageTimes& mine) {
  double total = 0.0;
  for (const auto& [stage, seconds] : mine) total += seconds;
  return max_over_ranks(total);
}

// Whether the command line has "--name 1".
bool flag_on(int argc, char** argv, const std::string& name) {
  for (int i = 1; i + 1 < argc; ++i)
    if (argv[i] == name && std::string(argv[i + 1]) == "1") return true;
  return false;
}

rpyfmm::StageTimes slowest(const rpyfmm::StageTimes& mine) {
  rpyfmm::StageTimes out;
  for (const auto& [stage, seconds] : mine) out[stage] = max_over_ranks(seconds);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  const auto [rank, ranks] = bench_mpi::start(&argc, &argv);
  const bench_mpi::Args a = bench_mpi::parse(argc, argv);
  const bench_mpi::Share share = bench_mpi::make_share(a, rank, ranks, 1);

  rpyfmm::mpi::DistributedFmmOptions options;
  options.fmm.tolerance = a.eps;
  options.gather_all_regions = flag_on(argc, argv, "--gather-all-regions");
  rpyfmm::mpi::DistributedLaplaceFmm fmm(MPI_COMM_WORLD, options);
  const double plan_s = bench_mpi::median_seconds(1, [&] { fmm.set_points(share.x); });
  const rpyfmm::mpi::FmmCommunication plan_traffic = fmm.communication();

  std::vector<double> results(fmm.local_target_size() * rpyfmm::fmm::result_width);
  const auto evaluate = [&](const rpyfmm::mpi::DistributedLaplaceFmm& f) {
    f.evaluate(share.q, 1, rpyfmm::fmm::potential | rpyfmm::fmm::gradient, results);
  };
  const bool overlap = flag_on(argc, argv, "--overlap-exchange");
  std::unique_ptr<rpyfmm::mpi::DistributedLaplaceFmm> split;
  if (overlap) {
    rpyfmm::mpi::DistributedFmmOptions split_options = options;
    split_options.overlap_exchange = true;
    split = std::make_unique<rpyfmm::mpi::DistributedLaplaceFmm>(MPI_COMM_WORLD, split_options);
    split->set_points(share.x);
  }
  std::vector<double> one_times, split_times;
  for (int r = 0; r < a.reps; ++r) {  // alternately, so that the machine's load falls on both alike
    one_times.push_back(bench_mpi::median_seconds(1, [&] { evaluate(fmm); }));
    if (split) split_times.push_back(bench_mpi::median_seconds(1, [&] { evaluate(*split); }));
  }
  const double eval_s = bench_mpi::median(one_times);
  const rpyfmm::mpi::FmmCommunication& t = fmm.communication();
  const rpyfmm::StageTimes plan_comm = slowest(plan_traffic.plan_seconds);
  const rpyfmm::StageTimes eval_comm = slowest(t.evaluate_seconds);
  const rpyfmm::StageTimes plan_work = slowest(plan_traffic.compute_seconds);
  const rpyfmm::StageTimes eval_work = slowest(t.compute_seconds);
  const double plan_comm_s = slowest_total(plan_traffic.plan_seconds);
  const double eval_comm_s = slowest_total(t.evaluate_seconds);
  const double plan_bytes = sum_over_ranks(static_cast<double>(plan_traffic.plan_bytes_received));
  const double eval_bytes = sum_over_ranks(static_cast<double>(t.evaluate_bytes_received));
  const double essential = max_over_ranks(static_cast<double>(fmm.essential_size()));
  const double halo = sum_over_ranks(static_cast<double>(t.halo_received));
  const double nodes = sum_over_ranks(static_cast<double>(t.nodes_received));
  const auto neighbours = static_cast<double>(plan_traffic.region_neighbours);
  const double neighbours_max = max_over_ranks(neighbours), neighbours_sum = sum_over_ranks(neighbours);
  const double region_bytes = sum_over_ranks(static_cast<double>(plan_traffic.region_bytes_received));
  const bool measured = flag_on(argc, argv, "--measured-weights");
  double eval_measured_s = 0.0, essential_measured = 0.0;
  if (measured) {
    fmm.set_points(share.x, {}, fmm.measured_weights());
    eval_measured_s = bench_mpi::median_seconds(
        a.reps, [&] { fmm.evaluate(share.q, 1, rpyfmm::fmm::potential | rpyfmm::fmm::gradient, results); });
    essential_measured = max_over_ranks(static_cast<double>(fmm.essential_size()));
  }
  if (rank == 0) {
    std::printf(
        "{\"method\":\"fmm\",\"scaling\":\"%s\",\"ranks\":%d,\"N\":%llu,\"eps\":%g,\"plan_s\":%.6g,\"eval_s\":%.6g",
        a.scaling.c_str(), ranks, static_cast<unsigned long long>(share.total), a.eps, plan_s, eval_s);
    std::printf(",\"plan_comm_s\":%.6g,\"eval_comm_s\":%.6g,\"plan_MB\":%.6g,\"eval_MB\":%.6g", plan_comm_s,
                eval_comm_s, plan_bytes / 1e6, eval_bytes / 1e6);
    std::printf(",\"essential_max\":%.0f,\"halo\":%.0f,\"nodes\":%.0f", essential, halo, nodes);
    std::printf(",\"gather_all_regions\":%d,\"region_neighbours_max\":%.0f,\"region_neighbours_mean\":%.3g",
                options.gather_all_regions ? 1 : 0, neighbours_max, neighbours_sum / ranks);
    std::printf(",\"region_MB\":%.6g", region_bytes / 1e6);
    print_stages("plan_comm_", plan_comm);
    print_stages("eval_comm_", eval_comm);
    print_stages("plan_work_", plan_work);
    print_stages("eval_work_", eval_work);
    if (measured)
      std::printf(",\"eval_measured_s\":%.6g,\"essential_measured_max\":%.0f", eval_measured_s, essential_measured);
    if (overlap) std::printf(",\"eval_overlap_s\":%.6g", bench_mpi::median(split_times));
    std::printf("}\n");
  }
  MPI_Finalize();
  return 0;
}
