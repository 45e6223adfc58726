// rpyfmm CLI — the mobility operator chosen on the command line (see the header).
#include "mobility_choice.hpp"

#include <CLI/CLI.hpp>
#include <string>

#include "cli_common.hpp"
#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"

namespace rpyfmm::cli {

void add_mobility_options(CLI::App& cmd, MobilityChoice& choice) {
  cmd.add_option("--viscosity", choice.viscosity, "solvent viscosity eta, in " + ranges::kViscosity.str())
      ->capture_default_str();
  cmd.add_option(
         "--method", choice.method,
         "direct (exact O(N^2)), fmm (free space, O(N)), pse (periodic with --box, free space "
         "without: open boundaries), auto (direct for small N, fmm above; pse with --box), none (free draining)")
      ->capture_default_str();
  add_renamed_option(cmd, "--tolerance", "--eps", choice.tolerance,
                     "relative tolerance of fmm/pse, in " + ranges::kMobilityTolerance.str())
      .option->capture_default_str();
  cmd.add_option("--box", choice.box, "periodic box: L (cube) or Lx Ly Lz; particles are wrapped into it")
      ->expected(1, 3);
  cmd.add_option("--wave-precision", choice.wave_precision,
                 "pse: wave-space grids in single or double precision; auto = single for --tolerance >= 1e-5")
      ->capture_default_str();
  cmd.add_option("--device", choice.device, "pse: cpu, or cuda (on a GPU, in a build with CUDA)")
      ->capture_default_str();
}

bool bodies_across_ranks(const MobilityChoice& choice, int ranks, const std::string& command) {
  const bool free_space = (choice.method == "direct" || choice.method == "fmm") && choice.box.empty();
  const bool pse = choice.method == "pse" && !choice.box.empty() && choice.wave_precision != "single";
  const bool supported = (free_space || pse) && choice.device == "cpu";
  require(supported || ranks == 1, ErrorCode::not_supported, command,
          "across " + std::to_string(ranks) +
              " MPI ranks runs --method direct or fmm without --box, or --method pse with --box "
              "(double-precision wave grids), on the CPU (docs/mpi.md), not --method " +
              choice.method + (choice.box.empty() ? "" : " with --box") + "; run other methods without mpirun");
  if (supported) {  // as make_operator checks them
    ranges::require_in(ranges::kViscosity, choice.viscosity, "--viscosity", "viscosity");
    ranges::require_in(ranges::kMobilityTolerance, choice.tolerance, "--tolerance", "tolerance");
  }
  return supported;
}

std::unique_ptr<rpy::MobilityOperator> make_operator(const MobilityChoice& choice, std::size_t n) {
  ranges::require_in(ranges::kViscosity, choice.viscosity, "--viscosity", "viscosity");
  ranges::require_in(ranges::kMobilityTolerance, choice.tolerance, "--tolerance", "tolerance");
  rpy::MobilitySpec spec;
  spec.method = rpy::mobility_method_from_string(choice.method);
  spec.tolerance = choice.tolerance;
  spec.viscosity = choice.viscosity;
  spec.wave_precision = rpy::pse::wave_precision_from_name(choice.wave_precision, "--wave-precision");
  require(spec.wave_precision == rpy::pse::WavePrecision::automatic || spec.method == rpy::MobilityMethod::pse ||
              (spec.method == rpy::MobilityMethod::automatic && !choice.box.empty()),
          ErrorCode::invalid_argument, "--wave-precision", "applies to the pse method only");
  spec.device = rpy::compute_device_from_string(choice.device, "--device");
  spec.geometry = box_geometry(choice.box);
  return rpy::make_mobility(spec, n);
}

rpy::Geometry box_geometry(const std::vector<double>& box) {
  if (box.empty()) return rpy::Geometry::open();
  require(box.size() == 1 || box.size() == 3, ErrorCode::invalid_argument, "--box",
          "give one length L (cube) or three lengths Lx Ly Lz, got " + std::to_string(box.size()) + " values");
  return box.size() == 1 ? rpy::Geometry::periodic(box[0]) : rpy::Geometry::periodic(box[0], box[1], box[2]);
}

}  // namespace rpyfmm::cli
