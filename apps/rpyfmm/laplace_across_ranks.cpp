// rpyfmm CLI — `rpyfmm laplace` across MPI ranks, the FMM or direct sums (laplace_across_ranks.hpp).
#include "laplace_across_ranks.hpp"

#include <mpi.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <iostream>
#include <limits>
#include <optional>
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

// What every rank reads: the sizes, its shares, the output's shape and the seconds spent
// distributing rank 0's reads (scatters, broadcasts).
struct SharesRead {
  Sizes z;
  LocalShare local;
  std::vector<std::size_t> shape;
  double distribute_seconds = 0.0;
};

// This rank's share of every density of the charges (nd x share), with read_laplace_problem's
// checks and messages; sets z.nd and returns the layout.
ChargesLayout read_charges(const std::string& path, IoMode mode, SharesRead& r, const mpi::Communicator& comm) {
  const std::optional<NpyLayout> layout =
      mode == IoMode::collective ? shared_npy_layout(path, comm) : std::optional<NpyLayout>();
  Array whole;
  const std::vector<std::size_t> shape = layout ? layout->shape : read_whole_on_root(path, whole, comm);
  comm.run([&] {
    if (comm.rank() == 0) charges_layout(shape, r.z.n);
  });
  const ChargesLayout charges = charges_layout(shape, r.z.n);  // checked above: throws nowhere
  r.z.nd = charges.nd;
  const Shares s1 = shares_of(r.z.n, comm.size(), 1);
  const auto displ = static_cast<std::size_t>(s1.displs[static_cast<std::size_t>(comm.rank())]);
  for (std::size_t d = 0; d < charges.nd; ++d) {  // density by density: the serial check's order
    const std::size_t first = d * r.z.n + displ;
    StopWatch watch;
    const std::vector<double> part =
        layout ? read_values_at_all(path, *layout, first, s1.count(comm.rank()), comm)
               : scatter(comm.rank() == 0 ? whole.data.data() + d * r.z.n : nullptr, s1, comm);
    if (!layout) r.distribute_seconds += watch.seconds();
    require_finite_share(
        part, first, [&](std::size_t i, bool nan) { return nonfinite_charge(i, nan, charges, r.z.n); }, comm);
    r.local.charges.insert(r.local.charges.end(), part.begin(), part.end());
  }
  return charges;
}

// Every rank's shares of the sources, the targets and the charges, read and checked in the serial
// command's order with its messages (array_shares.hpp): with --io collective each rank reads its
// shares of the .npy files, with --io root rank 0 reads and scatters.
SharesRead read_shares(const RanksLaplaceArgs& args, const mpi::Communicator& comm) {
  const IoMode mode = io_mode(args.io);
  SharesRead r;
  ArrayShare sources = read_points_share(args.sources, "sources", mode, r.distribute_seconds, comm);
  r.z.n = r.z.m = values_of(sources.shape) / 3;
  r.local.sources = std::move(sources.local);
  if (!args.targets.empty()) {
    ArrayShare targets = read_points_share(args.targets, "targets", mode, r.distribute_seconds, comm);
    r.z.m = values_of(targets.shape) / 3;
    r.z.targets = true;
    r.local.targets = std::move(targets.local);
  }
  const ChargesLayout charges = read_charges(args.charges, mode, r, comm);
  r.shape = {r.z.m, fmm::result_width};
  if (charges.two_d) r.shape.insert(r.shape.begin(), r.z.nd);
  return r;
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

// --direct: rank 0 reads the serial command's files, broadcasts every source and charge, and
// scatters the targets (every rank needs every source and charge).
SharesRead read_for_direct(const RanksLaplaceArgs& args, const mpi::Communicator& comm) {
  LaplaceProblem whole;
  comm.run([&] {
    if (comm.rank() == 0) whole = read_laplace_problem(args.sources, args.targets, args.charges);
  });
  const StopWatch watch;
  SharesRead r;
  r.z = broadcast_sizes(whole, !args.targets.empty(), comm);
  comm.run([&] { r.local = distribute_for_direct(whole, r.z, comm); });
  r.shape = laplace_output_shape(whole);
  r.distribute_seconds = watch.seconds();
  return r;
}

// --direct with --io collective: every rank read its shares (read_shares), then gathers every
// source and every density's charges (MPI_Allgatherv, density by density) and sums at its share of
// the targets (of the sources when there are no targets): read_for_direct's shares, without rank 0
// holding any input whole.
SharesRead gathered_for_direct(SharesRead r, const mpi::Communicator& comm) {
  const StopWatch watch;
  if (!r.z.targets) r.local.targets = r.local.sources;
  const Shares s3 = shares_of(r.z.n, comm.size(), 3);  // read_shares checked these counts
  const Shares s1 = shares_of(r.z.n, comm.size(), 1);
  r.local.sources = all_gather(r.local.sources, s3, comm);
  const std::size_t share = s1.count(comm.rank());
  std::vector<double> charges;
  for (std::uint64_t d = 0; d < r.z.nd; ++d) {
    const auto begin = r.local.charges.begin() + static_cast<std::ptrdiff_t>(d * share);
    const std::vector<double> all = all_gather({begin, begin + static_cast<std::ptrdiff_t>(share)}, s1, comm);
    charges.insert(charges.end(), all.begin(), all.end());
  }
  r.local.charges = std::move(charges);
  r.distribute_seconds += watch.seconds();
  return r;
}

// What every rank reads: its shares for the FMM; for --direct every source and charge, by rank 0's
// reads and broadcasts (--io root) or by every rank's reads and gathers (--io collective).
SharesRead read_inputs(const RanksLaplaceArgs& args, const mpi::Communicator& comm) {
  if (!args.direct) return read_shares(args, comm);
  if (io_mode(args.io) == IoMode::root) return read_for_direct(args, comm);
  return gathered_for_direct(read_shares(args, comm), comm);
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
  SharesRead r = read_inputs(args, comm);
  measured.stages["read"] = watch.seconds() - r.distribute_seconds;
  measured.communication["distribute"] = measured.stages["distribute"] = r.distribute_seconds;
  const Sizes z = r.z;
  const LocalShare local = std::move(r.local);
  const std::vector<std::size_t> shape = std::move(r.shape);

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
