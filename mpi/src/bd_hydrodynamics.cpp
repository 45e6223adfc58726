// rpyfmm — the hydrodynamic interactions of distributed Brownian dynamics (bd_hydrodynamics.hpp).
#include "bd_hydrodynamics.hpp"

#include <memory>
#include <string>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/sqrt.hpp"

namespace rpyfmm::mpi {

std::unique_ptr<DistributedBd::Hydrodynamics> DistributedBd::Hydrodynamics::make(MPI_Comm comm,
                                                                                 const DistributedBdOptions& options,
                                                                                 const rpy::Geometry& geometry) {
  const rpy::MobilityMethod method = options.method;
  if (method == rpy::MobilityMethod::none) return nullptr;
  const char* where = "DistributedBd";
  require(
      method == rpy::MobilityMethod::direct || method == rpy::MobilityMethod::fmm, ErrorCode::not_supported, where,
      std::string("mobility method '") + rpy::to_string(method) + "' is not run across ranks (none, direct or fmm)");
  require(geometry.is_open(), ErrorCode::not_supported, where,
          "hydrodynamic interactions across ranks are free-space (direct, fmm): a periodic box needs PSE, which "
          "does not run across ranks yet");
  if (method == rpy::MobilityMethod::direct)
    return std::make_unique<Hydrodynamics>(
        Hydrodynamics{DistributedDirectRpy(comm, options.viscosity), options.integrator.sqrt});
  return std::make_unique<Hydrodynamics>(
      Hydrodynamics{DistributedFmmRpy(comm, options.viscosity, options.fmm), options.integrator.sqrt});
}

rpy::SqrtReport DistributedBd::Hydrodynamics::products(std::span<const double> x, std::span<const double> a,
                                                       std::span<const double> f, std::span<const double> z,
                                                       std::span<double> u, std::span<double> w) {
  return std::visit(
      [&](auto& mobility) {
        mobility.set_positions(x, a);
        mobility.apply(f, u);
        return z.empty() ? rpy::SqrtReport{} : sqrt_apply(mobility, z, w, sqrt);
      },
      op);
}

}  // namespace rpyfmm::mpi
