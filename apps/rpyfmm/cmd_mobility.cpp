// rpyfmm CLI — `rpyfmm mobility`: velocities U = M F of N spheres under the
// Rotne-Prager-Yamakawa mobility.
//
//   rpyfmm mobility --positions X.npy --forces F.npy (--radius a | --radii R.npy)
//                   [--viscosity 1] [--method direct|fmm|pse|auto|none] [--eps 1e-6]
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
#include "rpyfmm/bd/mobility_factory.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {
namespace {

struct MobilityArgs {
  std::string positions, forces, radii, out;
  double radius = 0.0;
  double viscosity = 1.0;
  std::string method = "direct";
  double eps = 1e-6;                    // tolerance of fmm / pse (direct is exact)
  std::vector<double> box;              // periodic box: L or Lx Ly Lz (empty = free space)
  std::string wave_precision = "auto";  // pse: auto | single | double
  std::string device = "cpu";           // pse: cpu | cuda
  CommonOptions common;
};

// ---- methods ------------------------------------------------------------
// Every --method goes through rpyfmm::bd::make_mobility, the one factory that
// the BD engine uses too: direct, fmm, pse (periodic, needs --box), auto, none.
std::unique_ptr<rpy::MobilityOperator> make_operator(const MobilityArgs& args, std::size_t n) {
  bd::MobilitySpec spec;
  spec.method = bd::mobility_method_from_string(args.method);
  spec.tolerance = args.eps;
  spec.viscosity = args.viscosity;
  spec.wave_precision = rpy::pse::wave_precision_from_name(args.wave_precision, "--wave-precision");
  require(spec.wave_precision == rpy::pse::WavePrecision::automatic || spec.method == bd::MobilityMethod::pse ||
              (spec.method == bd::MobilityMethod::automatic && !args.box.empty()),
          ErrorCode::invalid_argument, "--wave-precision", "applies to the pse method only");
  spec.device = bd::compute_device_from_string(args.device, "--device");
  if (!args.box.empty()) {
    require(args.box.size() == 1 || args.box.size() == 3, ErrorCode::invalid_argument, "--box",
            "give one length L (cube) or three lengths Lx Ly Lz, got " + std::to_string(args.box.size()) + " values");
    spec.geometry = args.box.size() == 1 ? rpy::Geometry::periodic(args.box[0])
                                         : rpy::Geometry::periodic(args.box[0], args.box[1], args.box[2]);
  }
  return bd::make_mobility(spec, n);
}
// -------------------------------------------------------------------------

void run_mobility(const MobilityArgs& args, bool radius_given) {
  apply_threads(args.common);
  require(radius_given != !args.radii.empty(), ErrorCode::invalid_argument, "mobility",
          "give exactly one of --radius a or --radii R.npy");
  if (radius_given) require_positive(args.radius, "--radius", "radius");
  require_positive(args.viscosity, "--viscosity", "viscosity");

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
  auto op = make_operator(args, n);
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
  write_npy(args.out, {n, 3}, u);
  stages["write"] = watch.seconds();

  if (args.common.json) {
    JsonLine line;
    line.add("command", "mobility")
        .add("method", op->name())
        .add("n", n)
        .add("viscosity", args.viscosity)
        .add("eps", args.eps)
        .add("equal_radii", op->equal_radii())
        .add("threads", active_threads())
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
  auto* radius = cmd->add_option("--radius", args->radius, "common sphere radius a > 0");
  auto* radii = cmd->add_option("--radii", args->radii, "per-particle radii (N,)");
  radius->excludes(radii);
  cmd->add_option("--viscosity", args->viscosity, "solvent viscosity eta > 0")->capture_default_str();
  cmd->add_option("--method", args->method,
                  "direct (exact O(N^2)), fmm (free space, O(N)), pse (periodic, needs --box), "
                  "auto (direct for small N, fmm above; pse with --box), none (free draining)")
      ->capture_default_str();
  cmd->add_option("--eps", args->eps, "relative tolerance of fmm/pse, in [1e-12, 1e-1]")->capture_default_str();
  cmd->add_option("--box", args->box, "periodic box: L (cube) or Lx Ly Lz; particles are wrapped into it")
      ->expected(1, 3);
  cmd->add_option("--wave-precision", args->wave_precision,
                  "pse: wave-space grids in single or double precision; auto = single for --eps >= 1e-5")
      ->capture_default_str();
  cmd->add_option("--device", args->device, "pse: cpu, or cuda (on a GPU, in a build with CUDA)")
      ->capture_default_str();
  cmd->add_option("--out", args->out, "output .npy, shape (N,3)")->required();
  add_common_options(*cmd, args->common);
  cmd->callback([args, radius] { run_mobility(*args, radius->count() > 0); });
}

}  // namespace rpyfmm::cli
