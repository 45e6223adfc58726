// rpyfmm Python module — the arguments and results of whole BD runs (run_arguments.hpp).
#include "run_arguments.hpp"

#include <iostream>

namespace rpyfmm::python {

bd::RunConfig config_from(nb::handle config) {
  bd::RunConfig parsed;
  if (nb::try_cast(config, parsed, false)) return parsed;
  std::string text;
  if (nb::try_cast(config, text, false) &&
      (text.find('\n') != std::string::npos || text.find('=') != std::string::npos)) {
    return bd::parse_config(text, "<python string>");
  }
  std::filesystem::path path;
  if (nb::try_cast(config, path, true)) return reading_file("config", path, [&] { return bd::load_config(path); });
  fail(ErrorCode::invalid_argument, "config", "expected a RunConfig, a TOML file path or TOML text");
}

nb::dict summary_dict(const bd::RunSummary& s) {
  nb::dict d;
  d["particles"] = s.particles;
  d["mobility"] = s.mobility;
  d["engine"] = s.engine;
  d["first_step"] = s.first_step;
  d["last_step"] = s.last_step;
  d["wall_seconds"] = s.wall_seconds;
  d["steps_per_second"] = s.steps_per_second;
  d["neighbour_rebuilds"] = s.neighbour_rebuilds;
  d["mean_sqrt_iterations"] = s.mean_sqrt_iterations;
  d["preconditioner_blocks"] = s.preconditioner_blocks;
  d["mean_mobility_products"] = s.mean_mobility_products;
  d["seconds"] = s.seconds;
  d["out_dir"] = s.out_dir.string();
  d["trajectory"] = s.trajectory.string();
  d["log"] = s.log.string();
  d["checkpoint"] = s.checkpoint.string();
  return d;
}

bd::RunOptions run_options(std::optional<std::uint64_t> steps, std::optional<std::string> out_dir, bool progress) {
  bd::RunOptions o;
  o.steps = steps;
  if (out_dir) o.out_dir = *out_dir;
  if (progress) o.progress = &std::cerr;
  return o;
}

}  // namespace rpyfmm::python
