// rpyfmm CLI — `rpyfmm rigid`: linear and angular velocities of rigid bodies made of beads
// (bead-shell models) under forces and torques, with hydrodynamic interactions among all beads
// (rpyfmm/rpy/rigid_bodies.hpp).
//
//   rpyfmm rigid --positions X.npy (--radius a | --radii R.npy) --body-sizes S.txt
//                --forces FT.npy [--reference Q.npy] [--tol 1e-6] [--max-iterations 500]
//                [--no-precondition] [--method direct|fmm|pse|auto] [--eps 1e-6] [--viscosity 1]
//                [--box L | --box Lx Ly Lz] --out UW.npy [--bead-forces L.npy] [--threads N] [--json]
//
// Beads are listed body after body; S holds the m body sizes (beads per body, each >= 3).
// FT is (m,6): F_x F_y F_z T_x T_y T_z per body (torques about the reference points Q, (m,3),
// default the bodies' centroids); UW is (m,6): U_x U_y U_z Omega_x Omega_y Omega_z.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstddef>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "cli_common.hpp"
#include "commands.hpp"
#include "mobility_choice.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

namespace rpyfmm::cli {
namespace {

struct RigidArgs {
  std::string positions, radii, body_sizes, forces, reference, out, bead_forces;
  double radius = 0.0;
  double tol = 1e-6;
  int max_iterations = 500;
  bool no_precondition = false;
  MobilityChoice mobility;
  CommonOptions common;
};

void run_rigid(const RigidArgs& args, bool radius_given) {
  apply_threads(args.common);
  require(radius_given != !args.radii.empty(), ErrorCode::invalid_argument, "rigid",
          "give exactly one of --radius a or --radii R.npy");
  if (radius_given) require_positive(args.radius, "--radius", "radius");
  require(args.tol > 0.0 && args.tol < 1.0, ErrorCode::invalid_argument, "--tol",
          "must lie in (0, 1), got " + std::to_string(args.tol));

  StopWatch total;
  StopWatch watch;
  const std::vector<double> x = as_points(read_array(args.positions), "positions");
  const std::size_t n = x.size() / 3;
  const Array sizes_array = read_array(args.body_sizes);
  const std::vector<std::size_t> offsets = body_offsets_from_sizes(sizes_array.data);
  const std::size_t m = offsets.size() - 1;
  require(m > 0, ErrorCode::invalid_input, "--body-sizes", "no bodies given");
  require(offsets.back() == n, ErrorCode::invalid_input, "--body-sizes",
          "the body sizes add up to " + std::to_string(offsets.back()) + " beads, but --positions has " +
              std::to_string(n));
  const Array ft = read_array(args.forces);
  require(ft.data.size() == 6 * m, ErrorCode::invalid_input, "--forces",
          "has " + std::to_string(ft.data.size()) + " entries, expected " + std::to_string(6 * m) +
              " (m x 6: F_x F_y F_z T_x T_y T_z per body)");
  std::vector<double> radii(n, args.radius);
  if (!radius_given) radii = as_vector(read_array(args.radii), n, "radii");
  std::vector<double> reference;
  if (!args.reference.empty()) {
    reference = as_points(read_array(args.reference), "reference points");
    require(reference.size() == 3 * m, ErrorCode::invalid_input, "--reference",
            "has " + std::to_string(reference.size() / 3) + " rows, expected " + std::to_string(m) + " (one per body)");
  }
  StageTimes stages;
  stages["read"] = watch.seconds();

  watch.restart();
  auto beads = make_operator(args.mobility, n);
  rpy::RigidBodies bodies(
      *beads, {.tolerance = args.tol, .max_iterations = args.max_iterations, .precondition = !args.no_precondition});
  bodies.set_configuration(x, radii, offsets, reference);
  stages["setup"] = watch.seconds();

  watch.restart();
  std::vector<double> uw(6 * m), lambda(args.bead_forces.empty() ? 0 : 3 * n);
  const rpy::RigidBodyReport report = bodies.apply(ft.data, uw, lambda);
  stages["solve"] = watch.seconds();

  watch.restart();
  write_npy(args.out, {m, 6}, uw);
  if (!args.bead_forces.empty()) write_npy(args.bead_forces, {n, 3}, lambda);
  stages["write"] = watch.seconds();

  if (args.common.json) {
    JsonLine line;
    line.add("command", "rigid")
        .add("method", beads->name())
        .add("bodies", m)
        .add("beads", n)
        .add("viscosity", args.mobility.viscosity)
        .add("eps", args.mobility.eps)
        .add("tol", args.tol)
        .add("preconditioned", !args.no_precondition)
        .add("iterations", report.iterations)
        .add("restarts", report.restarts)
        .add("residual", report.residual)
        .add("threads", active_threads())
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
  cmd->add_option("--positions", args->positions, "bead positions, (N,3) .npy or text, body after body")->required();
  auto* radius = cmd->add_option("--radius", args->radius, "common bead radius a > 0");
  auto* radii = cmd->add_option("--radii", args->radii, "per-bead radii (N,)");
  radius->excludes(radii);
  cmd->add_option("--body-sizes", args->body_sizes, "beads per body (m,), in the order of --positions")->required();
  cmd->add_option("--forces", args->forces, "forces and torques (m,6): F_x F_y F_z T_x T_y T_z per body")->required();
  cmd->add_option("--reference", args->reference,
                  "points (m,3) the torques and angular velocities refer to (default: body centroids)");
  cmd->add_option("--tol", args->tol, "GMRES relative residual, in (0, 1)")->capture_default_str();
  cmd->add_option("--max-iterations", args->max_iterations, "most GMRES iterations (bead products)")
      ->capture_default_str();
  cmd->add_flag("--no-precondition", args->no_precondition,
                "plain GMRES instead of the body-block preconditioner (for comparison; many more iterations)");
  add_mobility_options(*cmd, args->mobility);
  cmd->add_option("--out", args->out, "output .npy, shape (m,6): U_x U_y U_z Omega_x Omega_y Omega_z")->required();
  cmd->add_option("--bead-forces", args->bead_forces, "also write the bead forces (N,3) to this .npy");
  add_common_options(*cmd, args->common);
  cmd->callback([args, radius] { run_rigid(*args, radius->count() > 0); });
}

}  // namespace rpyfmm::cli
