// rpyfmm CLI — the commands that run across MPI ranks (mpi_session.hpp, docs/mpi.md):
//   mpirun -np P rpyfmm mobility --method direct|fmm [--torques T.npy | --angular] ...
//   mpirun -np P rpyfmm mobility --method pse --box L [--torques T.npy | --angular] ...
//   mpirun -np P rpyfmm sample --operator direct|fmm [--method lanczos|chebyshev]
//                              [--preconditioner none|block] [--angular] ...
//   mpirun -np P rpyfmm sample --operator pse --box L [--method split] [--angular] ...
//   mpirun -np P rpyfmm bd ...
// (`laplace`, `rigid` and `rigid-bd` run across the ranks too: laplace_across_ranks.hpp,
// rigid_across_ranks.hpp, rigid_bd_across_ranks.hpp.)
// Rank 0 reads the same files as the serial command and scatters the particles in P contiguous
// shares; rpyfmm::mpi::DistributedDirectRpy applies M (bit for bit the serial DirectRpy; with
// --torques or --angular to round-off, rpyfmm/mpi/direct_operator.hpp),
// rpyfmm::mpi::DistributedFmmRpy (within --tolerance of it) or rpyfmm::mpi::DistributedPseRpy (the
// serial PseRpy with double grids to round-off, with --torques or --angular too), and rpyfmm::mpi::sqrt_apply or
// DistributedPseRpy::apply_sqrt samples M^{1/2} z (with --angular the grand mobility's sampler,
// rpyfmm::mpi::sqrt_apply_rotation or DistributedPseRpy::apply_sqrt_rotation); rank 0 gathers the result and writes the
// same file (write_npy: a temporary file renamed into place). Every step fails on every rank alike
// (rpyfmm::mpi::Communicator::run), so no rank waits for another that gave up.
#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <iostream>
#include <memory>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "array_io.hpp"
#include "cli_common.hpp"
#include "mpi_session.hpp"
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

// The files a command reads on rank 0.
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

// What rank 0 reads: positions, radii (empty with a common radius), one row of three values per
// particle (forces, or noise; empty where none is read) and the torques (empty where none are read;
// with sample --angular the rotational noise z_r).
struct WholeInput {
  std::vector<double> x, radii, rows, torques;
};

// `name`'s rows of three values, one per particle of x.
std::vector<double> read_rows(const std::string& path, const std::string& name, const std::vector<double>& x) {
  std::vector<double> rows = as_points(read_array(path), name);
  require(rows.size() == x.size(), ErrorCode::invalid_input, name,
          "has " + std::to_string(rows.size() / 3) + " rows, expected " + std::to_string(x.size() / 3) +
              " (one per particle)");
  return rows;
}

// In the serial command's order: positions, forces (or noise), radii, torques.
WholeInput read_on_root(const Inputs& files) {
  WholeInput in;
  in.x = as_points(read_array(files.positions), "positions");
  const std::size_t n = in.x.size() / 3;
  if (files.rows_with_rotation && !files.rows.empty()) {
    std::tie(in.rows, in.torques) = as_split_rows6(read_array(files.rows), n, files.rows_name);
  } else if (!files.rows.empty()) {
    in.rows = read_rows(files.rows, files.rows_name, in.x);
  }
  if (!files.radii.empty()) in.radii = as_vector(read_array(files.radii), n, "radii");
  if (!files.torques.empty()) in.torques = read_rows(files.torques, "torques", in.x);
  return in;
}

// This rank's share of what rank 0 read.
struct LocalInput {
  std::uint64_t n = 0;     // particles in all
  std::size_t offset = 0;  // global index of this rank's first particle
  Shares s3;               // 3 values per particle
  std::vector<double> x, radii, rows, torques;
};

LocalInput distribute(const WholeInput& in, const Inputs& files, const mpi::Communicator& comm) {
  LocalInput local;
  local.n = in.x.size() / 3;
  mpi::check_mpi(MPI_Bcast(&local.n, 1, MPI_UINT64_T, 0, comm.get()), "MPI_Bcast");
  comm.run([&] { local.s3 = shares_of(local.n, comm.size(), 3); });
  const Shares s1 = shares_of(local.n, comm.size(), 1);
  local.offset = static_cast<std::size_t>(s1.displs[static_cast<std::size_t>(comm.rank())]);
  local.x = scatter(in.x.data(), local.s3, comm);
  if (!files.radii.empty()) local.radii = scatter(in.radii.data(), s1, comm);
  if (!files.rows.empty()) local.rows = scatter(in.rows.data(), local.s3, comm);
  if (files.reads_torques()) local.torques = scatter(in.torques.data(), local.s3, comm);
  return local;
}

// Gathers the result on rank 0, which checks and writes it: (N,3) rows of `local`, or with
// `local_angular` (not null on every rank) the serial command's (N,6) rows Ux Uy Uz Wx Wy Wz; fails
// on every rank alike. Returns the seconds this took (the "write" stage).
double gather_and_write(const std::vector<double>& local, const std::vector<double>* local_angular,
                        const LocalInput& in, const std::string& out, const std::string& what,
                        const mpi::Communicator& comm) {
  const StopWatch watch;
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
    std::vector<double> rows(6 * in.n);
    for (std::size_t i = 0; i < in.n; ++i)
      for (std::size_t c = 0; c < 3; ++c) {
        rows[6 * i + c] = whole[3 * i + c];
        rows[6 * i + 3 + c] = whole_angular[3 * i + c];
      }
    write_npy(out, {in.n, 6}, rows);
  });
  return watch.seconds();
}

