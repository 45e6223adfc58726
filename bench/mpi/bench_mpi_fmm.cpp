// Scaling benchmark of DistributedLaplaceFmm (rpyfmm/mpi/laplace_fmm.hpp, docs/mpi.md "Scaling and
// a performance model"), run under mpiexec by the launcher bench_mpi_fmm_ranks (bench/mpi/
// CMakeLists.txt) for bench/run.py's group "mpi".
//
// usage: bench_mpi_fmm --n N --eps E [--scaling strong|weak] [--reps 3]
//   strong: N sources in all; weak: N sources per rank (N x P in all). Uniform in the unit cube,
//   zero-mean charges; every rank draws its own contiguous share of the global sequence (fixed
//   seed), so the input does not depend on P beyond its size.
// Prints one JSON line (rank 0): the plan (set_points) time, the median over reps of one evaluate
// (one density, potential and gradient), each the slowest rank's after a barrier, and per stage
// of the plan and of the last evaluate the slowest rank's exchange seconds, the bytes received by
// all ranks together, the slowest rank's local work and the largest essential set.
#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"

namespace {

struct Args {
  double n = 1e5, eps = 1e-6;
  std::string scaling = "strong";
  int reps = 3;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--n") a.n = std::atof(v.c_str());
    if (k == "--eps") a.eps = std::atof(v.c_str());
    if (k == "--scaling") a.scaling = v;
    if (k == "--reps") a.reps = std::atoi(v.c_str());
  }
  return a;
}

// Sources [first, first + count) of the global sequence and their charges (minus the mean of 0.5).
void make_share(std::uint64_t first, std::uint64_t count, std::vector<double>& x, std::vector<double>& q) {
  x.resize(3 * count);
  q.resize(count);
  for (std::uint64_t i = 0; i < count; ++i) {
    std::mt19937_64 g(first + i);  // per index: independent of the split
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int k = 0; k < 3; ++k) x[3 * i + k] = u(g);
    q[i] = u(g) - 0.5;
  }
}

double max_over_ranks(double v) {
  double m = 0.0;
  MPI_Allreduce(&v, &m, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  return m;
}

double sum_over_ranks(double v) {
  double s = 0.0;
  MPI_Allreduce(&v, &s, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  return s;
}

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

rpyfmm::StageTimes slowest(const rpyfmm::StageTimes& mine) {
  rpyfmm::StageTimes out;
  for (const auto& [stage, seconds] : mine) out[stage] = max_over_ranks(seconds);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  const Args a = parse(argc, argv);
  const auto per = static_cast<std::uint64_t>(a.n);
  const std::uint64_t total = a.scaling == "weak" ? per * static_cast<std::uint64_t>(ranks) : per;
  const std::uint64_t share = total / static_cast<std::uint64_t>(ranks) +
                              (static_cast<std::uint64_t>(rank) < total % static_cast<std::uint64_t>(ranks) ? 1 : 0);
  const std::uint64_t first =
      static_cast<std::uint64_t>(rank) * (total / static_cast<std::uint64_t>(ranks)) +
      std::min<std::uint64_t>(static_cast<std::uint64_t>(rank), total % static_cast<std::uint64_t>(ranks));
  std::vector<double> x, q;
  make_share(first, share, x, q);

  rpyfmm::mpi::DistributedFmmOptions options;
  options.fmm.tolerance = a.eps;
  rpyfmm::mpi::DistributedLaplaceFmm fmm(MPI_COMM_WORLD, options);
  MPI_Barrier(MPI_COMM_WORLD);
  rpyfmm::StopWatch watch;
  fmm.set_points(x);
  const double plan_s = max_over_ranks(watch.seconds());
  const rpyfmm::mpi::FmmCommunication plan_traffic = fmm.communication();

  std::vector<double> results(fmm.local_target_size() * rpyfmm::fmm::result_width);
  std::vector<double> times;
  for (int r = 0; r < a.reps; ++r) {
    MPI_Barrier(MPI_COMM_WORLD);
    watch.restart();
    fmm.evaluate(q, 1, rpyfmm::fmm::potential | rpyfmm::fmm::gradient, results);
    times.push_back(max_over_ranks(watch.seconds()));
  }
  std::sort(times.begin(), times.end());
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
  if (rank == 0) {
    std::printf("{\"scaling\":\"%s\",\"ranks\":%d,\"N\":%llu,\"eps\":%g,\"plan_s\":%.6g,\"eval_s\":%.6g",
                a.scaling.c_str(), ranks, static_cast<unsigned long long>(total), a.eps, plan_s,
                times[times.size() / 2]);
    std::printf(",\"plan_comm_s\":%.6g,\"eval_comm_s\":%.6g,\"plan_MB\":%.6g,\"eval_MB\":%.6g", plan_comm_s,
                eval_comm_s, plan_bytes / 1e6, eval_bytes / 1e6);
    std::printf(",\"essential_max\":%.0f,\"halo\":%.0f,\"nodes\":%.0f", essential, halo, nodes);
    print_stages("plan_comm_", plan_comm);
    print_stages("eval_comm_", eval_comm);
    print_stages("plan_work_", plan_work);
    print_stages("eval_work_", eval_work);
    std::printf("}\n");
  }
  MPI_Finalize();
  return 0;
}
