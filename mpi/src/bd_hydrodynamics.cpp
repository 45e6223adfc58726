// rpyfmm — the hydrodynamic interactions of distributed Brownian dynamics (bd_hydrodynamics.hpp).
#include "bd_hydrodynamics.hpp"

#include <memory>
#include <string>
#include <type_traits>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/sqrt.hpp"

namespace rpyfmm::mpi {

std::unique_ptr<DistributedBd::Hydrodynamics> DistributedBd::Hydrodynamics::make(MPI_Comm comm,
                                                                                 const DistributedBdOptions& options,
                                                                                 const rpy::Geometry& geometry) {
  using rpy::MobilityMethod;
  const MobilityMethod method = options.method;
  if (method == MobilityMethod::none) return nullptr;
  const char* where = "DistributedBd";
  const rpy::SqrtOptions& sampler = options.integrator.sqrt;
  require(method == MobilityMethod::direct || method == MobilityMethod::fmm || method == MobilityMethod::pse,
          ErrorCode::not_supported, where,
          std::string("mobility method '") + rpy::to_string(method) +
              "' is not run across ranks (none, direct or fmm in free space, pse in a periodic box)");
  if (method == MobilityMethod::pse) {
    require(geometry.is_periodic(), ErrorCode::not_supported, where,
            "mobility method 'pse' across ranks needs a periodic box (DistributedPseRpy); in free space use direct "
            "or fmm");
    // bd::Integrator fuses drift and noise with PseRpy for these samplers only (bd::fuses_drift_and_noise).
    require(sampler.method == rpy::SqrtMethod::automatic || sampler.method == rpy::SqrtMethod::split,
            ErrorCode::not_supported, where,
            std::string("mobility method 'pse' across ranks samples by PSE's split sampler (integrator.sqrt.method "
                        "automatic or split), not '") +
                rpy::to_string(sampler.method) + "'");
    return std::make_unique<Hydrodynamics>(std::in_place_type<DistributedPseRpy>, sampler, comm, geometry,
                                           options.viscosity, options.pse);
  }
  require(geometry.is_open(), ErrorCode::not_supported, where,
          std::string("mobility method '") + rpy::to_string(method) +
              "' across ranks is free-space (direct, fmm): a periodic box needs pse");
  if (method == MobilityMethod::direct)
    return std::make_unique<Hydrodynamics>(std::in_place_type<DistributedDirectRpy>, sampler, comm, options.viscosity);
  return std::make_unique<Hydrodynamics>(std::in_place_type<DistributedFmmRpy>, sampler, comm, options.viscosity,
                                         options.fmm);
}

rpy::SqrtReport DistributedBd::Hydrodynamics::products(std::span<const double> x, std::span<const double> a,
                                                       std::span<const double> f, std::span<const double> z,
                                                       const FusedNoise& noise, std::span<double> u,
                                                       std::span<double> w) {
  return std::visit(
      [&](auto& mobility) {
        mobility.set_positions(x, a);
        if constexpr (std::is_same_v<std::decay_t<decltype(mobility)>, DistributedPseRpy>) {
          if (noise.scale > 0.0) return mobility.apply_with_noise(f, noise.scale, noise.seed, noise.step, noise.ids, u);
          mobility.apply(f, u);
          return rpy::SqrtReport{};
        } else {
          mobility.apply(f, u);
          return z.empty() ? rpy::SqrtReport{} : sqrt_apply(mobility, z, w, sqrt);
        }
      },
      op);
}

rpy::SqrtReport DistributedBd::Hydrodynamics::grand_products(std::span<const double> x, std::span<const double> a,
                                                             bd::GrandVector<const double> loads,
                                                             bd::GrandVector<const double> z,
                                                             std::span<const std::uint64_t> ids,
                                                             bd::GrandVector<double> velocities,
                                                             bd::GrandVector<double> w) {
  return std::visit(
      [&](auto& mobility) {
        mobility.set_positions(x, a);
        mobility.apply(loads.translation, loads.rotation, velocities.translation, velocities.rotation);
        if (z.translation.empty()) return rpy::SqrtReport{};
        if constexpr (std::is_same_v<std::decay_t<decltype(mobility)>, DistributedPseRpy>) {
          // PseRpy::apply_sqrt_rotation's wave noise is keyed by the hash of the whole z in the
          // serial (global index) order.
          return mobility.apply_sqrt_rotation(z.translation, z.rotation, ids, w.translation, w.rotation, sqrt);
        } else {
          return sqrt_apply_rotation(mobility, z.translation, z.rotation, w.translation, w.rotation, sqrt);
        }
      },
      op);
}

}  // namespace rpyfmm::mpi
