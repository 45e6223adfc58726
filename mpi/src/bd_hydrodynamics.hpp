// rpyfmm — the hydrodynamic interactions of distributed Brownian dynamics (rpyfmm/mpi/
// brownian_dynamics.hpp, docs/mpi.md "Brownian dynamics across ranks"): the RPY mobility of the
// particles of all ranks, in free space by DistributedDirectRpy or DistributedFmmRpy with the
// Brownian displacement w = M^{1/2} z by the Lanczos sampler across ranks (rpyfmm/mpi/sqrt.hpp),
// in a periodic box by DistributedPseRpy with drift and noise in one pass (Positively Split Ewald:
// Fiore, Balboa Usabiaga, Donev & Swan, J. Chem. Phys. 146, 124116 (2017)).
#pragma once

#include <cstdint>
#include <span>
#include <utility>
#include <variant>

#include "rpyfmm/bd/rotation_sampling.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::mpi {

struct DistributedBd::Hydrodynamics {
  /// The Brownian term that the pse operator draws itself, as bd::Integrator asks PseRpy for it
  /// (bd::fused_drift_and_noise): u = M F + scale M^{1/2} z with scale = sqrt(2 kT dt) / dt (0: no
  /// noise, u = M F) and z keyed by (seed, step) and the particles' global indices.
  struct FusedNoise {
    double scale = 0.0;
    std::uint64_t seed = 0, step = 0;
    std::span<const std::uint64_t> ids;
    std::uint64_t total = 0;  ///< the particles of all ranks, N
  };

  std::variant<DistributedDirectRpy, DistributedFmmRpy, DistributedPseRpy> op;
  rpy::SqrtOptions sqrt;
  MPI_Comm comm = MPI_COMM_NULL;  ///< the operator's

  template <class Operator, class... Args>
  Hydrodynamics(std::in_place_type_t<Operator> type, const rpy::SqrtOptions& sampler, Args&&... args)
      : op(type, std::forward<Args>(args)...), sqrt(sampler) {}

  /// Collective: the operator of options.method (direct or fmm in open geometry, pse in a periodic
  /// box; none: nullptr). Throws on every rank for a method the geometry or the ranks do not run,
  /// and for pse with a sampler other than its split one.
  static std::unique_ptr<Hydrodynamics> make(MPI_Comm comm, const DistributedBdOptions& options,
                                             const rpy::Geometry& geometry);

  /// Whether products() draws the noise itself (pse) where the step passes no z (grand_products,
  /// with rotation, is never fused, nor are split displacements: bd::Integrator draws z then).
  [[nodiscard]] bool fused() const { return std::holds_alternative<DistributedPseRpy>(op); }

  /// Collective, for this rank's particles at x with radii a (3 values per particle each; one
  /// radius per particle): direct, fmm: u = M F and, where z is not empty, w = M^{1/2} z; pse:
  /// where z is empty u = M F + noise.scale M^{1/2} z in one pass, w untouched; where z is given
  /// (split displacements) u = M F and w = M^{1/2} z by PseRpy::apply_sqrt's split sampler, its
  /// wave noise keyed by the hash of the whole z in global index order (noise.ids) as the serial
  /// engine's: the particles are sent to the ranks of their blocks of global indices, [r N / P,
  /// (r + 1) N / P), for the two products (one MPI_Alltoallv each way).
  rpy::SqrtReport products(std::span<const double> x, std::span<const double> a, std::span<const double> f,
                           std::span<const double> z, const FusedNoise& noise, std::span<double> u,
                           std::span<double> w);

  /// Collective, with rotation, as bd::rotational_drift_and_noise on the serial operator:
  /// [u; omega] = M [f; t] by the operator's grand mobility and, where z.translation is not empty,
  /// [w_t; w_r] = B [z_t; z_r] by rpyfmm::mpi::sqrt_apply_rotation (direct, fmm) or
  /// DistributedPseRpy::apply_sqrt_rotation with the particles' global indices `ids` (pse).
  rpy::SqrtReport grand_products(std::span<const double> x, std::span<const double> a,
                                 bd::GrandVector<const double> loads, bd::GrandVector<const double> z,
                                 std::span<const std::uint64_t> ids, bd::GrandVector<double> velocities,
                                 bd::GrandVector<double> w);
};

}  // namespace rpyfmm::mpi
