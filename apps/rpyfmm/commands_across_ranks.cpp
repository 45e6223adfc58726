// rpyfmm CLI — the commands that run across MPI ranks (mpi_session.hpp, docs/mpi.md):
//   mpirun -np P rpyfmm mobility --method direct ...
//   mpirun -np P rpyfmm mobility --method pse --box L ...
//   mpirun -np P rpyfmm sample --operator direct [--method lanczos] ...
//   mpirun -np P rpyfmm sample --operator pse --box L [--method split] ...
// Rank 0 reads the same files as the serial command and scatters the particles in P contiguous
// shares; rpyfmm::mpi::DistributedDirectRpy applies M (bit for bit the serial DirectRpy), or
// rpyfmm::mpi::DistributedPseRpy (the serial PseRpy with double grids to round-off), and
// rpyfmm::mpi::sqrt_apply or DistributedPseRpy::apply_sqrt samples M^{1/2} z; rank 0 gathers the result and writes the
// same file (write_npy: a temporary file renamed into place). Every step fails on every rank alike
// (rpyfmm::mpi::Communicator::run), so no rank waits for another that gave up.
#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <iostream>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "array_io.hpp"
#include "cli_common.hpp"
#include "mpi_session.hpp"
#include "rank_shares.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "sqrt_report_json.hpp"

