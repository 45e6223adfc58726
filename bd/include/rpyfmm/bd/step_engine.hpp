// rpyfmm::bd — what steps an Integrator's particles (docs/gpu-bd.md): the CPU engine, or the
// device engine (free draining, the whole step on a CUDA device), run by CUDA or by its host
// launcher; and the choice made from a mobility spec, as `[mobility] device = "cuda"` with
// `method = "none"` asks for the device engine in a run configuration and in Python.
#pragma once

#include <cstddef>
#include <memory>

#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"

namespace rpyfmm::bd {

/// The engine of IntegratorOptions::engine.
enum class StepEngine {
  cpu,            ///< the Integrator's own step, any mobility operator and feature
  cuda,           ///< the device engine on a CUDA device (free draining only; docs/gpu-bd.md)
  host_launcher,  ///< the device engine's stages run on the host: its results bit for bit, no GPU needed
  external        ///< an engine the caller gives the Integrator (rpyfmm/bd/stepper.hpp; e.g. across MPI ranks)
};

/// What runs the device engine's stages when a mobility spec asks for it: CUDA, or the host
/// launcher (tests and machines without a GPU).
enum class DeviceLauncher { cuda, host };

/// "cpu", "cuda", "host launcher" or "external".
const char* to_string(StepEngine engine);

/// The engine for `spec`: the device engine, run by `launcher`, where spec asks for the whole step
/// on a CUDA device (device "cuda" with the free-draining method "none"); the CPU engine otherwise
/// (device "cuda" with method "pse" is the CPU engine with the PSE operator on the GPU).
StepEngine step_engine_for(const rpy::MobilitySpec& spec, DeviceLauncher launcher = DeviceLauncher::cuda);

/// The Integrator's mobility operator for `spec` and `engine`, for n particles: on the device
/// engine the CPU's free-draining operator, whose viscosity and checks the device engine takes;
/// otherwise rpy::make_mobility(spec, n).
std::unique_ptr<rpy::MobilityOperator> engine_mobility(const rpy::MobilitySpec& spec, StepEngine engine, std::size_t n);

}  // namespace rpyfmm::bd
