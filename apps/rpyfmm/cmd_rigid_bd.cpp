// rpyfmm CLI — `rpyfmm rigid-bd`: Brownian dynamics of rigid bodies made of beads, with
// hydrodynamic interactions among all beads and the thermal drift (rpyfmm/bd/rigid_dynamics.hpp).
//
//   rpyfmm rigid-bd --positions X.npy (--radius a | --radii R.npy) --body-sizes S.txt
//                   [--reference Q.npy] --dt DT --steps N [--kT 1] [--seed 1] [--drift rfd|none]
//                   [--rfd-delta 1e-3] [--body-force Fx Fy Fz] [--body-torque Tx Ty Tz]
//                   [--pair none|wca|soft|lj36_18] [--pair-epsilon 1] [--pair-sigma 0]
//                   [--solver-tolerance 1e-6] [--sqrt-tolerance 1e-3]
//                   [--sqrt-preconditioner auto|none|block] [--every K] [--method ...]
//                   [--tolerance ...]
//                   [--box ...] --out TRAJ.npy [--beads-out B.npy] [--restart OLD.npy
//                   --first-step S] [--threads N] [--json] [--io collective|root]
//
// X holds the beads at time 0, body after body (S: beads per body); the bodies' reference points
// are Q (default: centroids) and their orientations start at the identity, so bead i of body k
// sits at q_k(t) + R(quaternion_k(t)) (x_i(0) - q_k(0)), x_i(0) - q_k(0) a minimum image in a
// periodic box (bodies may be given wrapped into it). TRAJ is (frames, m, 7): q_x q_y q_z
// w x y z per body, frames at the first step, at steps that are multiples of K, and at the last
// step. Files are written at the end, atomically: a failed run leaves no output.
//
// Restart: --restart OLD.npy starts from OLD's last frame (with the original --positions,
// --body-sizes and --reference, which define the bodies' shapes); with --first-step S, S the
// last step of the earlier run, the continuation equals one longer run bit for bit.
//
// Under mpirun, --method direct and fmm (free space) and --method pse with --box (double-precision
// wave grids), on the CPU, also with --pair, run across the ranks, each rank owning whole bodies and
// reading and writing their rows of the .npy files (--io collective, the default) or rank 0 all of
// them (--io root) (rigid_bd_across_ranks.hpp); other methods are refused on more than one rank.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
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
#include "rigid_bd_across_ranks.hpp"
#include "rigid_bd_run.hpp"
#include "rpyfmm/bd/rigid_dynamics.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {
namespace {

struct RigidBdArgs {
  BeadBodyArgs bodies;
  std::string out, beads_out, restart;
  std::uint64_t first_step = 0;
  double dt = 0.0, kT = 1.0, rfd_delta = 1e-3;
  double solver_tolerance = 1e-6, sqrt_tolerance = 1e-3;  // GMRES residual; bead noise B z
  long long steps = 0, every = 0;
  std::uint64_t seed = 1;
  std::string drift = "rfd";
  std::string sqrt_preconditioner = "auto";  // auto | none | block
  BeadPairArgs pair;
  std::vector<double> body_force{0, 0, 0}, body_torque{0, 0, 0};
  MobilityChoice mobility;
  CommonOptions common;
  std::string io = "collective";  // --io, across MPI ranks
};

/// Checks every option that needs no file before anything is read.
void validate(const RigidBdArgs& args) {
  const BeadBodyArgs& b = args.bodies;
  require_distinct_files(std::vector<NamedPath>{{"--positions", b.positions},
                                                {"--radii", b.radii},
                                                {"--body-sizes", b.body_sizes},
                                                {"--reference", b.reference},
                                                {"--restart", args.restart}},
                         std::vector<NamedPath>{{"--out", args.out}, {"--beads-out", args.beads_out}});
  apply_threads(args.common);
  ranges::require_in(ranges::kSolverTolerance, args.solver_tolerance, "--solver-tolerance", "tolerance");
  ranges::require_in(ranges::kSolverTolerance, args.sqrt_tolerance, "--sqrt-tolerance", "tolerance");
  require(args.drift == "rfd" || args.drift == "none", ErrorCode::invalid_argument, "--drift",
          "must be rfd or none, got '" + args.drift + "'");
  require(
      args.sqrt_preconditioner == "auto" || args.sqrt_preconditioner == "none" || args.sqrt_preconditioner == "block",
      ErrorCode::invalid_argument, "--sqrt-preconditioner",
      "must be auto, none or block, got '" + args.sqrt_preconditioner + "'");
  require(args.body_force.size() == 3 && args.body_torque.size() == 3, ErrorCode::invalid_argument, "rigid-bd",
          "--body-force and --body-torque take three numbers");
  require_finite(args.body_force, "--body-force", "force", 3);
  require_finite(args.body_torque, "--body-torque", "torque", 3);
}

/// --body-force and --body-torque, F then T.
std::array<double, 6> load_of(const RigidBdArgs& args) {
  return {args.body_force[0],  args.body_force[1],  args.body_force[2],
          args.body_torque[0], args.body_torque[1], args.body_torque[2]};
}

/// --sqrt-preconditioner: auto (the serial engine's block preconditioner; none across ranks), none
/// (the principal root) or block.
rpy::SqrtPreconditioner sqrt_preconditioner(const std::string& name) {
  if (name == "none") return rpy::SqrtPreconditioner::none;
  if (name == "block") return rpy::SqrtPreconditioner::block;
  return rpy::SqrtPreconditioner::automatic;
}

bd::RigidDynamicsOptions dynamics_options(const RigidBdArgs& args) {
  return {.dt = args.dt,
          .kT = args.kT,
          .seed = args.seed,
          .first_step = args.first_step,
          .drift = args.drift == "none" ? bd::RigidDrift::none : bd::RigidDrift::random_finite_difference,
          .rfd_delta = args.rfd_delta,
          .solver = {.tolerance = args.solver_tolerance},
          .sqrt = {.tolerance = args.sqrt_tolerance, .preconditioner = sqrt_preconditioner(args.sqrt_preconditioner)}};
}

/// Runs --steps steps; returns the frames (q, quaternion per body) at the first step, at multiples
/// of --every and at the last step.
std::vector<double> run_and_record(bd::RigidBodyDynamics& sim, const RigidBdArgs& args) {
  const std::size_t m = sim.bodies();
  std::vector<double> frames;
  const auto record = [&] {
    for (std::size_t k = 0; k < m; ++k) {
      frames.insert(frames.end(), sim.positions().begin() + std::ptrdiff_t(3 * k),
                    sim.positions().begin() + std::ptrdiff_t(3 * k + 3));
      frames.insert(frames.end(), sim.orientations().begin() + std::ptrdiff_t(4 * k),
                    sim.orientations().begin() + std::ptrdiff_t(4 * k + 4));
    }
  };
  step_and_record(
      static_cast<std::uint64_t>(args.steps), static_cast<std::uint64_t>(args.every), [&] { sim.step(); },
      [&] { return sim.step_count(); }, record);
  return frames;
}

void report_rigid_bd(const RigidBdArgs& args, const bd::RigidBodyDynamics& sim, std::size_t frame_count,
                     StageTimes& stages, double total_seconds) {
  const std::size_t m = sim.bodies(), n = sim.beads();
  const auto steps = static_cast<std::uint64_t>(args.steps);
  const auto& t = sim.totals();
  const double per_step = stages["run"] / double(steps);
  if (args.common.json) {
    JsonLine line;
    line.add("command", "rigid-bd")
        .add("drift", sim.options().drift == bd::RigidDrift::none ? "none" : "rfd")
        .add("bodies", m)
        .add("beads", n)
        .add("steps", static_cast<std::size_t>(steps))
        .add("last_step", static_cast<std::size_t>(sim.step_count()))
        .add("frames", frame_count)
        .add("dt", args.dt)
        .add("kT", args.kT)
        .add("solve_iterations_per_step", double(t.solve_iterations) / double(steps))
        .add("drift_iterations_per_step", double(t.drift_iterations) / double(steps))
        .add("sqrt_iterations_per_step", double(t.sqrt_iterations) / double(steps))
        .add("seconds_per_step", per_step)
        .add("threads", active_threads())
        .add("simd", simd_level_name(simd_level()))
        .add("out", args.out)
        .add("seconds", stages)
        .add("step_seconds", t.seconds)
        .add("total_seconds", total_seconds);
    std::cout << line.str() << '\n';
  } else {
    std::cout << "rigid-bd: " << m << " bodies, " << n << " beads, " << steps << " steps in " << stages["run"] << " s ("
              << per_step << " s/step; GMRES " << double(t.solve_iterations) / double(steps) << " + "
              << double(t.drift_iterations) / double(steps) << " drift, sampler "
              << double(t.sqrt_iterations) / double(steps) << " iterations per step); " << frame_count << " frames -> "
              << args.out << '\n';
  }
}

/// Under MPI: whether this run goes across the ranks (--method direct or fmm without --box, or pse
/// with --box and wave grids auto or double, on the CPU); otherwise more than one rank is refused.
/// Every rank parses the same options, so every rank refuses alike.
bool across_ranks(const RigidBdArgs& args) {
  return bodies_across_ranks(args.mobility, mpi_size(), "rigid-bd");
}

void run_rigid_bd(const RigidBdArgs& args) {
  validate(args);
  if (under_mpi() && across_ranks(args)) {
    run_rigid_bd_across_ranks({args.bodies, args.out, args.beads_out, args.restart,
                               static_cast<std::uint64_t>(args.steps), static_cast<std::uint64_t>(args.every),
                               dynamics_options(args), load_of(args), args.mobility.method, args.mobility.tolerance,
                               args.mobility.viscosity, box_geometry(args.mobility.box), args.pair, args.common.json,
                               args.io});
    return;
  }
  StopWatch total;
  StopWatch watch;
  const BeadBodies bodies = read_bead_bodies(args.bodies);
  const std::size_t n = bodies.beads(), m = bodies.bodies();
  // The operator first: its geometry gives the minimum images of bodies wrapped into a box.
  auto beads = make_operator(args.mobility, n);
  std::vector<double> reference = bodies.reference;
  const std::vector<double> shape = body_frame_shape(beads->geometry(), bodies, reference);
  const BodyState start = initial_state(args.restart, reference, m);
  StageTimes stages;
  stages["read"] = watch.seconds();

  watch.restart();
  bd::RigidBodyDynamics sim(std::move(beads), shape, bodies.radii, bodies.offsets, start.positions, start.orientations,
                            dynamics_options(args), constant_load(load_of(args)));
  if (auto field = bead_pair_field(args.pair, bodies.radii[0])) sim.set_bead_forces(std::move(*field));
  stages["setup"] = watch.seconds();

  watch.restart();
  const std::vector<double> frames = run_and_record(sim, args);
  stages["run"] = watch.seconds();

  watch.restart();
  require_finite_output(frames, "rigid-bd (trajectory)");
  require_finite_output(sim.bead_positions(), "rigid-bd (bead positions)");
  const std::size_t frame_count = frames.size() / (7 * m);
  const std::vector<double> bead_positions(sim.bead_positions().begin(), sim.bead_positions().end());
  write_npys({{args.out, {frame_count, m, 7}, &frames}, {args.beads_out, {n, 3}, &bead_positions}});
  stages["write"] = watch.seconds();
  report_rigid_bd(args, sim, frame_count, stages, total.seconds());
}

}  // namespace

