// rpyfmm CLI — `rpyfmm rigid`: linear and angular velocities of rigid bodies made of beads
// (bead-shell models) under forces and torques, with hydrodynamic interactions among all beads
// (rpyfmm/rpy/rigid_bodies.hpp).
//
//   rpyfmm rigid --positions X.npy (--radius a | --radii R.npy) --body-sizes S.txt
//                --forces FT.npy [--reference Q.npy] [--solver-tolerance 1e-6] [--max-iterations 500]
//                [--no-precondition] [--method direct|fmm|pse|auto] [--tolerance 1e-6] [--viscosity 1]
//                [--box L | --box Lx Ly Lz] --out UW.npy [--bead-forces L.npy] [--threads N] [--json]
//                [--io collective|root]
//
// Beads are listed body after body; S holds the m body sizes (beads per body, each >= 3).
// FT is (m,6): F_x F_y F_z T_x T_y T_z per body (torques about the reference points Q, (m,3),
// default the bodies' centroids); UW is (m,6): U_x U_y U_z Omega_x Omega_y Omega_z.
// Under mpirun, --method direct and fmm (free space) and --method pse with --box (double-precision
// wave grids) run across the ranks, each rank owning whole bodies and reading and writing their
// rows of the .npy files (--io collective, the default) or rank 0 all of them (--io root)
// (rigid_across_ranks.hpp); other
// methods are refused on more than one rank.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "bead_bodies.hpp"
#include "cli_common.hpp"
#include "commands.hpp"
#include "mobility_choice.hpp"
#include "mpi_session.hpp"
#include "rigid_across_ranks.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

namespace rpyfmm::cli {
namespace {

struct RigidArgs {
  BeadBodyArgs bodies;
  std::string forces, out, bead_forces;
  double solver_tolerance = 1e-6;  // GMRES relative residual
  int max_iterations = 500;
  bool no_precondition = false;
  MobilityChoice mobility;
  CommonOptions common;
  std::string io = "collective";  // --io, across MPI ranks
};

/// Under MPI: whether this solve runs across the ranks (on the CPU: --method direct or fmm without
/// --box, or --method pse with --box and wave grids auto or double); otherwise it runs on one rank
/// only and more ranks are refused. Every rank parses the same options, so every rank refuses alike.
bool across_ranks(const RigidArgs& args) {
  return bodies_across_ranks(args.mobility, mpi_size(), "rigid");
}

void run_rigid(const RigidArgs& args) {
  const BeadBodyArgs& b = args.bodies;
  require_distinct_files(std::vector<NamedPath>{{"--positions", b.positions},
                                                {"--radii", b.radii},
                                                {"--body-sizes", b.body_sizes},
                                                {"--reference", b.reference},
                                                {"--forces", args.forces}},
                         std::vector<NamedPath>{{"--out", args.out}, {"--bead-forces", args.bead_forces}});
  apply_threads(args.common);
  ranges::require_in(ranges::kSolverTolerance, args.solver_tolerance, "--solver-tolerance", "tolerance");
  if (under_mpi() && across_ranks(args)) {
    run_rigid_across_ranks({args.bodies, args.forces, args.out, args.bead_forces, args.solver_tolerance,
                            args.max_iterations, !args.no_precondition, args.mobility.method, args.mobility.tolerance,
                            args.mobility.viscosity, box_geometry(args.mobility.box), args.common.json, args.io});
    return;
  }

  StopWatch total;
  StopWatch watch;
  const BeadBodies bodies_in = read_bead_bodies(args.bodies);
  const std::vector<double>& x = bodies_in.x;
  const std::vector<double>& radii = bodies_in.radii;
  const std::vector<std::size_t>& offsets = bodies_in.offsets;
  const std::vector<double>& reference = bodies_in.reference;
  const std::size_t n = bodies_in.beads(), m = bodies_in.bodies();
  const Array ft = read_array(args.forces);
  require(ft.data.size() == 6 * m, ErrorCode::invalid_input, "--forces",
          "has " + std::to_string(ft.data.size()) + " entries, expected " + std::to_string(6 * m) +
              " (m x 6: F_x F_y F_z T_x T_y T_z per body)");
  StageTimes stages;
  stages["read"] = watch.seconds();

  watch.restart();
  auto beads = make_operator(args.mobility, n);
  rpy::RigidBodies bodies(*beads, {.tolerance = args.solver_tolerance,
                                   .max_iterations = args.max_iterations,
                                   .precondition = !args.no_precondition});
  bodies.set_configuration(x, radii, offsets, reference);
  stages["setup"] = watch.seconds();

  watch.restart();
  std::vector<double> uw(6 * m), lambda(args.bead_forces.empty() ? 0 : 3 * n);
  const rpy::RigidBodyReport report = bodies.apply(ft.data, uw, lambda);
  stages["solve"] = watch.seconds();

  watch.restart();
  require_finite_output(uw, "rigid");
  require_finite_output(lambda, "rigid (bead forces)");
  write_npys({{args.out, {m, 6}, &uw}, {args.bead_forces, {n, 3}, &lambda}});
  stages["write"] = watch.seconds();

  if (args.common.json) {
    JsonLine line;
    line.add("command", "rigid")
        .add("method", beads->name())
        .add("bodies", m)
        .add("beads", n)
        .add("viscosity", args.mobility.viscosity)
        .add("tolerance", args.mobility.tolerance)
        .add("solver_tolerance", args.solver_tolerance)
        .add("preconditioned", !args.no_precondition)
        .add("iterations", report.iterations)
        .add("restarts", report.restarts)
        .add("residual", report.residual)
        .add("threads", active_threads())
        .add("simd", simd_level_name(simd_level()))
        .add("out", args.out)
        .add("seconds", stages)
        .add("total_seconds", total.seconds());
    std::cout << line.str() << '\n';
  }
}

}  // namespace

void register_rigid(CLI::App& app) {
  auto args = std::make_shared<RigidArgs>();
  CLI::App* cmd = app.add_subcommand("rigid", "velocities of rigid bodies made of beads under forces and torques");
  add_bead_body_options(*cmd, args->bodies, "bead positions, (N,3) .npy or text, body after body",
                        "points (m,3) the torques and angular velocities refer to (default: body centroids)");
  cmd->add_option("--forces", args->forces, "forces and torques (m,6): F_x F_y F_z T_x T_y T_z per body")->required();
  add_renamed_option(*cmd, "--solver-tolerance", "--tol", args->solver_tolerance,
                     "GMRES relative residual, in " + ranges::kSolverTolerance.str())
      .option->capture_default_str();
  add_integer_option(*cmd, "--max-iterations", args->max_iterations, ranges::kGmresIterations,
                     "most GMRES iterations (bead products)");
  cmd->add_flag("--no-precondition", args->no_precondition,
                "plain GMRES instead of the body-block preconditioner (for comparison; many more iterations)");
  add_mobility_options(*cmd, args->mobility);
  cmd->add_option("--out", args->out, "output .npy, shape (m,6): U_x U_y U_z Omega_x Omega_y Omega_z")->required();
  cmd->add_option("--bead-forces", args->bead_forces, "also write the bead forces (N,3) to this .npy");
  add_common_options(*cmd, args->common);
  add_io_option(*cmd, args->io);
  cmd->callback([args] {
    print_pending_warnings();
    run_rigid(*args);
  });
}

}  // namespace rpyfmm::cli