namespace rpyfmm::cli {
namespace {

// What rank 0 reads: positions, radii (empty with a common radius) and one row of three values per
// particle (forces, or noise; empty where none is read).
struct WholeInput {
  std::vector<double> x, radii, rows;
};

WholeInput read_on_root(const std::string& positions, const std::string& radii, const std::string& rows,
                        const std::string& rows_name) {
  WholeInput in;
  in.x = as_points(read_array(positions), "positions");
  const std::size_t n = in.x.size() / 3;
  if (!rows.empty()) {
    in.rows = as_points(read_array(rows), rows_name);
    require(
        in.rows.size() == in.x.size(), ErrorCode::invalid_input, rows_name,
        "has " + std::to_string(in.rows.size() / 3) + " rows, expected " + std::to_string(n) + " (one per particle)");
  }
  if (!radii.empty()) in.radii = as_vector(read_array(radii), n, "radii");
  return in;
}

// This rank's share of what rank 0 read.
struct LocalInput {
  std::uint64_t n = 0;     // particles in all
  std::size_t offset = 0;  // global index of this rank's first particle
  Shares s3;               // 3 values per particle
  std::vector<double> x, radii, rows;
};

LocalInput distribute(const WholeInput& in, bool radii, bool rows, const mpi::Communicator& comm) {
  LocalInput local;
  local.n = in.x.size() / 3;
  mpi::check_mpi(MPI_Bcast(&local.n, 1, MPI_UINT64_T, 0, comm.get()), "MPI_Bcast");
  comm.run([&] { local.s3 = shares_of(local.n, comm.size(), 3); });
  const Shares s1 = shares_of(local.n, comm.size(), 1);
  local.offset = static_cast<std::size_t>(s1.displs[static_cast<std::size_t>(comm.rank())]);
  local.x = scatter(in.x.data(), local.s3, comm);
  if (radii) local.radii = scatter(in.radii.data(), s1, comm);
  if (rows) local.rows = scatter(in.rows.data(), local.s3, comm);
  return local;
}

// Gathers the (N,3) result on rank 0, which checks and writes it; fails on every rank alike.
// Returns the seconds this took (the "write" stage).
double gather_and_write(const std::vector<double>& local, const LocalInput& in, const std::string& out,
                        const std::string& what, const mpi::Communicator& comm) {
  const StopWatch watch;
  std::vector<double> whole(comm.rank() == 0 ? 3 * in.n : 0);
  gather(local, in.s3, whole.data(), comm);
  comm.run([&] {
    if (comm.rank() != 0) return;
    require_finite_output(whole, what);
    write_npy(out, {in.n, 3}, whole);
  });
  return watch.seconds();
}

// Read by rank 0 and scattered, timed per stage.
struct Distributed {
  LocalInput in;
  StageTimes stages, communication;
};

// Distributed, and the direct operator set up on each rank's share: what both commands with the
// direct operator do first.
struct Prepared {
  LocalInput in;
  std::unique_ptr<mpi::DistributedDirectRpy> op;
  StageTimes stages, communication;
};

struct Inputs {
  const std::string& positions;
  const std::string& radii;  // empty with a common radius
  const std::string& rows;   // forces or noise; empty where none is read
  const char* rows_name;
  double radius;
  double viscosity;
};

Distributed read_and_distribute(const Inputs& files, const mpi::Communicator& comm) {
  Distributed p;
  StopWatch watch;
  WholeInput whole;
  comm.run([&] {
    if (comm.rank() == 0) whole = read_on_root(files.positions, files.radii, files.rows, files.rows_name);
  });
  p.stages["read"] = watch.seconds();

  watch.restart();
  p.in = distribute(whole, !files.radii.empty(), !files.rows.empty(), comm);
  whole = WholeInput{};  // rank 0 keeps only its share from here on
  p.communication["distribute"] = p.stages["distribute"] = watch.seconds();
  return p;
}

Prepared prepare(const Inputs& files, const mpi::Communicator& comm) {
  Distributed d = read_and_distribute(files, comm);
  Prepared p{std::move(d.in), nullptr, std::move(d.stages), std::move(d.communication)};
  StopWatch watch;
  p.op = std::make_unique<mpi::DistributedDirectRpy>(comm.get(), files.viscosity);
  if (files.radii.empty()) {
    p.op->set_positions(p.in.x, files.radius);
  } else {
    p.op->set_positions(p.in.x, p.in.radii);
  }
  p.stages["setup"] = watch.seconds();
  p.communication["setup"] = p.op->communication().set_positions_seconds;
  return p;
}

// What both commands add to --json under MPI: the ranks and the slowest rank's times.
void add_ranks(JsonLine& line, const StageTimes& stages, const StageTimes& communication,
               const mpi::Communicator& comm) {
  line.add("ranks", comm.size())
      .add("threads", active_threads())
      .add("simd", simd_level_name(simd_level()))
      .add("seconds", slowest(stages, comm))
      .add("communication_seconds", slowest(communication, comm));
}

// The start of sample's --json line, as the serial command's (its operator, sampler and noise).
JsonLine sample_json(const RanksSampleArgs& args, const char* op, const rpy::SqrtReport& report, std::uint64_t n) {
  JsonLine line;
  line.add("command", "sample")
      .add("operator", op)
      .add("method", rpy::to_string(report.method))
      .add("n", n)
      .add("sqrt_tolerance", args.options.tolerance);
  add_sqrt_report(line, report);
  line.add("angular", false).add("noise", args.noise.empty() ? "philox" : args.noise).add("viscosity", args.viscosity);
  return line;
}

// The PSE operator across the ranks on their shares (Inputs: the radius unless --radii was read),
// set up as the serial command sets up PseRpy; the time in the "setup" stage.
struct PseSetup {
  const std::vector<double>& box;  // --box: L or Lx Ly Lz
  double tolerance;                // the operator's (PseOptions::tolerance)
  bool radius_given;
  double radius;
  double viscosity;
};

std::unique_ptr<mpi::DistributedPseRpy> pse_on_shares(const PseSetup& setup, const LocalInput& in, StageTimes& stages,
                                                      const mpi::Communicator& comm) {
  StopWatch watch;
  require(setup.box.size() == 1 || setup.box.size() == 3, ErrorCode::invalid_argument, "--box",
          "give one length L (cube) or three lengths Lx Ly Lz, got " + std::to_string(setup.box.size()) + " values");
  const rpy::Geometry box = setup.box.size() == 1 ? rpy::Geometry::periodic(setup.box[0])
                                                  : rpy::Geometry::periodic(setup.box[0], setup.box[1], setup.box[2]);
  rpy::pse::PseOptions options;
  options.tolerance = setup.tolerance;
  auto op = std::make_unique<mpi::DistributedPseRpy>(comm.get(), box, setup.viscosity, options);
  if (setup.radius_given) {
    op->set_positions(in.x, setup.radius);
  } else {
    op->set_positions(in.x, in.radii);
  }
  stages["setup"] = watch.seconds();
  return op;
}

// `mobility --method pse --box ...`: rpyfmm::mpi::DistributedPseRpy on each rank's share (equal to
// the serial PseRpy with double-precision grids to round-off).
void run_pse_mobility_across_ranks(const RanksMobilityArgs& args, const mpi::Communicator& comm) {
  StopWatch total;
  Distributed d = read_and_distribute({args.positions, args.radius_given ? std::string() : args.radii, args.forces,
                                       "forces", args.radius, args.viscosity},
                                      comm);
  const LocalInput& in = d.in;
  const auto op =
      pse_on_shares({args.box, args.tolerance, args.radius_given, args.radius, args.viscosity}, in, d.stages, comm);
  StopWatch watch;
  std::vector<double> u(in.x.size());
  op->apply(in.rows, u);
  d.stages["apply"] = watch.seconds();
  d.stages["write"] = gather_and_write(u, in, args.out, "mobility", comm);

  JsonLine line;
  line.add("command", "mobility")
      .add("method", "pse")
      .add("n", in.n)
      .add("viscosity", args.viscosity)
      .add("tolerance", args.tolerance)
      .add("wave_precision", "double")
      .add("out", args.out);
  if (args.radius_given) line.add("radius", args.radius);
  add_ranks(line, d.stages, d.communication, comm);  // collective
  if (args.json && comm.rank() == 0) std::cout << line.add("total_seconds", total.seconds()).str() << '\n';
}

// `sample --operator pse --box ...` (the split sampler): DistributedPseRpy::apply_sqrt on each rank's
// share of the noise, read by rank 0 or drawn as the serial command draws it (stream 0 by global
// index); equal to the serial PseRpy::apply_sqrt with double grids to round-off.
void run_pse_sample_across_ranks(const RanksSampleArgs& args, const mpi::Communicator& comm) {
  StopWatch total;
  Distributed d = read_and_distribute({args.positions, args.radius_given ? std::string() : args.radii, args.noise,
                                       "noise", args.radius, args.viscosity},
                                      comm);
  LocalInput& in = d.in;
  const double tolerance = args.tolerance != 0.0 ? args.tolerance : rpy::pse::PseOptions{}.tolerance;
  const auto op =
      pse_on_shares({args.box, tolerance, args.radius_given, args.radius, args.viscosity}, in, d.stages, comm);
  if (args.noise.empty()) {  // the serial command's noise of this rank's particles
    in.rows.resize(in.x.size());
    mpi::fill_normal(in.rows, in.offset, args.seed, args.step);
  }
  StopWatch watch;
  std::vector<double> w(in.x.size());
  const rpy::SqrtReport report = op->apply_sqrt(in.rows, w, args.options);
  d.stages["sample"] = watch.seconds();
  d.stages["write"] = gather_and_write(w, in, args.out, "sample", comm);

  JsonLine line = sample_json(args, "pse", report, in.n);
  line.add("tolerance", tolerance).add("wave_precision", "double").add("out", args.out);
  if (args.noise.empty()) line.add("seed", args.seed).add("step", args.step);
  if (args.radius_given) line.add("radius", args.radius);
  add_ranks(line, d.stages, d.communication, comm);  // collective
  if (args.json && comm.rank() == 0) std::cout << line.add("total_seconds", total.seconds()).str() << '\n';
}

}  // namespace

void run_mobility_across_ranks(const RanksMobilityArgs& args) {
  const mpi::Communicator comm(MPI_COMM_WORLD);
  if (args.method == "pse") {
    run_pse_mobility_across_ranks(args, comm);
    return;
  }
  StopWatch total;
  Prepared p = prepare({args.positions, args.radius_given ? std::string() : args.radii, args.forces, "forces",
                        args.radius, args.viscosity},
                       comm);
  const LocalInput& in = p.in;
  mpi::DistributedDirectRpy& op = *p.op;
  StageTimes& stages = p.stages;
  StageTimes& communication = p.communication;

  StopWatch watch;
  std::vector<double> u(in.x.size());
  op.apply(in.rows, u);
  stages["apply"] = watch.seconds();
  communication["apply"] = op.communication().apply_seconds;

  stages["write"] = gather_and_write(u, in, args.out, "mobility", comm);

  JsonLine line;
  line.add("command", "mobility")
      .add("method", "direct")
      .add("n", in.n)
      .add("viscosity", args.viscosity)
      .add("tolerance", args.tolerance)
      .add("equal_radii", op.equal_radii())
      .add("out", args.out);
  if (args.radius_given) line.add("radius", args.radius);
  add_ranks(line, stages, communication, comm);  // collective
  if (args.json && comm.rank() == 0) std::cout << line.add("total_seconds", total.seconds()).str() << '\n';
}

void run_sample_across_ranks(const RanksSampleArgs& args) {
  const mpi::Communicator comm(MPI_COMM_WORLD);
  if (args.op == "pse") {
    run_pse_sample_across_ranks(args, comm);
    return;
  }
  StopWatch total;
  Prepared p = prepare({args.positions, args.radius_given ? std::string() : args.radii, args.noise, "noise",
                        args.radius, args.viscosity},
                       comm);
  LocalInput& in = p.in;
  const mpi::DistributedDirectRpy& op = *p.op;
  StageTimes& stages = p.stages;
  StageTimes& communication = p.communication;
  if (args.noise.empty()) {  // the serial command's noise of this rank's particles
    in.rows.resize(in.x.size());
    mpi::fill_normal(in.rows, in.offset, args.seed, args.step);
  }

  StopWatch watch;
  std::vector<double> w(in.x.size());
  double inner_products = 0.0;
  const rpy::SqrtReport report = mpi::sqrt_apply(op, in.rows, w, args.options, &inner_products);
  stages["sample"] = watch.seconds();
  communication["products"] = op.communication().applies_seconds;
  communication["inner_products"] = inner_products;

  stages["write"] = gather_and_write(w, in, args.out, "sample", comm);

  JsonLine line = sample_json(args, "direct", report, in.n);
  line.add("equal_radii", op.equal_radii()).add("out", args.out);
  if (args.noise.empty()) line.add("seed", args.seed).add("step", args.step);
  if (args.radius_given) line.add("radius", args.radius);
  add_ranks(line, stages, communication, comm);  // collective
  if (args.json && comm.rank() == 0) std::cout << line.add("total_seconds", total.seconds()).str() << '\n';
}

}  // namespace rpyfmm::cli
