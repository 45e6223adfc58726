// rpyfmm CLI — `rpyfmm laplace` across MPI ranks, the FMM or direct sums (laplace_across_ranks.hpp).
#include "laplace_across_ranks.hpp"

#include <mpi.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <iostream>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "array_shares.hpp"
#include "cli_common.hpp"
#include "laplace_problem.hpp"
#include "npy_collective_io.hpp"
#include "rank_shares.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"

namespace rpyfmm::cli {
namespace {

// The sizes rank 0 read, known to every rank after one broadcast.
struct Sizes {
  std::uint64_t n = 0, m = 0, nd = 1;
  bool targets = false;
};

Sizes broadcast_sizes(const LaplaceProblem& whole, bool targets, const mpi::Communicator& comm) {
  std::array<std::uint64_t, 4> v = {whole.n, whole.m, whole.nd, targets ? 1U : 0U};
  mpi::check_mpi(MPI_Bcast(v.data(), static_cast<int>(v.size()), MPI_UINT64_T, 0, comm.get()), "MPI_Bcast");
  return {v[0], v[1], v[2], v[3] != 0};
}

// This rank's share: its sources, its targets (empty at the sources) and its charges, nd x share.
// With --direct: every source and charge, and this rank's targets (its share of the sources when
// the targets are the sources).
struct LocalShare {
  std::vector<double> sources, targets, charges;
};

// nd densities of n entries each on rank 0 to this rank's share of each, nd x share.
std::vector<double> scatter_densities(const std::vector<double>& whole, const Sizes& z, const mpi::Communicator& comm) {
  const Shares s1 = shares_of(z.n, comm.size(), 1);
  std::vector<double> local;
  local.reserve(z.nd * s1.count(comm.rank()));
  for (std::uint64_t d = 0; d < z.nd; ++d) {
    const std::vector<double> share = scatter(comm.rank() == 0 ? whole.data() + d * z.n : nullptr, s1, comm);
    local.insert(local.end(), share.begin(), share.end());
  }
  return local;
}

LocalShare distribute(const LaplaceProblem& whole, const Sizes& z, const mpi::Communicator& comm) {
  LocalShare local;
  local.sources = scatter(whole.sources.data(), shares_of(z.n, comm.size(), 3), comm);
  if (z.targets) local.targets = scatter(whole.targets.data(), shares_of(z.m, comm.size(), 3), comm);
  local.charges = scatter_densities(whole.charges, z, comm);
  return local;
}

// `count` values of rank 0's `whole` on every rank (one MPI_Bcast; MPI's int count bounds it).
std::vector<double> broadcast(const std::vector<double>& whole, std::uint64_t count, const mpi::Communicator& comm) {
  require(count <= static_cast<std::uint64_t>(std::numeric_limits<int>::max()), ErrorCode::not_supported, "laplace",
          "--direct across ranks broadcasts every source and charge: " + std::to_string(count) +
              " values exceed MPI's int count");
  std::vector<double> all = comm.rank() == 0 ? whole : std::vector<double>(count);
  mpi::check_mpi(MPI_Bcast(all.data(), static_cast<int>(count), MPI_DOUBLE, 0, comm.get()), "MPI_Bcast");
  return all;
}

LocalShare distribute_for_direct(const LaplaceProblem& whole, const Sizes& z, const mpi::Communicator& comm) {
  LocalShare local;
  local.sources = broadcast(whole.sources, 3 * z.n, comm);
  local.charges = broadcast(whole.charges, z.nd * z.n, comm);
  local.targets = z.targets ? scatter(whole.targets.data(), shares_of(z.m, comm.size(), 3), comm)
                            : scatter(whole.sources.data(), shares_of(z.n, comm.size(), 3), comm);
  return local;
}

// Every density's results (nd x share x 10) gathered into nd x M x 10 on rank 0.
std::vector<double> gather_results(const std::vector<double>& local, const Sizes& z, const mpi::Communicator& comm) {
  const Shares s10 = shares_of(z.m, comm.size(), static_cast<int>(fmm::result_width));
  const std::size_t share = s10.count(comm.rank());
  std::vector<double> whole(comm.rank() == 0 ? z.nd * z.m * fmm::result_width : 0);
  for (std::uint64_t d = 0; d < z.nd; ++d) {
    const std::vector<double> part(local.begin() + static_cast<std::ptrdiff_t>(d * share),
                                   local.begin() + static_cast<std::ptrdiff_t>((d + 1) * share));
    gather(part, s10, comm.rank() == 0 ? whole.data() + d * z.m * fmm::result_width : nullptr, comm);
  }
  return whole;
}

// Rank 0 gathers every density's results, checks them and writes the serial command's file.
void gather_and_write(const std::vector<double>& local, const Sizes& z, const std::vector<std::size_t>& shape,
                      const std::string& out, const mpi::Communicator& comm) {
  std::vector<double> gathered;
  comm.run([&] { gathered = gather_results(local, z, comm); });
  comm.run([&] {
    if (comm.rank() != 0) return;
    require_finite_output(gathered, "laplace");
    write_npy(out, shape, gathered);
  });
}

// Every rank checks its results (nd x share x 10) and writes them, one run per density, into the
// same file (write_npy_at_all): the file and the messages of gather_and_write.
void write_at_all(const std::vector<double>& local, const Sizes& z, const std::vector<std::size_t>& shape,
                  const std::string& out, const mpi::Communicator& comm) {
  const Shares s10 = shares_of(z.m, comm.size(), static_cast<int>(fmm::result_width));
  const std::size_t share = s10.count(comm.rank());
  const auto first = static_cast<std::size_t>(s10.displs[static_cast<std::size_t>(comm.rank())]);
  std::vector<NpyRun> runs;
  for (std::uint64_t d = 0; d < z.nd; ++d) {
    const NpyRun run{d * z.m * fmm::result_width + first, std::span<const double>(local).subspan(d * share, share)};
    // Density by density: the first non-finite entry of the whole file, as the serial check finds it.
    require_finite_share(
        run.values, run.first, [](std::size_t i, bool nan) { return nonfinite_output(i, nan, "laplace"); }, comm);
    runs.push_back(run);
  }
  write_npy_at_all(out, shape, runs, comm);
}

double sum_of(const StageTimes& stages) {
  double total = 0.0;
  for (const auto& [stage, seconds] : stages) total += seconds;
  return total;
}

// The times and volumes that --json reports, this rank's.
struct Measured {
  StageTimes stages, communication, bytes;
};

void add_ranks(JsonLine& line, const Measured& m, const mpi::Communicator& comm) {
  line.add("ranks", comm.size())
      .add("threads", active_threads())
      .add("simd", simd_level_name(simd_level()))
      .add("seconds", slowest(m.stages, comm))
      .add("communication_seconds", slowest(m.communication, comm))
      .add("communication_bytes", summed(m.bytes, comm));
}

// The FMM across the ranks on this rank's share: its results, nd x share x 10.
std::vector<double> evaluate_fmm(const LocalShare& local, const Sizes& z, double tolerance, Measured& measured,
                                 const mpi::Communicator& comm) {
  StopWatch watch;
  mpi::DistributedFmmOptions options;
  options.fmm.tolerance = tolerance;
  mpi::DistributedLaplaceFmm fmm(comm.get(), options);
  fmm.set_points(local.sources, local.targets);
  measured.stages["plan"] = watch.seconds();

  watch.restart();
  std::vector<double> results(z.nd * fmm.local_target_size() * fmm::result_width);
  fmm.evaluate(local.charges, z.nd, fmm::all_outputs, results);
  measured.stages["evaluate"] = watch.seconds();
  const mpi::FmmCommunication& traffic = fmm.communication();
  measured.communication["plan"] = sum_of(traffic.plan_seconds);
  measured.communication["evaluate"] = sum_of(traffic.evaluate_seconds);
  measured.bytes["plan"] = static_cast<double>(traffic.plan_bytes_received);
  measured.bytes["evaluate"] = static_cast<double>(traffic.evaluate_bytes_received);
  return results;
}

// The direct sums over every source at this rank's targets, nd x share x 10: each target's sums are
// the serial command's, in the same order (fmm::laplace_direct sums every target alone). A rank
// without targets has nothing to sum. Failures (none expected: rank 0 validated the input) agreed.
std::vector<double> evaluate_direct(const LocalShare& local, const Sizes& z, Measured& measured,
                                    const mpi::Communicator& comm) {
  StopWatch watch;
  const std::size_t share = local.targets.size() / 3;
  std::vector<double> results(z.nd * share * fmm::result_width);
  comm.run([&] {
    if (share > 0) fmm::laplace_direct(local.sources, local.charges, z.nd, local.targets, fmm::all_outputs, results);
  });
  measured.stages["evaluate"] = watch.seconds();
  return results;
}

}  // namespace

void run_laplace_across_ranks(const RanksLaplaceArgs& args) {
  const mpi::Communicator comm(MPI_COMM_WORLD);
  StopWatch total;
  StopWatch watch;
  Measured measured;
  LaplaceProblem whole;
  comm.run([&] {
    if (comm.rank() == 0) whole = read_laplace_problem(args.sources, args.targets, args.charges);
  });
  measured.stages["read"] = watch.seconds();

  watch.restart();
  const Sizes z = broadcast_sizes(whole, !args.targets.empty(), comm);
  LocalShare local;
  comm.run([&] { local = args.direct ? distribute_for_direct(whole, z, comm) : distribute(whole, z, comm); });
  const std::vector<std::size_t> shape = laplace_output_shape(whole);
  whole = LaplaceProblem{};  // rank 0 keeps only what it evaluates from here on
  measured.communication["distribute"] = measured.stages["distribute"] = watch.seconds();

  const std::vector<double> results =
      args.direct ? evaluate_direct(local, z, measured, comm) : evaluate_fmm(local, z, args.tolerance, measured, comm);

  watch.restart();
  if (io_mode(args.io) == IoMode::root) {
    gather_and_write(results, z, shape, args.out, comm);
  } else {
    write_at_all(results, z, shape, args.out, comm);
  }
  measured.stages["write"] = watch.seconds();

  JsonLine line;
  line.add("command", "laplace")
      .add("method", args.direct ? "direct" : "fmm")
      .add("n_sources", z.n)
      .add("n_targets", z.m)
      .add("at_sources", !z.targets)
      .add("nd", z.nd)
      .add("out", args.out)
      .add("pairs", static_cast<double>(z.n) * static_cast<double>(z.m) * static_cast<double>(z.nd));
  if (!args.direct) line.add("tolerance", args.tolerance);
  add_ranks(line, measured, comm);  // collective
  if (args.json && comm.rank() == 0) std::cout << line.add("total_seconds", total.seconds()).str() << '\n';
}

}  // namespace rpyfmm::cli
