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
#include "rpyfmm/bd/stepper.hpp"

namespace rpyfmm::bd::device {

/// The device engine behind the Integrator's interface (rpyfmm/bd/stepper.hpp).
using Stepper = rpyfmm::bd::Stepper;

/// The engine of `launcher` for the particles of `types` at `positions` from step first_step
/// (DeviceEngine's constructor: throws naming the bad option, or not_supported naming why no
/// device is usable).
std::unique_ptr<Stepper> make_stepper(DeviceLauncher launcher, const ForceField& forces,
                                      std::vector<std::uint32_t> types, const rpy::Geometry& geometry,
                                      const EngineOptions& options, std::span<const double> positions,
                                      std::uint64_t first_step);

}  // namespace rpyfmm::bd::device
