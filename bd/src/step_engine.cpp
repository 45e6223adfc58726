#include "rpyfmm/bd/step_engine.hpp"

namespace rpyfmm::bd {

const char* to_string(StepEngine engine) {
  switch (engine) {
    case StepEngine::cuda:
      return "cuda";
    case StepEngine::host_launcher:
      return "host launcher";
    case StepEngine::external:
      return "external";
    case StepEngine::cpu:
      break;
  }
  return "cpu";
}

namespace {

/// True where make_mobility builds periodic PSE for `spec` ("pse", or "auto" in a periodic box).
bool asks_for_pse(const rpy::MobilitySpec& spec) {
  return spec.method == rpy::MobilityMethod::pse ||
         (spec.method == rpy::MobilityMethod::automatic && spec.geometry.is_periodic());
}

}  // namespace

StepEngine step_engine_for(const rpy::MobilitySpec& spec, DeviceLauncher launcher) {
  const bool device_method = spec.method == rpy::MobilityMethod::none || asks_for_pse(spec);
  if (spec.device != rpy::ComputeDevice::cuda || !device_method) return StepEngine::cpu;
  return launcher == DeviceLauncher::cuda ? StepEngine::cuda : StepEngine::host_launcher;
}

std::unique_ptr<rpy::MobilityOperator> engine_mobility(const rpy::MobilitySpec& spec, StepEngine engine,
                                                       std::size_t n) {
  // The CUDA engine's PSE stage moves PseRpyCuda on the device; the host launcher runs the CPU's
  // PseRpy, and free draining is the engine's own (its operator gives the viscosity).
  rpy::MobilitySpec cpu = spec;
  const bool device_operator = engine == StepEngine::cuda && asks_for_pse(spec);
  if (engine != StepEngine::cpu && !device_operator) cpu.device = rpy::ComputeDevice::cpu;
  return rpy::make_mobility(cpu, n);
}

}  // namespace rpyfmm::bd
