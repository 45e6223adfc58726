// rpyfmm CLI — the commands that run across MPI ranks (mpi_session.hpp, docs/mpi.md):
//   mpirun -np P rpyfmm mobility --method direct|fmm [--torques T.npy | --angular] ...
//   mpirun -np P rpyfmm mobility --method pse --box L [--torques T.npy | --angular] ...
//   mpirun -np P rpyfmm sample --operator direct|fmm [--method lanczos|chebyshev]
//                              [--preconditioner none|block] [--angular] ...
//   mpirun -np P rpyfmm sample --operator pse --box L [--method split] [--angular] ...
//   mpirun -np P rpyfmm bd ...
// (`laplace`, `rigid` and `rigid-bd` run across the ranks too: laplace_across_ranks.hpp,
// rigid_across_ranks.hpp, rigid_bd_across_ranks.hpp.)
// The ranks read the same files as the serial command in P contiguous shares of the particles
// (array_shares.hpp: with --io collective every rank reads its share of a .npy file with MPI-IO,
// with --io root rank 0 reads and scatters); rpyfmm::mpi::DistributedDirectRpy applies M (bit for
// bit the serial DirectRpy; with --torques or --angular to round-off,
// rpyfmm/mpi/direct_operator.hpp), rpyfmm::mpi::DistributedFmmRpy (within --tolerance of it) or
// rpyfmm::mpi::DistributedPseRpy (the serial PseRpy with double grids to round-off, with --torques
// or --angular too), and rpyfmm::mpi::sqrt_apply or DistributedPseRpy::apply_sqrt samples
// M^{1/2} z (with --angular the grand mobility's sampler, rpyfmm::mpi::sqrt_apply_rotation or
// DistributedPseRpy::apply_sqrt_rotation); the ranks write the serial command's file (with --io
// collective every rank its rows, npy_collective_io.hpp; with --io root rank 0 gathers and calls
// write_npy; either way a temporary file renamed into place). Every step fails on every rank alike
// (rpyfmm::mpi::Communicator::run), so no rank waits for another that gave up.
#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <iostream>
#include <memory>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "array_io.hpp"
#include "array_shares.hpp"
#include "cli_common.hpp"
#include "mpi_session.hpp"
#include "npy_collective_io.hpp"
#include "rank_shares.hpp"
#include "rpyfmm/bd/rotation_sampling.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/bd_stepper.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "sqrt_report_json.hpp"

namespace rpyfmm::cli {
namespace {

// The files a command reads.
struct Inputs {
  const std::string& positions;
  const std::string& radii;  // empty with a common radius
  const std::string& rows;   // forces or noise; empty where none is read
  const char* rows_name;
  double radius;
  const std::string& torques;       // empty where none is read
  bool rows_with_rotation = false;  // rows of six: the rows' triple, then the torques' (sample --angular's noise)

