// rpyfmm CLI — `rpyfmm rigid` across MPI ranks (rigid_across_ranks.hpp).
#include "rigid_across_ranks.hpp"

#include <mpi.h>

#include <climits>
#include <cstddef>
#include <cstdint>
#include <iostream>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "body_shares.hpp"
#include "cli_common.hpp"
#include "rank_shares.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/mpi/rigid_bodies.hpp"

namespace rpyfmm::cli {
namespace {

constexpr const char* kCommand = "rigid";

// What rank 0 read: the bodies and their forces and torques (6 per body).
struct WholeProblem {
  BeadBodies bodies;
  std::vector<double> forces_torques;
};

WholeProblem read_problem(const RanksRigidArgs& args) {
  WholeProblem p{read_bead_bodies(args.bodies), read_array(args.forces).data};
  const std::size_t m = p.bodies.bodies();
  require(p.forces_torques.size() == 6 * m, ErrorCode::invalid_input, "--forces",
          "has " + std::to_string(p.forces_torques.size()) + " entries, expected " + std::to_string(6 * m) +
              " (m x 6: F_x F_y F_z T_x T_y T_z per body)");
  require(3 * p.bodies.beads() <= static_cast<std::size_t>(INT_MAX) && 6 * m <= static_cast<std::size_t>(INT_MAX),
          ErrorCode::not_supported, kCommand,
          std::to_string(p.bodies.beads()) + " beads: more than MPI's int counts address in one scatter");
  return p;
}

// Collective: rank 0 reads the files (the other ranks hold nothing); a failure fails every rank.
WholeProblem read_on_rank_zero(const RanksRigidArgs& args, const mpi::Communicator& comm) {
  WholeProblem whole;
  comm.run([&] {
    if (comm.rank() == 0) whole = read_problem(args);
  });
  return whole;
}

// The bodies' layout (body_shares.hpp) and whether reference points were given, after rank 0's
// broadcasts.
struct Layout : BodyLayout {
  bool reference = false;
};

Layout broadcast_layout(const WholeProblem& whole, const mpi::Communicator& comm) {
  Layout z;
  static_cast<BodyLayout&>(z) = broadcast_body_layout(whole.bodies.offsets, comm);
  int reference = comm.rank() == 0 && !whole.bodies.reference.empty() ? 1 : 0;
  mpi::check_mpi(MPI_Bcast(&reference, 1, MPI_INT, 0, comm.get()), "MPI_Bcast");
  z.reference = reference != 0;
  return z;
}

// This rank's whole bodies: beads, radii, body offsets from 0, forces and torques, reference
// points (empty when none were given).
struct LocalProblem {
  std::vector<double> x, radii, forces_torques, reference;
  std::vector<std::size_t> offsets;
};

LocalProblem distribute(const WholeProblem& whole, const Layout& z, const mpi::Communicator& comm) {
  const BeadBodies& b = whole.bodies;
  LocalProblem local;
  local.x = scatter(b.x.data(), body_shares(z, 3, true), comm);
  local.radii = scatter(b.radii.data(), body_shares(z, 1, true), comm);
  local.forces_torques = scatter(whole.forces_torques.data(), body_shares(z, 6, false), comm);
  if (z.reference) local.reference = scatter(b.reference.data(), body_shares(z, 3, false), comm);
  local.offsets = local_body_offsets(z, comm.rank());
  return local;
}

// This rank's velocities (6 per body), bead forces (3 per bead, or none) and the solver's report.
struct LocalSolution {
  std::vector<double> velocities, bead_forces;
  rpy::RigidBodyReport report;
};

// Stage times and this rank's time in MPI calls per stage (setup: the bead operator's planning,
// products: its exchanges over every product of the solve), as --json reports them.
struct Measured {
  StageTimes stages, communication;
};

template <class Operator>
LocalSolution solve(Operator& beads, const RanksRigidArgs& args, const LocalProblem& local, Measured& measured) {
  StageTimes& stages = measured.stages;
  StopWatch watch;
  mpi::DistributedRigidBodies bodies(
      beads,
      {.tolerance = args.solver_tolerance, .max_iterations = args.max_iterations, .precondition = args.precondition});
  bodies.set_configuration(local.x, local.radii, local.offsets, local.reference);
  stages["setup"] = watch.seconds();
  watch.restart();
  LocalSolution s;
  s.velocities.resize(6 * bodies.local_bodies());
  s.bead_forces.resize(args.bead_forces.empty() ? 0 : local.x.size());
  s.report = bodies.apply(local.forces_torques, s.velocities, s.bead_forces);
  stages["solve"] = watch.seconds();
  measured.communication["setup"] = beads.communication().set_positions_seconds;
  measured.communication["products"] = beads.communication().applies_seconds;
  return s;
}

LocalSolution solve_across_ranks(const RanksRigidArgs& args, const LocalProblem& local, Measured& measured) {
  if (args.method == "fmm") {
    mpi::DistributedFmmRpy fmm(MPI_COMM_WORLD, args.viscosity, {.tolerance = args.tolerance});
    return solve(fmm, args, local, measured);
  }
  if (args.method == "pse") {  // PseRpy's options but the tolerance, as the serial command's PseRpy
    mpi::DistributedPseRpy pse(MPI_COMM_WORLD, args.box, args.viscosity, {.tolerance = args.tolerance});
    return solve(pse, args, local, measured);
  }
  mpi::DistributedDirectRpy direct(MPI_COMM_WORLD, args.viscosity);
  return solve(direct, args, local, measured);
}

// Rank 0 gathers the rows (`per` values per body or per bead) and writes them as (rows, per).
void gather_and_write(const std::string& path, const std::vector<double>& local, const Layout& z, int per,
                      bool by_beads, const mpi::Communicator& comm) {
  const std::uint64_t rows = by_beads ? z.beads() : z.bodies();
  std::vector<double> whole(comm.rank() == 0 ? rows * static_cast<std::uint64_t>(per) : 0);
  comm.run([&] { gather(local, body_shares(z, per, by_beads), whole.data(), comm); });
  comm.run([&] {
    if (comm.rank() != 0) return;
    require_finite_output(whole, kCommand);
    write_npy(path, {rows, static_cast<std::size_t>(per)}, whole);
  });
}

void report_json(const RanksRigidArgs& args, const Layout& z, const rpy::RigidBodyReport& report,
                 const Measured& measured, double total_seconds, const mpi::Communicator& comm) {
  const StageTimes slowest_stages = slowest(measured.stages, comm);  // collective
  const StageTimes slowest_communication = slowest(measured.communication, comm);
  if (!args.json || comm.rank() != 0) return;
  JsonLine line;
  line.add("command", "rigid")
      .add("method", args.method)
      .add("bodies", z.bodies())
      .add("beads", z.beads())
      .add("viscosity", args.viscosity)
      .add("tolerance", args.tolerance)
      .add("solver_tolerance", args.solver_tolerance)
      .add("preconditioned", args.precondition)
      .add("iterations", report.iterations)
      .add("restarts", report.restarts)
      .add("residual", report.residual)
      .add("ranks", comm.size())
      .add("threads", active_threads())
      .add("simd", simd_level_name(simd_level()))
      .add("out", args.out)
      .add("seconds", slowest_stages)
      .add("communication_seconds", slowest_communication)
      .add("total_seconds", total_seconds);
  std::cout << line.str() << '\n';
}

}  // namespace

void run_rigid_across_ranks(const RanksRigidArgs& args) {
  const mpi::Communicator comm(MPI_COMM_WORLD);
  StopWatch total;
  Measured measured;
  StageTimes& stages = measured.stages;
  WholeProblem whole = read_on_rank_zero(args, comm);
  stages["read"] = total.seconds();
  StopWatch watch;

  const Layout z = broadcast_layout(whole, comm);
  LocalProblem local;
  comm.run([&] { local = distribute(whole, z, comm); });
  whole = WholeProblem{};  // rank 0 keeps only its own bodies from here on
  measured.communication["distribute"] = stages["distribute"] = watch.seconds();

  const LocalSolution solution = solve_across_ranks(args, local, measured);

  watch.restart();
  gather_and_write(args.out, solution.velocities, z, 6, false, comm);
  if (!args.bead_forces.empty()) gather_and_write(args.bead_forces, solution.bead_forces, z, 3, true, comm);
  stages["write"] = watch.seconds();
  report_json(args, z, solution.report, measured, total.seconds(), comm);
}

}  // namespace rpyfmm::cli
