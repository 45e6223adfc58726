// rpyfmm — the hydrodynamic interactions of distributed Brownian dynamics (rpyfmm/mpi/
// brownian_dynamics.hpp, docs/mpi.md "Brownian dynamics across ranks"): the RPY mobility of the
// particles of all ranks by DistributedDirectRpy or DistributedFmmRpy, and the Brownian
// displacement w = M^{1/2} z by the Lanczos sampler across ranks (rpyfmm/mpi/sqrt.hpp).
#pragma once

#include <span>
#include <variant>

#include "rpyfmm/mpi/brownian_dynamics.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::mpi {

struct DistributedBd::Hydrodynamics {
  std::variant<DistributedDirectRpy, DistributedFmmRpy> op;
  rpy::SqrtOptions sqrt;

  /// Collective: the operator of options.method (direct or fmm; none: nullptr). Throws on every
  /// rank for a periodic geometry (the operators are free-space) and a sampler the ranks do not run.
  static std::unique_ptr<Hydrodynamics> make(MPI_Comm comm, const DistributedBdOptions& options,
                                             const rpy::Geometry& geometry);

  /// Collective: u = M F and, where z is not empty, w = M^{1/2} z for this rank's particles at x
  /// with radii a (3 values per particle each; one radius per particle).
  rpy::SqrtReport products(std::span<const double> x, std::span<const double> a, std::span<const double> f,
                           std::span<const double> z, std::span<double> u, std::span<double> w);
};

}  // namespace rpyfmm::mpi
