// rpyfmm::bd::device — the device engine as the Integrator steps it (IntegratorOptions::engine):
// the CUDA engine (DeviceEngine) or the same stages on the host launcher (HostEngine, tests
// without a GPU) behind one interface, with the positions and forces copied to the host only when
// they are read (a trajectory frame, a log row, a checkpoint; docs/gpu-bd.md).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "rpyfmm/bd/device/device_engine.hpp"
#include "rpyfmm/bd/step_engine.hpp"

namespace rpyfmm::bd::device {

class Stepper {
 public:
  virtual ~Stepper() = default;
  /// One step (DeviceEngine::step): on an error the positions stay at the last good step.
  virtual void step() = 0;
  /// The positions at the current step (3N, unwrapped), copied to the host once per step asked
  /// (into the same array: a view of it shows the step it was last read at).
  [[nodiscard]] virtual const std::vector<double>& positions() const = 0;
  /// The forces at the start of the last step (3N; 0 before the first), copied as positions().
  [[nodiscard]] virtual const std::vector<double>& forces() const = 0;
  [[nodiscard]] virtual std::uint64_t step_count() const = 0;
  /// The potential energy at the start of the last step; 0 before the first (as
  /// Integrator::last_report() before a step).
  [[nodiscard]] virtual double potential_energy() const = 0;
  [[nodiscard]] virtual std::size_t rebuilds() const = 0;
  /// Seconds per part: "neighbours", "forces", "update".
  [[nodiscard]] virtual StageTimes stage_times() const = 0;
};

/// The engine of `launcher` for the particles of `types` at `positions` from step first_step
/// (DeviceEngine's constructor: throws naming the bad option, or not_supported naming why no
/// device is usable).
std::unique_ptr<Stepper> make_stepper(DeviceLauncher launcher, const ForceField& forces,
                                      std::vector<std::uint32_t> types, const rpy::Geometry& geometry,
                                      const EngineOptions& options, std::span<const double> positions,
                                      std::uint64_t first_step);

}  // namespace rpyfmm::bd::device