// Read by rank 0, scattered, and the operator set up on each rank's share: what both commands do
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
Prepared<Operator> prepare(const Inputs& files, const mpi::Communicator& comm, Make&& make) {
  Prepared<Operator> p;
  StopWatch watch;
  WholeInput whole;
  comm.run([&] {
    if (comm.rank() == 0) whole = read_on_root(files);
  });
  p.stages["read"] = watch.seconds();

  watch.restart();
  p.in = distribute(whole, files, comm);
  whole = WholeInput{};  // rank 0 keeps only its share from here on
  p.communication["distribute"] = p.stages["distribute"] = watch.seconds();

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
};

// Prepares the operator `choice` selects ("fmm": DistributedFmmRpy, "pse": DistributedPseRpy in
// the --box, each at its tolerance; otherwise DistributedDirectRpy) and calls body(prepared).
template <class Body>
void with_operator(const OperatorChoice& choice, const Inputs& files, const mpi::Communicator& comm, Body&& body) {
  const double viscosity = choice.viscosity;
  if (choice.name == "fmm") {
    mpi::DistributedFmmRpyOptions options;
    if (choice.tolerance != 0.0) options.tolerance = choice.tolerance;
    auto p = prepare<mpi::DistributedFmmRpy>(
        files, comm, [&] { return std::make_unique<mpi::DistributedFmmRpy>(comm.get(), viscosity, options); });
    body(p);
  } else if (choice.name == "pse") {
    rpy::pse::PseOptions options;
    if (choice.tolerance != 0.0) options.tolerance = choice.tolerance;
    auto p = prepare<mpi::DistributedPseRpy>(files, comm, [&] {
      return std::make_unique<mpi::DistributedPseRpy>(comm.get(), periodic_box(choice.box), viscosity, options);
    });
    body(p);
  } else {
    auto p = prepare<mpi::DistributedDirectRpy>(
        files, comm, [&] { return std::make_unique<mpi::DistributedDirectRpy>(comm.get(), viscosity); });
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

  p.stages["write"] = gather_and_write(u, rotation ? &w : nullptr, in, args.out, "mobility", comm);

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
  with_operator({args.method, args.tolerance, args.viscosity, args.box}, files, comm,
                [&](auto& p) { apply_and_write(p, args, comm, total); });
}

namespace {

// M^{1/2} z across the ranks: the Lanczos sampler on the free-space operators, PSE's split sampler.
template <class Operator>
rpy::SqrtReport sample_across(const Operator& op, std::span<const double> z, std::span<double> w,
                              const rpy::SqrtOptions& options, double* inner_products) {
  return mpi::sqrt_apply(op, z, w, options, inner_products);
}
rpy::SqrtReport sample_across(const mpi::DistributedPseRpy& op, std::span<const double> z, std::span<double> w,
                              const rpy::SqrtOptions& options, double*) {
  return op.apply_sqrt(z, w, options);
}

// [w_t; w_r] = S^{-1} (S M S)^{1/2} [z_t; z_r], the grand mobility's sampler across the ranks
// (rpy::MobilityOperator::apply_sqrt_rotation's): Lanczos or Chebyshev on the free-space operators,
// PSE's split sampler.
template <class Operator>
rpy::SqrtReport sample_across(const Operator& op, std::span<const double> z_t, std::span<const double> z_r,
                              std::span<double> w_t, std::span<double> w_r, const rpy::SqrtOptions& options,
                              double* inner_products) {
  return mpi::sqrt_apply_rotation(op, z_t, z_r, w_t, w_r, options, inner_products);
}
rpy::SqrtReport sample_across(const mpi::DistributedPseRpy& op, std::span<const double> z_t,
                              std::span<const double> z_r, std::span<double> w_t, std::span<double> w_r,
                              const rpy::SqrtOptions& options, double*) {
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
  double inner_products = 0.0;
  const rpy::SqrtReport report = args.angular
                                     ? sample_across(*p.op, in.rows, in.torques, w, w_r, args.options, &inner_products)
                                     : sample_across(*p.op, in.rows, w, args.options, &inner_products);
  p.stages["sample"] = watch.seconds();
  p.communication["products"] = p.op->communication().applies_seconds;  // every product of the sampler
  p.communication["inner_products"] = inner_products;

  p.stages["write"] = gather_and_write(w, args.angular ? &w_r : nullptr, in, args.out, "sample", comm);

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
  with_operator({args.op, args.tolerance, args.viscosity, args.box}, files, comm,
                [&](auto& p) { sample_and_write(p, args, comm, total); });
}

bd::RunOptions bd_options_across_ranks(bd::RunOptions options) {
  return mpi::across_ranks(MPI_COMM_WORLD, std::move(options));
}

}  // namespace rpyfmm::cli
