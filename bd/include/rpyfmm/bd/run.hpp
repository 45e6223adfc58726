// rpyfmm::bd — a whole BD run from a config: particles, forces, mobility,
// integrator, trajectory/log/checkpoint output, restart and blow-up handling.
// This is what `rpyfmm bd` calls.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <ostream>
#include <span>
#include <string>

#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/step_engine.hpp"
#include "rpyfmm/bd/stepper.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/core/timer.hpp"

namespace rpyfmm::bd {

struct RunOptions {
  /// Total number of steps of the run (overrides integrator.steps); a restarted run
  /// continues until the step counter reaches it.
  std::optional<std::uint64_t> steps;
  /// Output directory (overrides output.dir).
  std::optional<std::filesystem::path> out_dir;
  /// Progress line ("\r step k/n, rate, ETA") on this stream, or none.
  std::ostream* progress = nullptr;
  /// The device engine's launcher (runs with device = "cuda" and method = "none" only;
  /// step_engine_for).
  DeviceLauncher device_launcher = DeviceLauncher::cuda;
  /// Where set, an engine the caller makes takes the run's steps (StepEngine::external; e.g. the
  /// engine across MPI ranks of rpyfmm/mpi/bd_stepper.hpp). Called on every process of the run with
  /// the config, the run's force field, the whole system's positions, types, (with rotation;
  /// empty: the identity) orientations and (with Langevin types; empty: the Maxwell draw)
  /// half-step velocities, and the first step.
  std::function<std::unique_ptr<Stepper>(const RunConfig&, const ForceField&, std::span<const double> positions,
                                         std::span<const std::uint32_t> types, std::span<const double> orientations,
                                         std::span<const double> velocities, std::uint64_t first_step)>
      engine;
  /// The summary's name of the engine `engine` makes (RunSummary::engine; across MPI ranks: "mpi").
  std::string engine_name = "external";
  /// False on the processes of a run across MPI ranks other than the one that writes its files:
  /// they take every step and read every record's state with the writer (the engine's reads may be
  /// collective), but create no file.
  bool writes_files = true;
  /// Where set (runs across processes), called on every process after each of the writer's file
  /// operations with its error, if any; it throws the error on every process (MPI:
  /// Communicator::agree), so that all stop together. Unset: the error propagates as it is.
  std::function<void(const std::optional<Error>&)> agree;
};

struct RunSummary {
  std::size_t particles = 0;
  std::string mobility;  ///< operator name
  /// What ran the steps: "cpu" (Integrator), "cuda" (the device engine), "host launcher" (the
  /// device engine's stages on the host, RunOptions::device_launcher), or a caller's engine by
  /// RunOptions::engine_name ("mpi" across ranks).
  std::string engine = "cpu";
  std::uint64_t first_step = 0, last_step = 0;
  double wall_seconds = 0.0;
  double steps_per_second = 0.0;
  std::uint64_t neighbour_rebuilds = 0;
  double mean_sqrt_iterations = 0.0;      ///< per step
  double mean_mobility_products = 0.0;    ///< per step
  std::size_t preconditioner_blocks = 0;  ///< the last step's block-preconditioner blocks (0: none)
  StageTimes seconds;                     ///< per part (see IntegratorTotals) + "output"
  std::filesystem::path out_dir, trajectory, log, checkpoint;
};

/// Runs `config` from its initial particles. Throws rpyfmm::Error on bad input; on a
/// blow-up the last good state is written to the checkpoint first and the error says so.
RunSummary run_bd(const RunConfig& config, const RunOptions& options = {});

/// Continues the run stored in `checkpoint` (its embedded config is used), bitwise as
/// if it had not been interrupted; trajectory and log (in the checkpoint's directory
/// unless options.out_dir is set) are truncated to the checkpoint and appended to.
RunSummary restart_bd(const std::filesystem::path& checkpoint, const RunOptions& options = {});

}  // namespace rpyfmm::bd
