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
    : sum_(p, box, viscosity, use_table, cache, cache_limit_bytes), r_cut_(p.r_cut) {}

void RealSpaceHalo::set_positions(const Communicator& comm, const rpy::Geometry& geometry, std::span<const double> x) {
  n_ = x.size() / 3;
  const OwnedCells cells = owned_cells(x, geometry);
  const std::vector<std::vector<Box>> regions = gather_regions(comm, region_of(cells));
  exchange_ = IndexExchange{
      .send = select_halo(comm, cells, regions, geometry, r_cut_), .recv_counts = {}, .self = comm.rank()};
  std::vector<double> part(x.begin(), x.end());
  const std::vector<double> halo = exchange_.forward(comm, x.data(), 3, kWhere, "the real-space halo's positions");
  part.insert(part.end(), halo.begin(), halo.end());
  comm.run([&] { sum_.set_positions(part); });
}

void RealSpaceHalo::apply(const Communicator& comm, const double* forces, double* out) const {
  std::vector<double> part_forces(forces, forces + 3 * n_);
  const std::vector<double> halo = exchange_.forward(comm, forces, 3, kWhere, "the real-space halo's forces");
  part_forces.insert(part_forces.end(), halo.begin(), halo.end());
  // The halo's rows are computed and dropped; this rank's rows add to out as the serial operator
  // adds M_r F to M_w F (RealSpaceSum::apply with accumulate).
  std::vector<double> part_out(part_forces.size(), 0.0);
  std::copy(out, out + 3 * n_, part_out.begin());
  sum_.apply(part_forces.data(), part_out.data(), 1, true);
  std::copy(part_out.begin(), part_out.begin() + static_cast<std::ptrdiff_t>(3 * n_), out);
}

}  // namespace rpyfmm::mpi::detail
