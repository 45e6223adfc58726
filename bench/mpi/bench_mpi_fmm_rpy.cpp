// One product U = M F of DistributedFmmRpy (rpyfmm/mpi/fmm_rpy.hpp, docs/mpi.md "Distributed
// FmmRpy") on P ranks beside the serial rpy::FmmRpy on the whole set, run under mpiexec by the
// launcher bench_mpi_ranks (bench/mpi/CMakeLists.txt) for bench/run.py's group "mpi-fmm-rpy".
//
// usage: bench_mpi_fmm_rpy --n N [--eps 1e-6] [--reps 3] [--phi 0.1]
//   N spheres of radius 1 uniform in a cube at volume fraction phi (bench_mpi_common.hpp's unit
//   cube scaled by its side), forces uniform in [-0.5, 0.5); every rank draws its contiguous share
//   of the global sequence, so the input does not depend on P beyond its size.
// Prints one JSON line (rank 0): the plan (set_positions) time and the median over reps of one
// apply after a first, each the slowest rank's after a barrier; of the last apply the slowest
// rank's seconds in the owners' serial Laplace FMM ("anterpolation" and "fmm" of
// DistributedLaplaceFmm's compute_seconds: far_s), in the exchanges (FmmRpyCommunication::
// apply_seconds: comm_s, its near field's share near_comm_s), in the near field's RPY blocks
// (near_sums_seconds: near_s) and in the rest of its apply (the O(n) charges and combination, the
// Laplace FMM's local assembly: other_s); the largest halo; then, on rank 0 alone with
// the other ranks asleep, the serial FmmRpy::apply on the whole set at the same eps (median over
// reps after a first: serial_s, its near field serial_near_s) and the relative l2 error of the
// distributed U against it (err_vs_serial; both lie within eps of the exact product, so at most
// 2 eps).
#include <mpi.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include "bench_mpi_common.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"

namespace {

using bench_mpi::max_over_ranks;

// The concatenation over the ranks of `mine` on rank 0 (empty elsewhere).
std::vector<double> gather_to_root(const std::vector<double>& mine, int rank, int ranks) {
  const int count = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<std::size_t>(ranks)), displs(static_cast<std::size_t>(ranks), 0);
  MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::vector<double> all;
  if (rank == 0) {
    for (std::size_t r = 1; r < counts.size(); ++r) displs[r] = displs[r - 1] + counts[r - 1];
    all.resize(static_cast<std::size_t>(displs.back() + counts.back()));
  }
  MPI_Gatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  return all;
}

// A barrier at which the ranks other than 0 wait without polling a core (the serial operator's
// timing on rank 0 shares the machine with them): a non-blocking barrier, tested every millisecond
// there and waited for on rank 0.
void barrier_asleep(int rank) {
  MPI_Request request = MPI_REQUEST_NULL;
  MPI_Ibarrier(MPI_COMM_WORLD, &request);
  if (rank == 0) {
    MPI_Wait(&request, MPI_STATUS_IGNORE);
    return;
  }
  int done = 0;
  while (done == 0) {
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

// The serial FmmRpy on the whole set on rank 0: the median over reps of one apply after a first,
// the median of its "rpy_near" stage and its velocities.
struct Serial {
  double seconds = 0.0, near_seconds = 0.0;
  std::vector<double> u;
};
Serial serial_fmm_rpy(const std::vector<double>& x, const std::vector<double>& f, double eps, int reps) {
  rpyfmm::rpy::FmmRpy op(rpyfmm::rpy::Geometry::open(), 1.0, {.tolerance = eps});
  op.set_positions(x, 1.0);
  Serial s;
  s.u.resize(f.size());
  op.apply(f, s.u);
  std::vector<double> times, near;
  for (int r = 0; r < reps; ++r) {
    rpyfmm::StopWatch timer;
    op.apply(f, s.u);
    times.push_back(timer.seconds());
    near.push_back(op.last_timings().at("rpy_near"));
  }
  s.seconds = bench_mpi::median(times);
  s.near_seconds = bench_mpi::median(near);
  return s;
}

double relative_l2(const std::vector<double>& u, const std::vector<double>& reference) {
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < u.size(); ++i) {
    num += (u[i] - reference[i]) * (u[i] - reference[i]);
    den += reference[i] * reference[i];
  }
  return std::sqrt(num / den);
}

}  // namespace

int main(int argc, char** argv) {
  const auto [rank, ranks] = bench_mpi::start(&argc, &argv);
  const bench_mpi::Args a = bench_mpi::parse(argc, argv);
  double phi = 0.1;
  for (int i = 1; i + 1 < argc; i += 2)
    if (std::string(argv[i]) == "--phi") phi = std::atof(argv[i + 1]);
  bench_mpi::Share s = bench_mpi::make_share(a, rank, ranks, 3);
  // Radius 1 at volume fraction phi: N (4/3) pi = phi side^3.
  const double side = std::cbrt(static_cast<double>(s.total) * 4.0 * std::numbers::pi / (3.0 * phi));
  for (double& v : s.x) v *= side;

  rpyfmm::mpi::DistributedFmmRpy op(MPI_COMM_WORLD, 1.0, {.tolerance = a.eps});
  const double plan_s = bench_mpi::median_seconds(1, [&] { op.set_positions(s.x, 1.0); });
  std::vector<double> u(s.q.size());
  op.apply(s.q, u);
  double mine_s = 0.0;
  const double eval_s = bench_mpi::median_seconds(a.reps, [&] {
    rpyfmm::StopWatch timer;
    op.apply(s.q, u);
    mine_s = timer.seconds();
  });
  // The stage split of the last apply, each the slowest rank's.
  const rpyfmm::StageTimes& work = op.laplace().communication().compute_seconds;
  const double far_mine = work.at("anterpolation") + work.at("fmm");
  const rpyfmm::mpi::FmmRpyCommunication& comm = op.communication();
  const double far_s = max_over_ranks(far_mine), comm_s = max_over_ranks(comm.apply_seconds);
  const double near_comm_s = max_over_ranks(comm.near_apply_seconds);
  const double near_s = max_over_ranks(comm.near_sums_seconds);
  const double other_s = max_over_ranks(mine_s - far_mine - comm.apply_seconds - comm.near_sums_seconds);
  const double halo_max = max_over_ranks(static_cast<double>(op.halo_size()));

  const std::vector<double> x_all = gather_to_root(s.x, rank, ranks), f_all = gather_to_root(s.q, rank, ranks);
  const std::vector<double> u_all = gather_to_root(u, rank, ranks);
  if (rank == 0) {
    const Serial serial = serial_fmm_rpy(x_all, f_all, a.eps, a.reps);
    std::printf(
        "{\"ranks\":%d,\"N\":%llu,\"eps\":%.3g,\"phi\":%.3g,\"plan_s\":%.6g,\"eval_s\":%.6g,\"far_s\":%.6g,"
        "\"near_s\":%.6g,\"other_s\":%.6g,\"comm_s\":%.6g,\"near_comm_s\":%.6g,\"halo_max\":%.0f,\"serial_s\":%.6g,"
        "\"serial_near_s\":%.6g,\"err_vs_serial\":%.3g}\n",
        ranks, static_cast<unsigned long long>(s.total), a.eps, phi, plan_s, eval_s, far_s, near_s, other_s, comm_s,
        near_comm_s, halo_max, serial.seconds, serial.near_seconds, relative_l2(u_all, serial.u));
    std::fflush(stdout);
  }
  barrier_asleep(rank);
  MPI_Finalize();
  return 0;
}
