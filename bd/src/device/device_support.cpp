#include "rpyfmm/bd/device/device_support.hpp"

#include <algorithm>
#include <string>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/pse/pse_operator.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::bd::device {

namespace {

/// True for the periodic PSE operators the device engine's PSE stage runs ("pse" on the host
/// launcher, "pse-cuda" on the CUDA engine; the open-geometry "pse-open" is not one).
bool periodic_pse(const rpy::MobilityOperator& mobility) {
  const bool named = mobility.name() == "pse" || mobility.name() == "pse-cuda";
  return named && mobility.geometry().is_periodic() && dynamic_cast<const rpy::pse::PseOperator*>(&mobility) != nullptr;
}

}  // namespace

void require_device_support(const IntegratorOptions& options, const rpy::MobilityOperator& mobility) {
  const char* where = "bd device engine";
  const bool pse = periodic_pse(mobility);
  require(mobility.name() == "none" || pse, ErrorCode::not_supported, where,
          "the device engine runs free draining (mobility \"none\") or PSE in a periodic box (\"pse\"), not '" +
              mobility.name() + "' (use the CPU engine; docs/gpu-bd.md)");
  const rpy::SqrtMethod sampler = options.sqrt.method;
  require(!pse || sampler == rpy::SqrtMethod::automatic || sampler == rpy::SqrtMethod::split, ErrorCode::not_supported,
          where,
          std::string("PSE on the device samples the noise by its split sampler (sqrt method automatic or split), "
                      "not '") +
              rpy::to_string(sampler) + "'");
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
  o.sqrt = options.sqrt;  // EngineOptions::pse is the caller's to set: the engine moves that operator
  return o;
}

}  // namespace rpyfmm::bd::device
