// rpyfmm — the hydrodynamic interactions of distributed Brownian dynamics (bd_hydrodynamics.hpp).
#include "bd_hydrodynamics.hpp"

#include <algorithm>
#include <memory>
#include <numeric>
#include <string>
#include <type_traits>
#include <vector>

#include "alltoallv.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/sqrt.hpp"

namespace rpyfmm::mpi {
namespace {

// u = M F and w = M^{1/2} z by PSE on the particles in blocks of global indices: rank r holds
// [r N / P, (r + 1) N / P) in increasing index, so that DistributedPseRpy::apply_sqrt's hash of
// the whole z in rank order is PseRpy::apply_sqrt's in global index order (the serial engine's).
// Each particle travels as (owner rank, id, x, a, f, z) and its (id, u, w) come back.
rpy::SqrtReport pse_split_in_index_blocks(const Communicator& comm, DistributedPseRpy& pse, std::span<const double> x,
                                          std::span<const double> a, std::span<const double> f,
                                          std::span<const double> z, std::span<const std::uint64_t> ids,
                                          std::uint64_t total, std::span<double> u, std::span<double> w,
                                          const rpy::SqrtOptions& sqrt) {
  constexpr const char* where = "DistributedBd";
  constexpr std::size_t kOut = 12, kBack = 7;
  const auto p = static_cast<std::uint64_t>(comm.size());
  std::vector<std::vector<double>> send(comm.size());
  for (std::size_t i = 0; i < ids.size(); ++i) {
    std::vector<double>& to = send[static_cast<std::size_t>((ids[i] * p) / total)];
    to.insert(to.end(), {static_cast<double>(comm.rank()), static_cast<double>(ids[i])});
    to.insert(to.end(), &x[3 * i], &x[3 * i + 3]);
    to.push_back(a[i]);
    to.insert(to.end(), &f[3 * i], &f[3 * i + 3]);
    to.insert(to.end(), &z[3 * i], &z[3 * i + 3]);
  }
  const std::vector<double> got = detail::alltoallv(comm, send, where, "the particles for PSE's split sampler");
  const std::size_t m = got.size() / kOut;
  std::vector<std::size_t> order(m);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(),
            [&](std::size_t i, std::size_t j) { return got[kOut * i + 1] < got[kOut * j + 1]; });
  std::vector<double> xb(3 * m), ab(m), fb(3 * m), zb(3 * m), ub(3 * m), wb(3 * m);
  for (std::size_t k = 0; k < m; ++k) {
    const double* v = &got[kOut * order[k]];
    std::copy(v + 2, v + 5, &xb[3 * k]);
    ab[k] = v[5];
    std::copy(v + 6, v + 9, &fb[3 * k]);
    std::copy(v + 9, v + 12, &zb[3 * k]);
  }
  pse.set_positions(xb, ab);
  pse.apply(fb, ub);
  const rpy::SqrtReport report = pse.apply_sqrt(zb, wb, sqrt);
  std::vector<std::vector<double>> back(comm.size());
  for (std::size_t k = 0; k < m; ++k) {
    const double* v = &got[kOut * order[k]];
    std::vector<double>& to = back[static_cast<std::size_t>(v[0])];
    to.push_back(v[1]);
    to.insert(to.end(), &ub[3 * k], &ub[3 * k + 3]);
    to.insert(to.end(), &wb[3 * k], &wb[3 * k + 3]);
  }
  const std::vector<double> mine = detail::alltoallv(comm, back, where, "PSE's split products");
  for (std::size_t k = 0; kBack * k < mine.size(); ++k) {
    const double* v = &mine[kBack * k];
    const auto i = static_cast<std::size_t>(std::lower_bound(ids.begin(), ids.end(), static_cast<std::uint64_t>(v[0])) -
                                            ids.begin());
    std::copy(v + 1, v + 4, &u[3 * i]);
    std::copy(v + 4, v + 7, &w[3 * i]);
  }
  return report;
}

}  // namespace

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
    auto pse = std::make_unique<Hydrodynamics>(std::in_place_type<DistributedPseRpy>, sampler, comm, geometry,
                                               options.viscosity, options.pse);
    pse->comm = comm;
    return pse;
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
        if constexpr (std::is_same_v<std::decay_t<decltype(mobility)>, DistributedPseRpy>) {
          if (!z.empty())
            return pse_split_in_index_blocks(Communicator(comm), mobility, x, a, f, z, noise.ids, noise.total, u, w,
                                             sqrt);
          mobility.set_positions(x, a);
          if (noise.scale > 0.0) return mobility.apply_with_noise(f, noise.scale, noise.seed, noise.step, noise.ids, u);
          mobility.apply(f, u);
          return rpy::SqrtReport{};
        } else {
          mobility.set_positions(x, a);
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
