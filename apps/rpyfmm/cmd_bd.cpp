// rpyfmm CLI — `rpyfmm bd`: Brownian dynamics with hydrodynamic interactions.
//
//   rpyfmm bd [--config run.toml] [--steps N] [--out-dir DIR] [--restart CHECKPOINT]
//             [--threads N] [--json] [--quiet]
//
// Without --config (and without --restart) it runs the built-in demo: a
// sedimenting cloud of 2000 spheres with HI. The config reference is
// docs/bd-config.md; examples are in examples/bd/. A progress line (rate, ETA)
// goes to stderr when stdout is a terminal; a summary (or one JSON line with
// --json) goes to stdout at the end. Bad input: one line on stderr, exit 2.
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "cli_common.hpp"
#include "commands.hpp"
#include "mpi_session.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {
namespace {

struct BdArgs {
  std::string config, out_dir, restart;
  std::uint64_t steps = 0;
  bool steps_given = false;
  bool quiet = false;
  CommonOptions common;
};

void run_bd_command(const BdArgs& args) {
  apply_threads(args.common);
  require(args.config.empty() || args.restart.empty(), ErrorCode::invalid_argument, "bd",
          "give --config or --restart, not both (a checkpoint carries its config)");
  bd::RunOptions options;
  if (args.steps_given) options.steps = args.steps;
  if (!args.out_dir.empty()) options.out_dir = args.out_dir;
  const bool terminal = ::isatty(STDOUT_FILENO) != 0;
  if (terminal && !args.quiet && !args.common.json) options.progress = &std::cerr;
  // Under mpirun: DistributedBd across the ranks takes the steps, rank 0 writes the files and
  // prints (docs/mpi.md, "The command-line tool under mpirun").
  const bool ranks = under_mpi();
  if (ranks) options = bd_options_across_ranks(options);
  const bool prints = mpi_rank() == 0;

  bd::RunSummary s;
  std::string source;
  if (!args.restart.empty()) {
    source = args.restart;
    s = bd::restart_bd(args.restart, options);
  } else {
    if (!args.config.empty()) require_regular_input(args.config, "--config");  // /dev/zero would never end
    const bd::RunConfig config = args.config.empty() ? bd::parse_config(bd::demo_config_text(), "<built-in demo>")
                                                     : bd::load_config(args.config);
    source = config.source;
    if (!args.quiet && !args.common.json && prints)
      std::cout << "rpyfmm bd: " << source << " (" << rpy::to_string(config.mobility.method) << " mobility, "
                << active_threads() << " threads)" << std::endl;
    s = bd::run_bd(config, options);
  }
  if (!prints) return;
  if (args.common.json) {
    JsonLine line;
    line.add("command", "bd")
        .add("config", source)
        .add("n", s.particles)
        .add("mobility", s.mobility)
        .add("engine", s.engine)
        .add("threads", active_threads())
        .add("simd", simd_level_name(simd_level()))
        .add("first_step", static_cast<long long>(s.first_step))
        .add("last_step", static_cast<long long>(s.last_step))
        .add("wall_seconds", s.wall_seconds)
        .add("steps_per_second", s.steps_per_second)
        .add("neighbour_rebuilds", static_cast<long long>(s.neighbour_rebuilds))
        .add("sqrt_iterations_per_step", s.mean_sqrt_iterations)
        .add("preconditioner_blocks", s.preconditioner_blocks)
        .add("mobility_products_per_step", s.mean_mobility_products)
        .add("seconds", s.seconds)
        .add("out_dir", s.out_dir.string());
    if (ranks) line.add("ranks", mpi_size());
    std::cout << line.str() << '\n';
  } else if (!args.quiet) {
    std::printf("%zu particles, steps %llu -> %llu in %.2f s (%.3g steps/s), %s mobility, %s engine\n", s.particles,
                static_cast<unsigned long long>(s.first_step), static_cast<unsigned long long>(s.last_step),
                s.wall_seconds, s.steps_per_second, s.mobility.c_str(), s.engine.c_str());
    const std::string blocks = s.preconditioner_blocks > 0
                                   ? " (block-preconditioned, " + std::to_string(s.preconditioner_blocks) + " blocks)"
                                   : "";
    std::printf("per step: %.1f Lanczos iterations%s, %.1f mobility products; %llu neighbour-list builds\n",
                s.mean_sqrt_iterations, blocks.c_str(), s.mean_mobility_products,
                static_cast<unsigned long long>(s.neighbour_rebuilds));
    std::printf("time:");
    for (const auto& [part, sec] : s.seconds) std::printf(" %s %.2fs", part.c_str(), sec);
    std::printf("\noutput: %s (trajectory %s, log %s, checkpoint %s)\n", s.out_dir.string().c_str(),
                s.trajectory.filename().string().c_str(), s.log.filename().string().c_str(),
                s.checkpoint.filename().string().c_str());
  }
}

}  // namespace

void register_bd(CLI::App& app) {
  auto args = std::make_shared<BdArgs>();
  CLI::App* cmd = app.add_subcommand(
      "bd", "Brownian dynamics with hydrodynamic interactions (no --config: built-in sedimentation demo)");
  cmd->add_option("--config", args->config, "TOML run config (docs/bd-config.md)");
  add_integer_option(*cmd, "--steps", args->steps, ranges::kSteps,
                     "total steps of the run (overrides integrator.steps)")
      ->default_str("")  // not given: the config's integrator.steps
      ->each([args](const std::string&) { args->steps_given = true; });
  cmd->add_option("--out-dir", args->out_dir, "output directory (overrides output.dir)");
  cmd->add_option("--restart", args->restart, "continue from a checkpoint file (bitwise identical)");
  cmd->add_flag("--quiet", args->quiet, "no progress line and no summary");
  add_common_options(*cmd, args->common);
  cmd->callback([args] { run_bd_command(*args); });
}

}  // namespace rpyfmm::cli
