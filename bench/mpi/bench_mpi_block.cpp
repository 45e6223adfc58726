// Several right-hand sides per product on the distributed RPY operators (docs/mpi.md, "apply_block"):
// apply_block with nrhs right-hand sides against nrhs calls of apply, on DistributedDirectRpy
// (one pass of the source blocks carrying every right-hand side) or DistributedFmmRpy (one Laplace
// evaluation carrying the densities of every right-hand side). Run under mpiexec by bench_mpi_ranks
// (bench/mpi/CMakeLists.txt).
//
// usage: bench_mpi_block --method direct|fmm --n N [--nrhs 4] [--eps 1e-6] [--reps 3]
//   (bench_mpi_common.hpp: N in all, uniform in the unit cube, radius 0.001 as bench_mpi_direct,
//   forces in [-0.5, 0.5)).
// Prints one JSON line (rank 0): "block_s" = the median over reps of one apply_block, "singles_s" =
// the median over reps of nrhs applies, each the slowest rank's, and "speedup" = singles_s / block_s;
// for fmm also the slowest rank's seconds in the owners' serial Laplace FMM ("fmm" of
// DistributedLaplaceFmm's compute_seconds) of one apply_block and of one apply.
#include <mpi.h>

#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>
#include <vector>

#include "bench_mpi_common.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"

namespace {

// The two timings of one operator (set_positions already called): apply_block on the nrhs
// right-hand sides in f, and nrhs applies of them one by one.
template <class Operator>
void time_block_and_singles(const Operator& op, const std::vector<double>& f, std::size_t nrhs, int reps,
                            double& block_s, double& singles_s) {
  const std::size_t n3 = f.size() / nrhs;
  std::vector<double> u(f.size());
  block_s = bench_mpi::median_seconds(reps, [&] { op.apply_block(f, u, nrhs); });
  singles_s = bench_mpi::median_seconds(reps, [&] {
    for (std::size_t k = 0; k < nrhs; ++k)
      op.apply(std::span<const double>(f).subspan(k * n3, n3), std::span<double>(u).subspan(k * n3, n3));
  });
}

}  // namespace

int main(int argc, char** argv) {
  const auto [rank, ranks] = bench_mpi::start(&argc, &argv);
  const bench_mpi::Args a = bench_mpi::parse(argc, argv);
  std::string method = "direct";
  std::size_t nrhs = 4;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i];
    if (k == "--method") method = argv[i + 1];
    if (k == "--nrhs") nrhs = static_cast<std::size_t>(std::atoi(argv[i + 1]));
  }
  // nrhs force components per particle: right-hand side k takes the k-th of each particle's values.
  const bench_mpi::Share s = bench_mpi::make_share(a, rank, ranks, static_cast<int>(3 * nrhs));
  const std::size_t n = s.x.size() / 3;
  std::vector<double> f(3 * n * nrhs);
  for (std::size_t k = 0; k < nrhs; ++k)
    for (std::size_t i = 0; i < 3 * n; ++i) f[3 * n * k + i] = s.q[3 * nrhs * (i / 3) + 3 * k + i % 3];

  double block_s = 0.0, singles_s = 0.0, block_fmm_s = 0.0, single_fmm_s = 0.0;
  if (method == "fmm") {
    rpyfmm::mpi::DistributedFmmRpy op(MPI_COMM_WORLD, 1.0, {.tolerance = a.eps});
    op.set_positions(s.x, 0.001);
    time_block_and_singles(op, f, nrhs, a.reps, block_s, singles_s);
    const auto serial_fmm = [&] {
      return bench_mpi::max_over_ranks(op.laplace().communication().compute_seconds.at("fmm"));
    };
    std::vector<double> u(f.size());
    op.apply_block(f, u, nrhs);
    block_fmm_s = serial_fmm();
    op.apply(std::span<const double>(f).first(f.size() / nrhs), std::span<double>(u).first(f.size() / nrhs));
    single_fmm_s = serial_fmm();
  } else {
    rpyfmm::mpi::DistributedDirectRpy op(MPI_COMM_WORLD, 1.0);
    op.set_positions(s.x, 0.001);
    time_block_and_singles(op, f, nrhs, a.reps, block_s, singles_s);
  }
  if (rank == 0)
    std::printf(
        "{\"method\":\"%s\",\"ranks\":%d,\"N\":%llu,\"nrhs\":%zu,\"eps\":%.3g,\"block_s\":%.6g,\"singles_s\":%.6g,"
        "\"speedup\":%.3f,\"block_fmm_s\":%.6g,\"single_fmm_s\":%.6g}\n",
        method.c_str(), ranks, static_cast<unsigned long long>(s.total), nrhs, a.eps, block_s, singles_s,
        singles_s / block_s, block_fmm_s, single_fmm_s);
  MPI_Finalize();
  return 0;
}
