// rpyfmm CLI — `rpyfmm mobility`: velocities U = M F of N spheres under the
// Rotne-Prager-Yamakawa mobility.
//
//   rpyfmm mobility --positions X.npy --forces F.npy (--radius a | --radii R.npy)
//                   [--viscosity 1] [--method direct|fmm|pse|auto|none] [--tolerance 1e-6]
//                   [--box L | --box Lx Ly Lz] [--wave-precision auto|single|double] [--device cpu|cuda]
//                   --out U.npy [--threads N] [--json]
//
// U has shape (N,3).
#include <CLI/CLI.hpp>
#include <cstddef>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "cli_common.hpp"
#include "commands.hpp"
#include "mobility_choice.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {
namespace {

struct MobilityArgs {
  std::string positions, forces, radii, out;
  double radius = 0.0;
  MobilityChoice mobility;  // --method, --tolerance, --viscosity, --box, ... (mobility_choice.hpp)
  CommonOptions common;
};

void run_mobility(const MobilityArgs& args, bool radius_given) {
  require_distinct_files(
      std::vector<NamedPath>{{"--positions", args.positions}, {"--forces", args.forces}, {"--radii", args.radii}},
      std::vector<NamedPath>{{"--out", args.out}});
  apply_threads(args.common);
  require(radius_given != !args.radii.empty(), ErrorCode::invalid_argument, "mobility",
          "give exactly one of --radius a or --radii R.npy");
  if (radius_given) ranges::require_in(ranges::kRadius, args.radius, "--radius", "radius");
  ranges::require_in(ranges::kViscosity, args.mobility.viscosity, "--viscosity", "viscosity");

  StopWatch total;
  StopWatch watch;
  const std::vector<double> x = as_points(read_array(args.positions), "positions");
  const std::size_t n = x.size() / 3;
  const Array farr = read_array(args.forces);
  const std::vector<double> f = as_points(farr, "forces");
  require(f.size() == x.size(), ErrorCode::invalid_input, "forces",
          "has " + std::to_string(f.size() / 3) + " rows, expected " + std::to_string(n) + " (one per particle)");
  std::vector<double> radii;
  if (!radius_given) radii = as_vector(read_array(args.radii), n, "radii");
  StageTimes stages;
  stages["read"] = watch.seconds();

  watch.restart();
  auto op = make_operator(args.mobility, n);
  if (radius_given) {
    op->set_positions(x, args.radius);
  } else {
    op->set_positions(x, radii);
  }
  stages["setup"] = watch.seconds();

  watch.restart();
  std::vector<double> u(3 * n);
  op->apply(f, u);
  stages["apply"] = watch.seconds();

  watch.restart();
  require_finite_output(u, "mobility");
  write_npy(args.out, {n, 3}, u);
  stages["write"] = watch.seconds();

  if (args.common.json) {
    JsonLine line;
    line.add("command", "mobility")
        .add("method", op->name())
        .add("n", n)
        .add("viscosity", args.mobility.viscosity)
        .add("tolerance", args.mobility.tolerance)
        .add("equal_radii", op->equal_radii())
        .add("threads", active_threads())
        .add("simd", simd_level_name(simd_level()))
        .add("out", args.out)
        .add("seconds", stages)
        .add("total_seconds", total.seconds());
    if (radius_given) line.add("radius", args.radius);
    std::cout << line.str() << '\n';
  }
}

}  // namespace

void register_mobility(CLI::App& app) {
  auto args = std::make_shared<MobilityArgs>();
  CLI::App* cmd = app.add_subcommand("mobility", "RPY velocities U = M F of N spheres");
  cmd->add_option("--positions", args->positions, "positions, (N,3) .npy or text")->required();
  cmd->add_option("--forces", args->forces, "forces (N,3)")->required();
  auto* radius = cmd->add_option("--radius", args->radius, "common sphere radius a, in " + ranges::kRadius.str());
  auto* radii = cmd->add_option("--radii", args->radii, "per-particle radii (N,)");
  radius->excludes(radii);
  add_mobility_options(*cmd, args->mobility);
  cmd->add_option("--out", args->out, "output .npy, shape (N,3)")->required();
  add_common_options(*cmd, args->common);
  cmd->callback([args, radius] {
    print_pending_warnings();
    run_mobility(*args, radius->count() > 0);
  });
}

}  // namespace rpyfmm::cli
