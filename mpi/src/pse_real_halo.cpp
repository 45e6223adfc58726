// rpyfmm — the real-space part of DistributedPseRpy on a rank's particles and its halo
// (pse_real_halo.hpp).
//
// Row i of M_r F sums over the particles within r_cut of particle i (minimum image; the box is at
// least 2 r_cut wide, pse_parameters.hpp). Every such particle of another rank lies within r_cut of
// a box of this rank's region (a cover of its particles by tight boxes), so it is in the halo: the
// rows of this rank's particles in a sum over its particles and the halo hold the same pairs, with
// the same displacements (the same wrapped positions), as the serial sum's rows; only the order of
// the additions differs. The halo's own rows are incomplete and dropped.
#include "pse_real_halo.hpp"

#include <algorithm>

#include "bd_halo.hpp"

namespace rpyfmm::mpi::detail {
namespace {
constexpr const char* kWhere = "DistributedPseRpy";
}  // namespace

RealSpaceHalo::RealSpaceHalo(const rpy::pse::PseParameters& p, const std::array<double, 3>& box, double viscosity,
                             bool use_table, rpy::pse::detail::PairCache cache, std::size_t cache_limit_bytes)
    : sum_(p, box, viscosity, use_table, cache, cache_limit_bytes),
      params_(p),
      box_(box),
      viscosity_(viscosity),
      r_cut_(p.r_cut) {}

void RealSpaceHalo::set_positions(const Communicator& comm, const rpy::Geometry& geometry, std::span<const double> x) {
  n_ = x.size() / 3;
  const OwnedCells cells = owned_cells(x, geometry);
  const std::vector<std::vector<Box>> regions = gather_regions(comm, region_of(cells));
  exchange_ = IndexExchange{.send = select_halo(comm, cells, regions, geometry, r_cut_),
                            .recv_counts = {},
                            .self = comm.rank(),
                            .traffic = {}};
  x_.assign(x.begin(), x.end());
  const std::vector<double> halo = exchange_.forward(comm, x.data(), 3, kWhere, "the real-space halo's positions");
  x_.insert(x_.end(), halo.begin(), halo.end());
  comm.run([&] { sum_.set_positions(x_); });
}

std::vector<double> RealSpaceHalo::with_halo(const Communicator& comm, const double* values, const char* what) const {
  std::vector<double> part(values, values + 3 * n_);
  const std::vector<double> halo = exchange_.forward(comm, values, 3, kWhere, what);
  part.insert(part.end(), halo.begin(), halo.end());
  return part;
}

void RealSpaceHalo::apply(const Communicator& comm, const double* forces, double* out) const {
  const std::vector<double> part_forces = with_halo(comm, forces, "the real-space halo's forces");
  // The halo's rows are computed and dropped; this rank's rows add to out as the serial operator
  // adds M_r F to M_w F (RealSpaceSum::apply with accumulate).
  std::vector<double> part_out(part_forces.size(), 0.0);
  std::copy(out, out + 3 * n_, part_out.begin());
  sum_.apply(part_forces.data(), part_out.data(), 1, true);
  std::copy(part_out.begin(), part_out.begin() + static_cast<std::ptrdiff_t>(3 * n_), out);
}

void RealSpaceHalo::apply_rotation(const Communicator& comm, const double* forces, const double* torques,
                                   double* velocities, double* angular) const {
  if (!rotation_) {
    comm.run([&] { rotation_ = std::make_unique<rpy::pse::detail::RotationRealSpaceSum>(params_, box_, viscosity_); });
  }
  const std::vector<double> part_forces = with_halo(comm, forces, "the real-space halo's forces");
  const std::vector<double> part_torques = with_halo(comm, torques, "the real-space halo's torques");
  // PseRpy's order: M_r^{UF} F added to the wave part's U, then the rotational blocks to U and W;
  // the halo's rows are computed and dropped.
  std::vector<double> part_u(part_forces.size(), 0.0), part_w(part_forces.size(), 0.0);
  std::copy(velocities, velocities + 3 * n_, part_u.begin());
  std::copy(angular, angular + 3 * n_, part_w.begin());
  sum_.apply(part_forces.data(), part_u.data(), 1, true);
  rotation_->apply(sum_.slot_lists(), x_, part_forces.data(), part_torques.data(), part_u.data(), part_w.data());
  const auto own = static_cast<std::ptrdiff_t>(3 * n_);
  std::copy(part_u.begin(), part_u.begin() + own, velocities);
  std::copy(part_w.begin(), part_w.begin() + own, angular);
}

}  // namespace rpyfmm::mpi::detail
