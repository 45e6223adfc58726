// rpyfmm CLI — `rpyfmm mobility`: velocities U = M F of N spheres under the
// Rotne-Prager-Yamakawa mobility.
//
//   rpyfmm mobility --positions X.npy --forces F.npy (--radius a | --radii R.npy)
//                   [--viscosity 1] [--method direct|fmm|pse|auto|none] [--tolerance 1e-6]
//                   [--box L | --box Lx Ly Lz] [--wave-precision auto|single|double] [--device cpu|cuda]
//                   [--torques T.npy | --angular] --out U.npy [--threads N] [--json]
//
// U has shape (N,3). With --torques (N,3) or --angular (T = 0), the grand mobility with rotation
// (docs/theory/rpy.md section 7; operators with supports_rotation: --method direct, fmm, pse (CPU and CUDA), none): the
// output has shape (N,6), columns Ux Uy Uz Wx Wy Wz. Under mpirun (docs/mpi.md) --method direct and fmm, and
// --method pse --box, run across the ranks with or without rotation (commands_across_ranks.cpp).
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
#include "mpi_session.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {
namespace {

struct MobilityArgs {
  std::string positions, forces, radii, torques, out;
  bool angular = false;  // (N, 6) output with rotation; T = 0 unless --torques
  double radius = 0.0;
  MobilityChoice mobility;  // --method, --tolerance, --viscosity, --box, ... (mobility_choice.hpp)
  CommonOptions common;
  std::string io = "collective";  // --io, across MPI ranks
};

/// U = M F, or with torques t (non-empty) [U; W] = M [F; T] written as (N, 6) rows Ux Uy Uz Wx Wy Wz;
/// checked finite, then written to `out`. Times "apply" and "write".
void apply_and_write(const rpy::MobilityOperator& op, const std::vector<double>& f, const std::vector<double>& t,
                     const std::string& out, StageTimes& stages) {
  const std::size_t n = f.size() / 3;
  const bool rotation = !t.empty();
  StopWatch watch;
  std::vector<double> u(3 * n), w(rotation ? 3 * n : 0);
  if (rotation) {
    op.apply(f, t, u, w);
  } else {
    op.apply(f, u);
  }
  stages["apply"] = watch.seconds();
  watch.restart();
  require_finite_output(u, "mobility");
  if (!rotation) {
    write_npy(out, {n, 3}, u);
  } else {
    require_finite_output(w, "mobility");
    std::vector<double> uw(6 * n);
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) uw[6 * i + c] = u[3 * i + c], uw[6 * i + 3 + c] = w[3 * i + c];
    write_npy(out, {n, 6}, uw);
  }
  stages["write"] = watch.seconds();
}

/// Under MPI: whether this product runs across the ranks (on the CPU: --method direct or fmm in free
/// space, or --method pse with --box and wave grids auto or double; each with --torques or --angular
/// too); otherwise it runs on one rank only and more ranks are refused. Every rank parses the same
/// options, so every rank refuses alike.
bool across_ranks(const MobilityArgs& args) {
  const MobilityChoice& m = args.mobility;
  const bool free_space = (m.method == "direct" || m.method == "fmm") && m.box.empty();
  const bool pse = m.method == "pse" && !m.box.empty() && m.wave_precision != "single";
  const bool supported = (free_space || pse) && m.device == "cpu";
  require(supported || mpi_size() == 1, ErrorCode::not_supported, "mobility",
          "across " + std::to_string(mpi_size()) +
              " MPI ranks runs --method direct or fmm without --box, or --method pse with --box (double-precision "
              "wave grids), --torques and --angular included, on the CPU (docs/mpi.md); run other methods without "
              "mpirun");
  return supported;
}

void run_mobility(const MobilityArgs& args, bool radius_given) {
  require_distinct_files(std::vector<NamedPath>{{"--positions", args.positions},
                                                {"--forces", args.forces},
                                                {"--radii", args.radii},
                                                {"--torques", args.torques}},
                         std::vector<NamedPath>{{"--out", args.out}});
  apply_threads(args.common);
  require(radius_given != !args.radii.empty(), ErrorCode::invalid_argument, "mobility",
          "give exactly one of --radius a or --radii R.npy");
  if (radius_given) ranges::require_in(ranges::kRadius, args.radius, "--radius", "radius");
  ranges::require_in(ranges::kViscosity, args.mobility.viscosity, "--viscosity", "viscosity");
  if (under_mpi() && across_ranks(args)) {
    run_mobility_across_ranks({args.positions, args.forces, args.radii, args.out, args.torques, args.angular,
                               args.radius, radius_given, args.mobility.viscosity, args.mobility.tolerance,
                               args.common.json, args.mobility.method, args.mobility.box, args.io});
    return;
  }

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

  const bool rotation = args.angular || !args.torques.empty();
  std::vector<double> t(rotation ? 3 * n : 0, 0.0);
  if (!args.torques.empty()) {
    t = as_points(read_array(args.torques), "torques");
    require(t.size() == x.size(), ErrorCode::invalid_input, "torques",
            "has " + std::to_string(t.size() / 3) + " rows, expected " + std::to_string(n) + " (one per particle)");
  }
  require(!rotation || op->supports_rotation(), ErrorCode::not_supported, "mobility",
          "--torques and --angular need a mobility with rotation (--method direct, fmm, pse on the CPU or none); '" +
              op->name() + "' has none");

  apply_and_write(*op, f, t, args.out, stages);

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
  cmd->add_option("--torques", args->torques,
                  "torques (N,3): the output is then (N,6), velocities and angular velocities (--method direct, fmm, "
                  "pse on the CPU, none)");
  cmd->add_flag("--angular", args->angular, "output (N,6) with angular velocities, torques zero unless --torques");
  cmd->add_option("--out", args->out, "output .npy, shape (N,3), or (N,6) with --torques / --angular")->required();
  add_common_options(*cmd, args->common);
  add_io_option(*cmd, args->io);
  cmd->callback([args, radius] {
    print_pending_warnings();
    run_mobility(*args, radius->count() > 0);
  });
}

}  // namespace rpyfmm::cli
