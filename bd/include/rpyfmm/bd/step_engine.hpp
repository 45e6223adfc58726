// rpyfmm::bd — what steps an Integrator's particles (docs/gpu-bd.md): the CPU engine, or the
// device engine (free draining or PSE, the whole step on a CUDA device), run by CUDA or by its
// host launcher; and the choice made from a mobility spec, as `[mobility] device = "cuda"` with
// `method = "none"` or `"pse"` asks for the device engine in a run configuration and in Python.
#pragma once

#include <cstddef>
#include <memory>

#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"

namespace rpyfmm::bd {

/// The engine of IntegratorOptions::engine.
enum class StepEngine {
  cpu,            ///< the Integrator's own step, any mobility operator and feature
  cuda,           ///< the device engine on a CUDA device (free draining or periodic PSE; docs/gpu-bd.md)
  host_launcher,  ///< the device engine's stages run on the host: its results bit for bit, no GPU needed
  external        ///< an engine the caller gives the Integrator (rpyfmm/bd/stepper.hpp; e.g. across MPI ranks)
};

/// What runs the device engine's stages when a mobility spec asks for it: CUDA, or the host
/// launcher (tests and machines without a GPU).
enum class DeviceLauncher { cuda, host };

/// "cpu", "cuda", "host launcher" or "external".
const char* to_string(StepEngine engine);

/// The engine for `spec`: the device engine, run by `launcher`, where spec asks for the whole step
/// on a CUDA device (device "cuda" with the method "none", or "pse" / "auto" in a periodic box);
/// the CPU engine otherwise.
StepEngine step_engine_for(const rpy::MobilitySpec& spec, DeviceLauncher launcher = DeviceLauncher::cuda);

/// The Integrator's mobility operator for `spec` and `engine`, for n particles: on the device
/// engine with "none" the CPU's free-draining operator, whose viscosity and checks the device
/// engine takes; with "pse" PseRpyCuda on the CUDA engine and PseRpy on the host launcher (the
/// operators the engine's PSE stage moves); otherwise rpy::make_mobility(spec, n).
std::unique_ptr<rpy::MobilityOperator> engine_mobility(const rpy::MobilitySpec& spec, StepEngine engine, std::size_t n);

}  // namespace rpyfmm::bd
