// Several right-hand sides per product on the distributed RPY operators (docs/mpi.md, "apply_block"):
// apply_block with nrhs right-hand sides against nrhs calls of apply, on DistributedDirectRpy
// (one pass of the source blocks carrying every right-hand side) or DistributedFmmRpy (one Laplace
// evaluation carrying the densities of every right-hand side). Run under mpiexec by bench_mpi_ranks
// (bench/mpi/CMakeLists.txt).
//
// With --sampler lanczos|chebyshev, the samplers instead (docs/mpi.md, "Several right-hand sides"):
// mpi::sqrt_apply on the nrhs right-hand sides in one call against nrhs calls, at tolerance --tol.
//
// usage: bench_mpi_block --method direct|fmm --n N [--nrhs 4] [--eps 1e-6] [--reps 3]
//                        [--sampler lanczos|chebyshev] [--tol 1e-3]
//   (bench_mpi_common.hpp: N in all, uniform in the unit cube, radius 0.001 as bench_mpi_direct,
//   forces in [-0.5, 0.5), the right-hand sides of the samplers too).
// Prints one JSON line (rank 0): "block_s" = the median over reps of one apply_block, "singles_s" =
// the median over reps of nrhs applies, each the slowest rank's, and "speedup" = singles_s / block_s;
// with --sampler the same of one sqrt_apply call and of nrhs calls, with the call's iterations and
// exchanges of inner products and those of the nrhs calls together;
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
#include "rpyfmm/mpi/sqrt.hpp"

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

// The samplers' timings: one sqrt_apply on the nrhs right-hand sides in z, and nrhs calls on them one
// by one; prints the JSON line on rank 0.
template <class Operator>
void time_samplers(const Operator& op, const std::vector<double>& z, std::size_t nrhs, int reps,
                   const std::string& sampler, double tol, const std::string& method, int ranks, double total) {
  rpyfmm::rpy::SqrtOptions options;
  options.method = rpyfmm::rpy::sqrt_method_from_string(sampler);
  options.tolerance = tol;
  const std::size_t n3 = z.size() / nrhs;
  std::vector<double> w(z.size());
  rpyfmm::mpi::InnerProductStats one{}, each{};
  rpyfmm::rpy::SqrtReport report;
  long long singles_exchanges = 0;
  const auto block = [&] { report = rpyfmm::mpi::sqrt_apply(op, z, w, nrhs, options, &one); };
  const auto singles = [&] {
    singles_exchanges = 0;
    for (std::size_t k = 0; k < nrhs; ++k) {
      rpyfmm::mpi::sqrt_apply(op, std::span<const double>(z).subspan(k * n3, n3),
                              std::span<double>(w).subspan(k * n3, n3), 1, options, &each);
      singles_exchanges += each.exchanges;
    }
  };
  // The two alternate rep by rep, so that a shared machine's changing load slows both alike.
  std::vector<double> block_times, singles_times;
  for (int r = 0; r < reps; ++r) {
    block_times.push_back(bench_mpi::median_seconds(1, block));
    singles_times.push_back(bench_mpi::median_seconds(1, singles));
  }
  const double block_s = bench_mpi::median(block_times), singles_s = bench_mpi::median(singles_times);
  int rank = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (rank == 0)
    std::printf(
        "{\"method\":\"%s\",\"sampler\":\"%s\",\"ranks\":%d,\"N\":%.0f,\"nrhs\":%zu,\"tol\":%.3g,"
        "\"block_s\":%.6g,\"singles_s\":%.6g,\"speedup\":%.3f,\"iterations\":%d,\"exchanges\":%lld,"
        "\"singles_exchanges\":%lld}\n",
        method.c_str(), sampler.c_str(), ranks, total, nrhs, tol, block_s, singles_s, singles_s / block_s,
        report.iterations, one.exchanges, singles_exchanges);
}

}  // namespace

int main(int argc, char** argv) {
  const auto [rank, ranks] = bench_mpi::start(&argc, &argv);
  const bench_mpi::Args a = bench_mpi::parse(argc, argv);
  std::string method = "direct";
  std::string sampler;
  double tol = 1e-3;
  std::size_t nrhs = 4;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i];
    if (k == "--method") method = argv[i + 1];
    if (k == "--nrhs") nrhs = static_cast<std::size_t>(std::atoi(argv[i + 1]));
    if (k == "--sampler") sampler = argv[i + 1];
    if (k == "--tol") tol = std::atof(argv[i + 1]);
  }
  // nrhs force components per particle: right-hand side k takes the k-th of each particle's values.
  const bench_mpi::Share s = bench_mpi::make_share(a, rank, ranks, static_cast<int>(3 * nrhs));
  const std::size_t n = s.x.size() / 3;
  std::vector<double> f(3 * n * nrhs);
  for (std::size_t k = 0; k < nrhs; ++k)
    for (std::size_t i = 0; i < 3 * n; ++i) f[3 * n * k + i] = s.q[3 * nrhs * (i / 3) + 3 * k + i % 3];

  if (!sampler.empty()) {
    const auto total = static_cast<double>(s.total);
    if (method == "fmm") {
      rpyfmm::mpi::DistributedFmmRpy op(MPI_COMM_WORLD, 1.0, {.tolerance = a.eps});
      op.set_positions(s.x, 0.001);
      time_samplers(op, f, nrhs, a.reps, sampler, tol, method, ranks, total);
    } else {
      rpyfmm::mpi::DistributedDirectRpy op(MPI_COMM_WORLD, 1.0);
      op.set_positions(s.x, 0.001);
      time_samplers(op, f, nrhs, a.reps, sampler, tol, method, ranks, total);
    }
    MPI_Finalize();
    return 0;
  }
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
