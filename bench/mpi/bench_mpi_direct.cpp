// Scaling benchmark of DistributedDirectRpy (rpyfmm/mpi/direct_operator.hpp, docs/mpi.md "Scaling
// and a performance model"): one product U = M F, exact O(N^2), run under mpiexec by
// bench_mpi_ranks (bench/mpi/CMakeLists.txt) for bench/run.py's group "mpi".
//
// usage: bench_mpi_direct --n N [--scaling strong|weak] [--reps 3]
//   (bench_mpi_common.hpp: strong = N in all, weak = N per rank; uniform in the unit cube, radius
//   0.001, forces in [-0.5, 0.5)).
// Prints one JSON line (rank 0) with the columns of bench_mpi_fmm that apply: "plan_s" =
// set_positions, "eval_s" = the median over reps of one apply, each the slowest rank's; the
// slowest rank's time in MPI calls of the last apply and the bytes all ranks received in it.
#include <mpi.h>

#include <cstdio>
#include <vector>

#include "bench_mpi_common.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"

int main(int argc, char** argv) {
  const auto [rank, ranks] = bench_mpi::start(&argc, &argv);
  const bench_mpi::Args a = bench_mpi::parse(argc, argv);
  const bench_mpi::Share s = bench_mpi::make_share(a, rank, ranks, 3);

  rpyfmm::mpi::DistributedDirectRpy op(MPI_COMM_WORLD, 1.0);
  const double plan_s = bench_mpi::median_seconds(1, [&] { op.set_positions(s.x, 0.001); });
  std::vector<double> u(s.x.size());
  const double eval_s = bench_mpi::median_seconds(a.reps, [&] { op.apply(s.q, u); });
  const double comm_s = bench_mpi::max_over_ranks(op.communication().apply_seconds);
  const double mb = bench_mpi::sum_over_ranks(static_cast<double>(op.communication().apply_bytes_received)) / 1e6;
  if (rank == 0)
    std::printf(
        "{\"method\":\"direct\",\"scaling\":\"%s\",\"ranks\":%d,\"N\":%llu,\"plan_s\":%.6g,\"eval_s\":%.6g,"
        "\"eval_comm_s\":%.6g,\"eval_MB\":%.6g}\n",
        a.scaling.c_str(), ranks, static_cast<unsigned long long>(s.total), plan_s, eval_s, comm_s, mb);
  MPI_Finalize();
  return 0;
}
