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

StepEngine step_engine_for(const rpy::MobilitySpec& spec, DeviceLauncher launcher) {
  if (spec.device != rpy::ComputeDevice::cuda || spec.method != rpy::MobilityMethod::none) return StepEngine::cpu;
  return launcher == DeviceLauncher::cuda ? StepEngine::cuda : StepEngine::host_launcher;
}

std::unique_ptr<rpy::MobilityOperator> engine_mobility(const rpy::MobilitySpec& spec, StepEngine engine,
                                                       std::size_t n) {
  rpy::MobilitySpec cpu = spec;
  if (engine != StepEngine::cpu) cpu.device = rpy::ComputeDevice::cpu;
  return rpy::make_mobility(cpu, n);
}

}  // namespace rpyfmm::bd
