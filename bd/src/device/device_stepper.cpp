#include "device_stepper.hpp"

#include <utility>

#include "host_engine.hpp"

namespace rpyfmm::bd::device {

namespace {

/// Stepper over an engine with DeviceEngine's members (DeviceEngine, HostEngine).
template <class Engine>
class EngineStepper final : public Stepper {
 public:
  EngineStepper(const ForceField& forces, std::vector<std::uint32_t> types, const rpy::Geometry& geometry,
                const EngineOptions& options, std::span<const double> positions, std::uint64_t first_step)
      : engine_(forces, std::move(types), geometry, options, positions, first_step),
        first_step_(first_step),
        x_(positions.begin(), positions.end()),
        x_step_(first_step) {}

  void step() override { engine_.step(); }

  const std::vector<double>& positions() override {
    if (x_step_ != engine_.step_count()) {
      const auto x = engine_.positions();
      x_.assign(x.begin(), x.end());
      x_step_ = engine_.step_count();
    }
    return x_;
  }

  [[nodiscard]] std::uint64_t step_count() const override { return engine_.step_count(); }
  [[nodiscard]] double potential_energy() const override {
    return engine_.step_count() == first_step_ ? 0.0 : engine_.potential_energy();
  }
  [[nodiscard]] std::size_t rebuilds() const override { return engine_.rebuilds(); }
  [[nodiscard]] StageTimes stage_times() const override { return engine_.stage_times(); }

 private:
  Engine engine_;
  std::uint64_t first_step_;
  std::vector<double> x_;  // the positions at step x_step_
  std::uint64_t x_step_;
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
