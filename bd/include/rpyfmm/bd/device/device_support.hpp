// rpyfmm::bd::device — which CPU engine runs the device engine can take over (docs/gpu-bd.md):
// free draining (the mobility "none") or PSE in a periodic box ("pse", "pse-cuda"; with the split
// sampler), without rotation, inertial (Langevin) particles, the SAC scheme, split displacements
// or force callbacks; and the device engine's options for such a run.
#pragma once

#include <array>

#include "rpyfmm/bd/device/device_engine.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::bd::device {

/// Throws rpyfmm::Error (not_supported) naming the first feature of the run that the device
/// engine lacks (the forces: require_device_forces).
void require_device_support(const IntegratorOptions& options, const rpy::MobilityOperator& mobility);

/// Throws rpyfmm::Error (not_supported) when `forces` has callbacks: they run on the host, and the
/// device engine's step has no host round trip.
void require_device_forces(const ForceField& forces);

/// The device engine's options for the Integrator run given by `options`, `mobility` (its
/// viscosity), `neighbours` and the force field's global force (ForceField::set_global_force),
/// after require_device_support. With a PSE mobility the caller sets EngineOptions::pse to it
/// (the engine's steps move that operator: it is taken by non-const pointer there).
EngineOptions engine_options_for(const IntegratorOptions& options, const rpy::MobilityOperator& mobility,
                                 const NeighbourOptions& neighbours, const std::array<double, 3>& global_force = {});

}  // namespace rpyfmm::bd::device