void register_rigid_bd(CLI::App& app) {
  auto args = std::make_shared<RigidBdArgs>();
  CLI::App* cmd = app.add_subcommand(
      "rigid-bd", "Brownian dynamics of rigid bodies made of beads (HI among all beads, thermal drift)");
  add_bead_body_options(*cmd, args->bodies, "bead positions at t = 0, (N,3) .npy or text, body after body",
                        "reference points (m,3) at t = 0 (default: body centroids)");
  cmd->add_option("--dt", args->dt, "time step > 0")->required();
  add_integer_option(*cmd, "--steps", args->steps, {1, ranges::kSteps.hi}, "number of steps")->required();
  cmd->add_option("--kT", args->kT, "thermal energy >= 0 (0: deterministic)")->capture_default_str();
  add_integer_option(*cmd, "--seed", args->seed, ranges::kSeed, "key of the noise");
  cmd->add_option("--drift", args->drift, "thermal drift: rfd (random finite difference) or none")
      ->capture_default_str();
  cmd->add_option("--rfd-delta", args->rfd_delta, "relative RFD step, in [1e-6, 0.1]")->capture_default_str();
  cmd->add_option("--body-force", args->body_force, "constant force on every body (3 numbers), e.g. gravity")
      ->expected(3);
  cmd->add_option("--body-torque", args->body_torque, "constant torque on every body (3 numbers)")->expected(3);
  cmd->add_option("--pair", args->pair.kind, "pair potential between beads of different bodies: none|wca|soft|lj36_18")
      ->capture_default_str();
  cmd->add_option("--pair-epsilon", args->pair.epsilon, "its energy scale")->capture_default_str();
  cmd->add_option("--pair-sigma", args->pair.sigma, "its length scale (0: twice the first bead's radius)")
      ->capture_default_str();
  add_renamed_option(*cmd, "--solver-tolerance", "--tol", args->solver_tolerance,
                     "GMRES relative residual, in " + ranges::kSolverTolerance.str())
      .option->capture_default_str();
  add_renamed_option(
      *cmd, "--sqrt-tolerance", "--sqrt-tol", args->sqrt_tolerance,
      "tolerance of the bead noise B z (block-preconditioned Lanczos), in " + ranges::kSolverTolerance.str())
      .option->capture_default_str();
  cmd->add_option("--sqrt-preconditioner", args->sqrt_preconditioner,
                  "bead noise B z: auto (block; none across MPI ranks), none (M^{1/2} z) or block")
      ->capture_default_str();
  add_integer_option(*cmd, "--every", args->every, ranges::kSteps,
                     "record a frame every K steps (0: first and last only)");
  add_mobility_options(*cmd, args->mobility);
  cmd->add_option("--out", args->out, "trajectory .npy, shape (frames, m, 7): q_x q_y q_z w x y z")->required();
  cmd->add_option("--beads-out", args->beads_out, "also write the final bead positions (N,3) to this .npy");
  cmd->add_option("--restart", args->restart,
                  "start from the last frame of this trajectory (same --positions, --body-sizes, --reference)");
  add_integer_option(*cmd, "--first-step", args->first_step, ranges::kSeed,
                     "step number of the initial state (with --restart: the earlier run's last step)");
  add_common_options(*cmd, args->common);
  add_io_option(*cmd, args->io);
  cmd->callback([args] {
    print_pending_warnings();
    run_rigid_bd(*args);
  });
}

}  // namespace rpyfmm::cli
