// rpyfmm::bd::device — which CPU engine runs the device engine can take over (docs/gpu-bd.md):
// free draining (the mobility "none") without rotation, inertial (Langevin) particles, the SAC
// scheme or split displacements; and the device engine's options for such a run.
#pragma once

#include <array>

#include "rpyfmm/bd/device/device_engine.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::bd::device {

/// Throws rpyfmm::Error (not_supported) naming the first feature of the run that the device
/// engine lacks. Force callbacks cannot be checked here (ForceField does not report them): the
/// caller must refuse them.
void require_device_support(const IntegratorOptions& options, const rpy::MobilityOperator& mobility);

/// The device engine's options for the Integrator run given by `options`, `mobility` (its
/// viscosity), `neighbours` and the force field's global force (ForceField::set_global_force),
/// after require_device_support.
EngineOptions engine_options_for(const IntegratorOptions& options, const rpy::MobilityOperator& mobility,
                                 const NeighbourOptions& neighbours, const std::array<double, 3>& global_force = {});

}  // namespace rpyfmm::bd::device
