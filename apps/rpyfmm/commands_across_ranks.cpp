// rpyfmm CLI — `mpirun -np P rpyfmm mobility --method direct ...` (mpi_session.hpp, docs/mpi.md):
// rank 0 reads the same files as the serial command and scatters the particles in P contiguous
// shares, rpyfmm::mpi::DistributedDirectRpy applies M (bit for bit the serial DirectRpy), rank 0
// gathers U and writes the same file (write_npy: a temporary file renamed into place). Every
// step fails on every rank alike (rpyfmm::mpi::Communicator::run), so no rank waits for another
// that gave up.
#include <mpi.h>

#include <algorithm>
#include <climits>
#include <cstddef>
#include <cstdint>
#include <iostream>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "cli_common.hpp"
#include "mpi_session.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"

namespace rpyfmm::cli {
namespace {

// What rank 0 reads: the whole set.
struct WholeInput {
  std::vector<double> x, f, radii;
};

WholeInput read_on_root(const RanksMobilityArgs& args) {
  WholeInput in;
  in.x = as_points(read_array(args.positions), "positions");
  const std::size_t n = in.x.size() / 3;
  in.f = as_points(read_array(args.forces), "forces");
  require(in.f.size() == in.x.size(), ErrorCode::invalid_input, "forces",
          "has " + std::to_string(in.f.size() / 3) + " rows, expected " + std::to_string(n) + " (one per particle)");
  if (!args.radius_given) in.radii = as_vector(read_array(args.radii), n, "radii");
  require(3 * n <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, "mobility",
          std::to_string(n) + " particles: more than MPI's int counts address in one scatter");
  return in;
}

// N particles in P contiguous shares, the remainder on the lowest ranks, in entries of `per`
// values per particle: counts and displacements for MPI_Scatterv / MPI_Gatherv.
struct Shares {
  std::vector<int> counts, displs;
};

Shares shares_of(std::size_t n, int ranks, int per) {
  Shares s;
  int offset = 0;
  for (int r = 0; r < ranks; ++r) {
    const auto share = static_cast<int>(n / static_cast<std::size_t>(ranks) +
                                        (static_cast<std::size_t>(r) < n % static_cast<std::size_t>(ranks) ? 1 : 0));
    s.counts.push_back(per * share);
    s.displs.push_back(offset);
    offset += per * share;
  }
  return s;
}

std::vector<double> scatter(const std::vector<double>& whole, const Shares& s, const mpi::Communicator& comm) {
  std::vector<double> local(static_cast<std::size_t>(s.counts[static_cast<std::size_t>(comm.rank())]));
  mpi::check_mpi(MPI_Scatterv(whole.data(), s.counts.data(), s.displs.data(), MPI_DOUBLE, local.data(),
                              static_cast<int>(local.size()), MPI_DOUBLE, 0, comm.get()),
                 "MPI_Scatterv");
  return local;
}

// The slowest rank's time of each stage, on rank 0.
StageTimes slowest(const StageTimes& mine, const mpi::Communicator& comm) {
  std::vector<double> local, global;
  for (const auto& [stage, seconds] : mine) local.push_back(seconds);
  global.resize(local.size());
  mpi::check_mpi(
      MPI_Reduce(local.data(), global.data(), static_cast<int>(local.size()), MPI_DOUBLE, MPI_MAX, 0, comm.get()),
      "MPI_Reduce");
  StageTimes out;
  std::size_t i = 0;
  for (const auto& [stage, seconds] : mine) out[stage] = global[i++];
  return out;
}

}  // namespace

void run_mobility_across_ranks(const RanksMobilityArgs& args) {
  const mpi::Communicator comm(MPI_COMM_WORLD);
  const bool root = comm.rank() == 0;
  StopWatch total;
  StopWatch watch;
  WholeInput in;
  comm.run([&] {
    if (root) in = read_on_root(args);
  });
  StageTimes stages, communication;
  stages["read"] = watch.seconds();

  watch.restart();
  std::uint64_t n = in.x.size() / 3;
  mpi::check_mpi(MPI_Bcast(&n, 1, MPI_UINT64_T, 0, comm.get()), "MPI_Bcast");
  const Shares s3 = shares_of(n, comm.size(), 3), s1 = shares_of(n, comm.size(), 1);
  const std::vector<double> x = scatter(in.x, s3, comm), f = scatter(in.f, s3, comm);
  const std::vector<double> radii = args.radius_given ? std::vector<double>{} : scatter(in.radii, s1, comm);
  in = WholeInput{};  // rank 0 keeps only its share from here on
  communication["distribute"] = stages["distribute"] = watch.seconds();

  watch.restart();
  mpi::DistributedDirectRpy op(comm.get(), args.viscosity);
  if (args.radius_given) {
    op.set_positions(x, args.radius);
  } else {
    op.set_positions(x, radii);
  }
  stages["setup"] = watch.seconds();
  communication["setup"] = op.communication().set_positions_seconds;

  watch.restart();
  std::vector<double> u(x.size());
  op.apply(f, u);
  stages["apply"] = watch.seconds();
  communication["apply"] = op.communication().apply_seconds;

  watch.restart();
  std::vector<double> whole(root ? 3 * n : 0);
  mpi::check_mpi(MPI_Gatherv(u.data(), static_cast<int>(u.size()), MPI_DOUBLE, whole.data(), s3.counts.data(),
                             s3.displs.data(), MPI_DOUBLE, 0, comm.get()),
                 "MPI_Gatherv");
  communication["collect"] = watch.seconds();
  comm.run([&] {
    if (!root) return;
    require_finite_output(whole, "mobility");
    write_npy(args.out, {n, 3}, whole);
  });
  stages["write"] = watch.seconds();

  const StageTimes slowest_stages = slowest(stages, comm), slowest_communication = slowest(communication, comm);
  if (args.json && root) {
    JsonLine line;
    line.add("command", "mobility")
        .add("method", "direct")
        .add("n", n)
        .add("ranks", comm.size())
        .add("viscosity", args.viscosity)
        .add("tolerance", args.tolerance)
        .add("equal_radii", op.equal_radii())
        .add("threads", active_threads())
        .add("simd", simd_level_name(simd_level()))
        .add("out", args.out)
        .add("seconds", slowest_stages)
        .add("communication_seconds", slowest_communication)
        .add("total_seconds", total.seconds());
    if (args.radius_given) line.add("radius", args.radius);
    std::cout << line.str() << '\n';
  }
}

}  // namespace rpyfmm::cli
