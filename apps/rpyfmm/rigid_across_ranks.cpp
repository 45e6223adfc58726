// rpyfmm CLI — `rpyfmm rigid` across MPI ranks (rigid_across_ranks.hpp).
#include "rigid_across_ranks.hpp"

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <iostream>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "body_io.hpp"
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

// This rank's whole bodies (body_io.hpp) and their forces and torques (6 per body).
struct LocalProblem {
  BodiesShare bodies;
  std::vector<double> forces_torques;
};

// Collective: the serial command's files and checks, each rank reading its bodies' rows (--io).
LocalProblem read_problem(const RanksRigidArgs& args, IoMode mode, const mpi::Communicator& comm) {
  LocalProblem p{read_bodies_share(args.bodies, mode, comm), {}};
  const std::size_t m = p.bodies.z.bodies();
  const auto check = [m](const std::vector<std::size_t>& shape) {
    require(values_of(shape) == 6 * m, ErrorCode::invalid_input, "--forces",
            "has " + std::to_string(values_of(shape)) + " entries, expected " + std::to_string(6 * m) +
                " (m x 6: F_x F_y F_z T_x T_y T_z per body)");
  };
  p.forces_torques =
      read_body_rows(args.forces, mode, 6, false, check, {}, p.bodies, p.bodies.scatter_seconds, comm).local;
  return p;
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
LocalSolution solve(Operator& beads, const RanksRigidArgs& args, const BeadBodies& local,
                    const std::vector<double>& forces_torques, Measured& measured) {
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
  s.report = bodies.apply(forces_torques, s.velocities, s.bead_forces);
  stages["solve"] = watch.seconds();
  measured.communication["setup"] = beads.communication().set_positions_seconds;
  measured.communication["products"] = beads.communication().applies_seconds;
  return s;
}

LocalSolution solve_across_ranks(const RanksRigidArgs& args, const LocalProblem& p, Measured& measured) {
  const BeadBodies& local = p.bodies.local;
  if (args.method == "fmm") {
    mpi::DistributedFmmRpy fmm(MPI_COMM_WORLD, args.viscosity, {.tolerance = args.tolerance});
    return solve(fmm, args, local, p.forces_torques, measured);
  }
  if (args.method == "pse") {  // PseRpy's options but the tolerance, as the serial command's PseRpy
    mpi::DistributedPseRpy pse(MPI_COMM_WORLD, args.box, args.viscosity, {.tolerance = args.tolerance});
    return solve(pse, args, local, p.forces_torques, measured);
  }
  mpi::DistributedDirectRpy direct(MPI_COMM_WORLD, args.viscosity);
  return solve(direct, args, local, p.forces_torques, measured);
}

// The velocities (m,6) and, with --bead-forces, the bead forces (N,3), checked first, written by
// every rank (--io collective) or by rank 0 after a gather (--io root), together (a failure leaves
// both targets as they were): the serial command's files.
void write_solution(const RanksRigidArgs& args, const LocalSolution& s, const BodyLayout& z, IoMode mode,
                    const mpi::Communicator& comm) {
  const NpyRun velocities{first_of_rows(z, 6, false, comm.rank()), s.velocities};
  const NpyRun bead_forces{first_of_rows(z, 3, true, comm.rank()), s.bead_forces};
  const bool beads = !args.bead_forces.empty();
  require_finite_result({&velocities, 1}, kCommand, comm);
  if (beads) require_finite_result({&bead_forces, 1}, "rigid (bead forces)", comm);
  std::vector<RowsFile> files{{args.out, {z.bodies(), 6}, {&velocities, 1}, body_shares(z, 6, false), 6 * z.bodies()}};
  if (beads)
    files.push_back({args.bead_forces, {z.beads(), 3}, {&bead_forces, 1}, body_shares(z, 3, true), 3 * z.beads()});
  write_rows_together(files, mode, comm);
}

void report_json(const RanksRigidArgs& args, const BodyLayout& z, const rpy::RigidBodyReport& report,
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
  IoMode mode = IoMode::collective;
  comm.run([&] { mode = io_mode(args.io); });
  const LocalProblem problem = read_problem(args, mode, comm);
  const double scattered = problem.bodies.scatter_seconds;
  stages["read"] = total.seconds() - scattered;
  measured.communication["distribute"] = stages["distribute"] = scattered;

  const LocalSolution solution = solve_across_ranks(args, problem, measured);

  StopWatch watch;
  write_solution(args, solution, problem.bodies.z, mode, comm);
  stages["write"] = watch.seconds();
  report_json(args, problem.bodies.z, solution.report, measured, total.seconds(), comm);
}

}  // namespace rpyfmm::cli
