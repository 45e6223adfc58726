#include "rpyfmm/bd/device/device_support.hpp"

#include <algorithm>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd::device {

void require_device_support(const IntegratorOptions& options, const rpy::MobilityOperator& mobility) {
  const char* where = "bd device engine";
  require(mobility.name() == "none", ErrorCode::not_supported, where,
          "the device engine runs free draining (mobility \"none\") only, not '" + mobility.name() +
              "' (with hydrodynamic interactions use the CPU engine, or method \"pse\" with PSE mobility on the GPU; "
              "docs/gpu-bd.md)");
  require(!options.rotation, ErrorCode::not_supported, where, "rotation is not supported on the device");
  const bool inertial =
      std::any_of(options.inertia.begin(), options.inertia.end(), [](const auto& type) { return type.has_value(); });
  require(!inertial, ErrorCode::not_supported, where, "inertial (Langevin) particles are not supported on the device");
  require(!options.sac.enabled, ErrorCode::not_supported, where, "the SAC scheme is not supported on the device");
  require(!options.keep_split_displacements, ErrorCode::not_supported, where,
          "split displacements (keep_split_displacements) are not kept on the device");
}

void require_device_forces(const ForceField& forces) {
  require(!forces.has_callbacks(), ErrorCode::not_supported, "bd device engine",
          "force callbacks (ForceField::add_callback) run on the host and are not supported on the device "
          "(its step has no host round trip); give the forces as pair potentials, bonds, external forces or the "
          "trap, or use the CPU engine");
}

EngineOptions engine_options_for(const IntegratorOptions& options, const rpy::MobilityOperator& mobility,
                                 const NeighbourOptions& neighbours, const std::array<double, 3>& global_force) {
  require_device_support(options, mobility);
  EngineOptions o;
  o.dt = options.dt;
  o.kT = options.kT;
  o.seed = options.seed;
  o.max_displacement = options.max_displacement;
  o.viscosity = mobility.viscosity();
  o.global_force = global_force;
  o.neighbours = neighbours;
  return o;
}

}  // namespace rpyfmm::bd::device
