// The block preconditioner's blocks kept between sampler calls (docs/mpi.md, "Brownian
// displacements"): the first mpi::sqrt_apply with the block preconditioner after set_positions
// (distributed bisection and factoring of the blocks, then the sample) against a second one on the same
// configuration (the kept blocks). Run under mpiexec by bench_mpi_ranks (bench/mpi/CMakeLists.txt).
//
// usage: bench_mpi_block_cache --method direct|fmm --n N [--eps 1e-6] [--reps 3] [--tol 1e-3] [--block 0]
//   (bench_mpi_common.hpp: N in all, uniform in the unit cube, radius 0.001; the noise in
//   [-0.5, 0.5); Lanczos; --block: preconditioner_block, 0 the automatic size).
// Prints one JSON line (rank 0): "first_s" and "second_s", the medians over reps (each rep a fresh
// set_positions and one product, then the two calls) of the slowest rank's time of each call; "build_s" and
// "gather_s", the medians of the slowest rank's build and its distributed bisection in the first
// call (BlockPreconditionerStats: gather_seconds); "exchange_s", the median of the slowest rank's time in the blocks'
// exchanges in the second call; the iterations of the last call.
#include <mpi.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "bench_mpi_common.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/sqrt.hpp"

namespace {

struct Timings {
  std::vector<double> first, second, build, gather, exchange;
  int iterations = 0;
};

// reps x (set_positions, the first call, the second call) on `op`.
template <class Operator>
Timings time_first_and_second(Operator& op, const std::vector<double>& x, const std::vector<double>& z, int reps,
                              double tol, int block) {
  rpyfmm::rpy::SqrtOptions options;
  options.method = rpyfmm::rpy::SqrtMethod::lanczos;
  options.preconditioner = rpyfmm::rpy::SqrtPreconditioner::block;
  options.tolerance = tol;
  options.preconditioner_block = block;
  std::vector<double> w(z.size());
  Timings t;
  rpyfmm::mpi::InnerProductStats stats;
  rpyfmm::rpy::SqrtReport report;
  const auto call = [&] { report = rpyfmm::mpi::sqrt_apply(op, z, w, 1, options, &stats); };
  std::vector<double> u(z.size());
  for (int r = 0; r < reps; ++r) {
    op.set_positions(x, 0.001);
    op.apply(z, u);  // a product first, so that neither call pays the operator's first-product costs
    t.first.push_back(bench_mpi::median_seconds(1, call));
    t.build.push_back(bench_mpi::max_over_ranks(stats.blocks.build_seconds));
    t.gather.push_back(bench_mpi::max_over_ranks(stats.blocks.gather_seconds));
    t.second.push_back(bench_mpi::median_seconds(1, call));
    t.exchange.push_back(bench_mpi::max_over_ranks(stats.blocks.exchange_seconds()));
  }
  t.iterations = report.iterations;
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  const auto [rank, ranks] = bench_mpi::start(&argc, &argv);
  const bench_mpi::Args a = bench_mpi::parse(argc, argv);
  std::string method = "direct";
  double tol = 1e-3;
  int block = 0;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i];
    if (k == "--method") method = argv[i + 1];
    if (k == "--tol") tol = std::atof(argv[i + 1]);
    if (k == "--block") block = std::atoi(argv[i + 1]);
  }
  const bench_mpi::Share s = bench_mpi::make_share(a, rank, ranks, 3);
  Timings t;
  if (method == "fmm") {
    rpyfmm::mpi::DistributedFmmRpy op(MPI_COMM_WORLD, 1.0, {.tolerance = a.eps});
    t = time_first_and_second(op, s.x, s.q, a.reps, tol, block);
  } else {
    rpyfmm::mpi::DistributedDirectRpy op(MPI_COMM_WORLD, 1.0);
    t = time_first_and_second(op, s.x, s.q, a.reps, tol, block);
  }
  if (rank == 0)
    std::printf(
        "{\"method\":\"%s\",\"ranks\":%d,\"N\":%llu,\"tol\":%.3g,\"block\":%d,\"first_s\":%.6g,\"second_s\":%.6g,"
        "\"build_s\":%.6g,\"gather_s\":%.6g,\"exchange_s\":%.6g,\"iterations\":%d}\n",
        method.c_str(), ranks, static_cast<unsigned long long>(s.total), tol, block, bench_mpi::median(t.first),
        bench_mpi::median(t.second), bench_mpi::median(t.build), bench_mpi::median(t.gather),
        bench_mpi::median(t.exchange), t.iterations);
  MPI_Finalize();
  return 0;
}
