#include "device_stepper.hpp"

#include <utility>

#include "host_engine.hpp"

namespace rpyfmm::bd::device {

namespace {

/// A host copy of one of an engine's arrays, refreshed when read at a step other than the copy's.
class StepCopy {
 public:
  StepCopy(std::vector<double> values, std::uint64_t step) : values_(std::move(values)), step_(step) {}

  [[nodiscard]] std::size_t size() const { return values_.size(); }

  /// The copy at `step`; read() gives the engine's array when the copy is older.
  template <class Read>
  const std::vector<double>& at(std::uint64_t step, Read&& read) {
    if (step_ != step) {
      const auto fresh = read();
      values_.assign(fresh.begin(), fresh.end());  // same size: the array stays where it is
      step_ = step;
    }
    return values_;
  }

 private:
  std::vector<double> values_;
  std::uint64_t step_;
};

/// The engine's arrays in place: device memory on the CUDA engine, host memory on the host launcher.
Stepper::StateView state_of(const DeviceEngine& engine, std::size_t size) {
  return {engine.device_positions(), engine.device_forces(), size, engine.device()};
}

Stepper::StateView state_of(const HostEngine& engine, std::size_t size) {
  return {engine.positions().data(), engine.forces().data(), size, -1};
}

/// Stepper over an engine with DeviceEngine's members (DeviceEngine, HostEngine).
template <class Engine>
class EngineStepper final : public Stepper {
 public:
  EngineStepper(const ForceField& forces, std::vector<std::uint32_t> types, const rpy::Geometry& geometry,
                const EngineOptions& options, std::span<const double> positions, std::uint64_t first_step)
      : engine_(forces, std::move(types), geometry, options, positions, first_step),
        first_step_(first_step),
        x_(std::vector<double>(positions.begin(), positions.end()), first_step),
        f_(std::vector<double>(positions.size(), 0.0), first_step) {}

  void step() override { engine_.step(); }

  [[nodiscard]] const std::vector<double>& positions() const override {
    return x_.at(engine_.step_count(), [this] { return engine_.positions(); });
  }
  [[nodiscard]] const std::vector<double>& forces() const override {
    return f_.at(engine_.step_count(), [this] { return engine_.forces(); });
  }

  [[nodiscard]] std::uint64_t step_count() const override { return engine_.step_count(); }
  [[nodiscard]] double potential_energy() const override {
    return engine_.step_count() == first_step_ ? 0.0 : engine_.potential_energy();
  }
  [[nodiscard]] std::size_t rebuilds() const override { return engine_.rebuilds(); }
  [[nodiscard]] StageTimes stage_times() const override { return engine_.stage_times(); }
  [[nodiscard]] std::optional<DriftNoiseReport> mobility_report() const override { return engine_.mobility_report(); }
  [[nodiscard]] std::optional<StateView> state_view() const override { return state_of(engine_, x_.size()); }

 private:
  Engine engine_;
  std::uint64_t first_step_;
  mutable StepCopy x_, f_;  // host copies, read on request (const reads refresh them)
};

}  // namespace

std::unique_ptr<Stepper> make_stepper(DeviceLauncher launcher, const ForceField& forces,
                                      std::vector<std::uint32_t> types, const rpy::Geometry& geometry,
                                      const EngineOptions& options, std::span<const double> positions,
                                      std::uint64_t first_step) {
  if (launcher == DeviceLauncher::host)
    return std::make_unique<EngineStepper<HostEngine>>(forces, std::move(types), geometry, options, positions,
                                                       first_step);
  return std::make_unique<EngineStepper<DeviceEngine>>(forces, std::move(types), geometry, options, positions,
                                                       first_step);
}

}  // namespace rpyfmm::bd::device