  // Whether a torques' triple (or z_r) per particle is read.
  [[nodiscard]] bool reads_torques() const { return !torques.empty() || (rows_with_rotation && !rows.empty()); }
};

// This rank's share of the inputs.
struct LocalInput {
  std::uint64_t n = 0;     // particles in all
  std::size_t offset = 0;  // global index of this rank's first particle
  Shares s3;               // 3 values per particle
  std::vector<double> x, radii, rows, torques;
  double scatter_seconds = 0.0;  // in MPI_Scatterv (rank 0's reads)
};

// `name`'s rows of three values, one per particle of `n`: as_points' checks, then the count.
std::vector<double> read_rows(const std::string& path, const std::string& name, std::uint64_t n, IoMode mode,
                              LocalInput& in, const mpi::Communicator& comm) {
  ArrayShare rows = read_points_share(path, name, mode, in.scatter_seconds, comm);
  const std::size_t got = values_of(rows.shape) / 3;
  comm.run([&] {
    require(got == n, ErrorCode::invalid_input, name,
            "has " + std::to_string(got) + " rows, expected " + std::to_string(n) + " (one per particle)");
  });
  return std::move(rows.local);
}

// The positions, and the particles' shares they set.
void read_positions(const std::string& path, IoMode mode, LocalInput& in, const mpi::Communicator& comm) {
  ArrayShare x = read_points_share(path, "positions", mode, in.scatter_seconds, comm);
  in.n = values_of(x.shape) / 3;
  in.s3 = shares_of(in.n, comm.size(), 3);  // within the int counts: read_share made these shares
  in.offset = x.first / 3;
  in.x = std::move(x.local);
}

// (N,6) rows, each a forces' (or z_t's) triple then a torques' (or z_r's): as_split_rows6's checks.
void read_rows6(const std::string& path, const std::string& name, IoMode mode, LocalInput& in,
                const mpi::Communicator& comm) {
  const std::size_t n = in.n;
  ArrayShare rows = read_share(
      path, mode, 6, [&](const auto& shape) { require_rows6_shape(shape, n, name); }, in.scatter_seconds, comm);
  require_finite_share(
      rows.local, rows.first,
      [&](std::size_t i, bool nan) {
        return Error(ErrorCode::invalid_input, name + ": " + name + " " + nonfinite_entry(i, 6, nan));
      },
      comm);
  std::tie(in.rows, in.torques) = split_rows6(rows.local);
}

// Every rank's share of the files, read and checked in the serial command's order (positions,
// forces or noise, radii, torques) with its messages.
LocalInput read_inputs(const Inputs& files, IoMode mode, const mpi::Communicator& comm) {
  LocalInput in;
  read_positions(files.positions, mode, in, comm);
  if (files.rows_with_rotation && !files.rows.empty()) {
    read_rows6(files.rows, files.rows_name, mode, in, comm);
  } else if (!files.rows.empty()) {
    in.rows = read_rows(files.rows, files.rows_name, in.n, mode, in, comm);
  }
  if (!files.radii.empty()) {
    const std::size_t n = in.n;
    ArrayShare radii = read_share(
        files.radii, mode, 1, [&](const auto& shape) { require_vector_shape(shape, n, "radii"); }, in.scatter_seconds,
        comm);
    require_finite_share(
        radii.local, radii.first,
        [](std::size_t i, bool nan) { return Error(ErrorCode::invalid_input, "radii " + nonfinite_entry(i, 1, nan)); },
        comm);
    in.radii = std::move(radii.local);
  }
  if (!files.torques.empty()) in.torques = read_rows(files.torques, "torques", in.n, mode, in, comm);
  return in;
}

// The serial command's (N,6) rows: each particle's triple of `u`, then its triple of `w`.
std::vector<double> rows6_of(const std::vector<double>& u, const std::vector<double>& w) {
  std::vector<double> rows(2 * u.size());
  for (std::size_t i = 0; i < u.size() / 3; ++i)
    for (std::size_t c = 0; c < 3; ++c) {
      rows[6 * i + c] = u[3 * i + c];
      rows[6 * i + 3 + c] = w[3 * i + c];
    }
  return rows;
}

// Gathers the result on rank 0, which checks and writes it: (N,3) rows of `local`, or with
// `local_angular` (not null on every rank) the serial command's (N,6) rows Ux Uy Uz Wx Wy Wz; fails
// on every rank alike.
void gather_and_write(const std::vector<double>& local, const std::vector<double>* local_angular, const LocalInput& in,
                      const std::string& out, const std::string& what, const mpi::Communicator& comm) {
  const bool angular = local_angular != nullptr;
  std::vector<double> whole(comm.rank() == 0 ? 3 * in.n : 0);
  std::vector<double> whole_angular(comm.rank() == 0 && angular ? 3 * in.n : 0);
  gather(local, in.s3, whole.data(), comm);
  if (angular) gather(*local_angular, in.s3, whole_angular.data(), comm);
  comm.run([&] {
    if (comm.rank() != 0) return;
    require_finite_output(whole, what);
    if (!angular) {
      write_npy(out, {in.n, 3}, whole);
      return;
    }
    require_finite_output(whole_angular, what);
    write_npy(out, {in.n, 6}, rows6_of(whole, whole_angular));
  });
}

// Every rank checks and writes its share of the result into the file at once (write_npy_at_all):
// the file and the messages of gather_and_write.
void write_at_all(const std::vector<double>& local, const std::vector<double>* local_angular, const LocalInput& in,
                  const std::string& out, const std::string& what, const mpi::Communicator& comm) {
  const auto output_error = [&](std::size_t i, bool nan) { return nonfinite_output(i, nan, what); };
  require_finite_share(local, 3 * in.offset, output_error, comm);
  if (local_angular == nullptr) {
    write_npy_at_all(out, {in.n, 3}, local, 3 * in.offset, comm);
    return;
  }
  require_finite_share(*local_angular, 3 * in.offset, output_error, comm);
  write_npy_at_all(out, {in.n, 6}, rows6_of(local, *local_angular), 6 * in.offset, comm);
}

// The result written by `mode`'s writer; returns the seconds this took (the "write" stage).
double write_result(const std::vector<double>& local, const std::vector<double>* local_angular, const LocalInput& in,
                    const std::string& out, const std::string& what, IoMode mode, const mpi::Communicator& comm) {
  const StopWatch watch;
  if (mode == IoMode::root) {
    gather_and_write(local, local_angular, in, out, what, comm);
  } else {
    write_at_all(local, local_angular, in, out, what, comm);
  }
  return watch.seconds();
}

// Read into each rank's share, and the operator set up on it: what both commands do
// first, timed per stage.
template <class Operator>
struct Prepared {
  LocalInput in;
  std::unique_ptr<Operator> op;
  StageTimes stages, communication;
};

// What --json says of the radii: equal_radii for the free-space operators (nothing for PSE, whose
// serial command does not report it).
void add_radii(JsonLine& line, const mpi::DistributedDirectRpy& op) {
  line.add("equal_radii", op.equal_radii());
}
void add_radii(JsonLine& line, const mpi::DistributedFmmRpy& op) {
  line.add("equal_radii", op.equal_radii());
}
void add_radii(JsonLine& line, const mpi::DistributedPseRpy&) {
  line.add("wave_precision", "double");
}

// --box: L (a cube) or Lx Ly Lz.
rpy::Geometry periodic_box(const std::vector<double>& box) {
  require(box.size() == 1 || box.size() == 3, ErrorCode::invalid_argument, "--box",
          "give one length L (cube) or three lengths Lx Ly Lz, got " + std::to_string(box.size()) + " values");
  return box.size() == 1 ? rpy::Geometry::periodic(box[0]) : rpy::Geometry::periodic(box[0], box[1], box[2]);
}

// `make()` constructs the operator (collective).
template <class Operator, class Make>
Prepared<Operator> prepare(const Inputs& files, IoMode mode, const mpi::Communicator& comm, Make&& make) {
  Prepared<Operator> p;
  StopWatch watch;
  p.in = read_inputs(files, mode, comm);
  p.stages["read"] = watch.seconds() - p.in.scatter_seconds;
  p.communication["distribute"] = p.stages["distribute"] = p.in.scatter_seconds;

  watch.restart();
  p.op = make();
  if (files.radii.empty()) {
    p.op->set_positions(p.in.x, files.radius);
  } else {
    p.op->set_positions(p.in.x, p.in.radii);
  }
  p.stages["setup"] = watch.seconds();
  p.communication["setup"] = p.op->communication().set_positions_seconds;
  return p;
}

// The operator a command names: "direct", "fmm" or "pse" (with its --box), its tolerance (0: the
// operator's default) and the viscosity.
struct OperatorChoice {
  const std::string& name;
  double tolerance;
  double viscosity;
  const std::vector<double>& box;
  IoMode io;  // who reads the inputs and writes the result
};

// Prepares the operator `choice` selects ("fmm": DistributedFmmRpy, "pse": DistributedPseRpy in
// the --box, each at its tolerance; otherwise DistributedDirectRpy) and calls body(prepared).
template <class Body>
void with_operator(const OperatorChoice& choice, const Inputs& files, const mpi::Communicator& comm, Body&& body) {
  const double viscosity = choice.viscosity;
  if (choice.name == "fmm") {
    mpi::DistributedFmmRpyOptions options;
    if (choice.tolerance != 0.0) options.tolerance = choice.tolerance;
    auto p = prepare<mpi::DistributedFmmRpy>(files, choice.io, comm, [&] {
      return std::make_unique<mpi::DistributedFmmRpy>(comm.get(), viscosity, options);
    });
    body(p);
  } else if (choice.name == "pse") {
    rpy::pse::PseOptions options;
    if (choice.tolerance != 0.0) options.tolerance = choice.tolerance;
    auto p = prepare<mpi::DistributedPseRpy>(files, choice.io, comm, [&] {
      return std::make_unique<mpi::DistributedPseRpy>(comm.get(), periodic_box(choice.box), viscosity, options);
    });
    body(p);
  } else {
    auto p = prepare<mpi::DistributedDirectRpy>(
        files, choice.io, comm, [&] { return std::make_unique<mpi::DistributedDirectRpy>(comm.get(), viscosity); });
    body(p);
  }
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

}  // namespace

namespace {

// U = M F, or with `rotation` [U; W] = M [F; T], on this rank's share (collective: every rank
// passes the same `rotation`, whatever its share's size).
template <class Operator>
void product(const Operator& op, bool rotation, const LocalInput& in, std::vector<double>& u, std::vector<double>& w) {
  if (rotation) {
    op.apply(in.rows, in.torques, u, w);
  } else {
    op.apply(in.rows, u);
  }
}

// U = M F with the prepared operator, or with rotation [U; W] = M [F; T] (T = 0 with --angular alone);
// rank 0 writes U, or U and W, and prints --json.
template <class Operator>
void apply_and_write(Prepared<Operator>& p, const RanksMobilityArgs& args, const mpi::Communicator& comm,
                     const StopWatch& total) {
  LocalInput& in = p.in;
  const bool rotation = args.angular || !args.torques.empty();
  if (rotation && args.torques.empty()) in.torques.assign(in.x.size(), 0.0);
  StopWatch watch;
  std::vector<double> u(in.x.size()), w(rotation ? in.x.size() : 0);
  product(*p.op, rotation, in, u, w);
  p.stages["apply"] = watch.seconds();
  p.communication["apply"] = p.op->communication().apply_seconds;

  p.stages["write"] = write_result(u, rotation ? &w : nullptr, in, args.out, "mobility", io_mode(args.io), comm);

  JsonLine line;
  line.add("command", "mobility")
      .add("method", args.method)
      .add("n", in.n)
      .add("viscosity", args.viscosity)
      .add("tolerance", args.tolerance);
  add_radii(line, *p.op);
  line.add("out", args.out);
  if (args.radius_given) line.add("radius", args.radius);
  add_ranks(line, p.stages, p.communication, comm);  // collective
  if (args.json && comm.rank() == 0) std::cout << line.add("total_seconds", total.seconds()).str() << '\n';
}

}  // namespace

void run_mobility_across_ranks(const RanksMobilityArgs& args) {
  const mpi::Communicator comm(MPI_COMM_WORLD);
  const StopWatch total;
  const Inputs files{args.positions, args.radius_given ? std::string() : args.radii, args.forces, "forces", args.radius,
                     args.torques};
  with_operator({args.method, args.tolerance, args.viscosity, args.box, io_mode(args.io)}, files, comm,
                [&](auto& p) { apply_and_write(p, args, comm, total); });
}

namespace {

// M^{1/2} z across the ranks: the Lanczos sampler on the free-space operators, PSE's split sampler.
template <class Operator>
rpy::SqrtReport sample_across(const Operator& op, std::span<const double> z, std::span<double> w,
                              const rpy::SqrtOptions& options, mpi::InnerProductStats& stats) {
  return mpi::sqrt_apply(op, z, w, 1, options, &stats);  // one column: the same bits (rpyfmm/mpi/sqrt.hpp)
}
rpy::SqrtReport sample_across(const mpi::DistributedPseRpy& op, std::span<const double> z, std::span<double> w,
                              const rpy::SqrtOptions& options, mpi::InnerProductStats&) {
  return op.apply_sqrt(z, w, options);
}

// [w_t; w_r] = S^{-1} (S M S)^{1/2} [z_t; z_r], the grand mobility's sampler across the ranks
// (rpy::MobilityOperator::apply_sqrt_rotation's): Lanczos or Chebyshev on the free-space operators,
// PSE's split sampler.
template <class Operator>
rpy::SqrtReport sample_across(const Operator& op, std::span<const double> z_t, std::span<const double> z_r,
                              std::span<double> w_t, std::span<double> w_r, const rpy::SqrtOptions& options,
                              mpi::InnerProductStats& stats) {
  return mpi::sqrt_apply_rotation(op, z_t, z_r, w_t, w_r, options, stats);
}
rpy::SqrtReport sample_across(const mpi::DistributedPseRpy& op, std::span<const double> z_t,
                              std::span<const double> z_r, std::span<double> w_t, std::span<double> w_r,
                              const rpy::SqrtOptions& options, mpi::InnerProductStats&) {
  return op.apply_sqrt_rotation(z_t, z_r, w_t, w_r, options);
}

// W = M^{1/2} Z with the prepared operator (with --angular [W_t; W_r] of the grand mobility); rank 0
// writes W and prints --json.
template <class Operator>
void sample_and_write(Prepared<Operator>& p, const RanksSampleArgs& args, const mpi::Communicator& comm,
                      const StopWatch& total) {
  LocalInput& in = p.in;
  if (args.noise.empty()) {  // the serial command's noise of this rank's particles
    in.rows.resize(in.x.size());
    mpi::fill_normal(in.rows, in.offset, args.seed, args.step);
    if (args.angular) {  // z_r: BD's rotational stream, as the serial command draws it
      in.torques.resize(in.x.size());
      mpi::fill_normal(in.torques, in.offset, args.seed, args.step, bd::kRotationNoiseStream);
    }
  }

  StopWatch watch;
  std::vector<double> w(in.x.size()), w_r(args.angular ? in.x.size() : 0);
  mpi::InnerProductStats stats;
  const rpy::SqrtReport report = args.angular ? sample_across(*p.op, in.rows, in.torques, w, w_r, args.options, stats)
                                              : sample_across(*p.op, in.rows, w, args.options, stats);
  p.stages["sample"] = watch.seconds();
  p.communication["products"] = p.op->communication().applies_seconds;  // every product of the sampler
  p.communication["inner_products"] = stats.seconds;
  // The block preconditioner's gather of the positions (0 where its blocks were kept) and its
  // G, G^T, G^{-1} exchanges; 0 without it.
  p.communication["blocks"] = stats.blocks.gather_seconds + stats.blocks.exchange_seconds();

  p.stages["write"] = write_result(w, args.angular ? &w_r : nullptr, in, args.out, "sample", io_mode(args.io), comm);

  JsonLine line;
  line.add("command", "sample")
      .add("operator", args.op)
      .add("method", rpy::to_string(report.method))
      .add("n", in.n)
      .add("sqrt_tolerance", args.options.tolerance);
  add_sqrt_report(line, report);
  line.add("angular", args.angular)
      .add("noise", args.noise.empty() ? "philox" : args.noise)
      .add("viscosity", args.viscosity);
  add_radii(line, *p.op);
  line.add("out", args.out);
  if (args.noise.empty()) line.add("seed", args.seed).add("step", args.step);
  add_chebyshev_bounds(line, report);
  if (args.radius_given) line.add("radius", args.radius);
  if (args.op != "direct") line.add("tolerance", args.tolerance);
  add_ranks(line, p.stages, p.communication, comm);  // collective
  if (args.json && comm.rank() == 0) std::cout << line.add("total_seconds", total.seconds()).str() << '\n';
}

}  // namespace

void run_sample_across_ranks(const RanksSampleArgs& given) {
  // The operator's tolerance where none was given: its options' default (reported by --json).
  RanksSampleArgs args = given;
  if (args.tolerance == 0.0)
    args.tolerance = args.op == "pse" ? rpy::pse::PseOptions{}.tolerance : mpi::DistributedFmmRpyOptions{}.tolerance;
  const mpi::Communicator comm(MPI_COMM_WORLD);
  const StopWatch total;
  const Inputs files{
      args.positions, args.radius_given ? std::string() : args.radii, args.noise, "noise", args.radius, std::string(),
      args.angular};
  with_operator({args.op, args.tolerance, args.viscosity, args.box, io_mode(args.io)}, files, comm,
                [&](auto& p) { sample_and_write(p, args, comm, total); });
}

bd::RunOptions bd_options_across_ranks(bd::RunOptions options) {
  return mpi::across_ranks(MPI_COMM_WORLD, std::move(options));
}

}  // namespace rpyfmm::cli
