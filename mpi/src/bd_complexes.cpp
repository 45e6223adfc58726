// rpyfmm — the SAC scheme of DistributedBd (rpyfmm/mpi/brownian_dynamics.hpp; docs/mpi.md, "Brownian
// dynamics across ranks"): Algorithm 2 of Tran et al. (2015) (Sec. 4.2; docs/theory/bd.md Sec. 9)
// as bd::Integrator runs it, on particles distributed over the ranks.
//
// A complex is a carrier (an inertial particle) and the adsorbers (Brownian particles) whose
// nearest carrier lies within R_A (bd::Complexes). The halo reaches max R_A + skin besides the
// pair potentials' list radius, and is rebuilt by the dynamic test, so it holds every carrier
// within R_A of an owned adsorber and every adsorber within R_A of an owned carrier: each rank
// finds its adsorbers' carriers with bd::Complexes on its part (the same distances, the same
// choice among equally near carriers: the lower global index), and the membership travels with the
// halo's values (part_values). A carrier's owner sums its complex's forces from the forces its
// adsorbed particles feel from outside the complex, fetched from their owners, in increasing
// global index as the serial engine sums them; an adsorbed particle's owner adds its carrier's
// displacement, fetched from the carrier's owner. So the positions and velocities are
// bd::Integrator's bit for bit on any number of ranks.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "bd_halo.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "DistributedBd";
constexpr std::uint32_t kFree = bd::Complexes::kFree;
constexpr std::size_t kNoRow = std::numeric_limits<std::size_t>::max();

// The part's row of global index `id` (the part is in increasing global index), or kNoRow.
std::size_t row_of(const DistributedBd::Halo& h, std::uint64_t id) {
  const auto it = std::lower_bound(h.ids.begin(), h.ids.end(), id);
  return it != h.ids.end() && *it == id ? static_cast<std::size_t>(it - h.ids.begin()) : kNoRow;
}

// Each part row's index among the owned particles, or kNoRow for a halo particle.
std::vector<std::size_t> owned_index(const DistributedBd::Halo& h) {
  std::vector<std::size_t> index(h.ids.size(), kNoRow);
  for (std::size_t i = 0; i < h.owned_rows.size(); ++i) index[h.owned_rows[i]] = i;
  return index;
}

}  // namespace

void DistributedBd::check_sac(std::span<const std::uint32_t> share_types) {
  // bd::Integrator's and bd::Complexes' checks, in their order; the options and the counts over
  // all ranks are the same everywhere, so every rank throws alike.
  const bd::IntegratorOptions& o = options_.integrator;
  require(inertial_, ErrorCode::invalid_argument, kWhere,
          "the SAC scheme (integrator.scheme = \"sac\") needs carriers, particles of a Langevin type; "
          "none of the particles has one");
  require(forces_.bonds().empty(), ErrorCode::invalid_argument, kWhere, "the SAC scheme does not support bonds");
  const double factor = o.sac.adsorption_factor;
  require(std::isfinite(factor) && factor > 0.0, ErrorCode::invalid_argument, kWhere,
          "SAC scheme (integrator.scheme = \"sac\"): adsorption_factor must be finite and > 0");
  const auto carrier_type = [&](std::size_t t) { return t < o.inertia.size() && o.inertia[t].has_value(); };
  std::uint64_t mine[2] = {0, share_types.size()}, all[2] = {0, 0};  // carriers, particles
  for (const std::uint32_t t : share_types) mine[0] += carrier_type(t) ? 1 : 0;
  check_mpi(MPI_Allreduce(mine, all, 2, MPI_UINT64_T, MPI_SUM, comm_.get()), "MPI_Allreduce");
  require(all[0] < all[1], ErrorCode::invalid_input, kWhere,
          "SAC scheme: needs at least one carrier (Langevin type) and one adsorbing (Brownian) particle; got " +
              std::to_string(all[0]) + " carriers among " + std::to_string(all[1]) + " particles");
  require(all[1] < kFree, ErrorCode::not_supported, kWhere,
          "SAC scheme: complexes are named by 32-bit particle indices (bd::Complexes), so N must be below 2^32 - 1");
  // max R_A over the pairs of a carrier and an adsorber type, as bd::Complexes computes it.
  const auto& types = forces_.types();
  for (std::size_t t = 0; t < types.size(); ++t)
    for (std::size_t u = 0; u < types.size(); ++u)
      if (carrier_type(t) && !carrier_type(u))
        sac_reach_ = std::max(sac_reach_, factor * (types[t].radius + types[u].radius));
  (void)bd::NeighbourList(geometry_, sac_reach_);  // bd::Complexes' list: its checks of the box, on every rank
  sac_ = true;
}

void DistributedBd::update_complexes() {
  const Halo& h = *halo_;
  const std::size_t n = ids_.size(), m = h.ids.size();
  // A new part (a rebuild) gets its own bd::Complexes; none when it lacks a carrier or an
  // adsorber (then no owned particle is in a complex).
  if (!part_complexes_ || part_complexes_->owner().size() != m || stats_.rebuilds != complexes_rebuild_) {
    part_complexes_.reset();
    const auto& inertia = options_.integrator.inertia;
    const auto carrier = [&](std::uint32_t t) { return t < inertia.size() && inertia[t].has_value(); };
    const bool carriers = std::any_of(h.types.begin(), h.types.end(), carrier);
    const bool adsorbers = !std::all_of(h.types.begin(), h.types.end(), carrier);
    if (carriers && adsorbers)
      part_complexes_.emplace(geometry_, forces_.types(), inertia, h.types, options_.integrator.sac.adsorption_factor);
    complexes_rebuild_ = stats_.rebuilds;
  }
  if (part_complexes_) part_complexes_->update(h.x);
  // Each owned particle's group: its carrier's global index when adsorbed, else its own.
  std::vector<double> group(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t row = h.owned_rows[i];
    const std::uint32_t o = part_complexes_ ? part_complexes_->owner()[row] : kFree;
    group[i] = static_cast<double>(o != kFree && o != row ? h.ids[o] : ids_[i]);
  }
  const std::vector<double> part = h.part_values(comm_, group, 1);
  groups_.resize(m);
  for (std::size_t r = 0; r < m; ++r) groups_[r] = static_cast<std::uint32_t>(part[r]);
  // complex_ids_: an adsorbed particle's carrier; a carrier with adsorbed particles (all in the
  // part, within R_A of it) its own index.
  const std::vector<std::size_t> index = owned_index(h);
  complex_ids_.assign(n, kFree);
  for (std::size_t r = 0; r < m; ++r) {
    if (groups_[r] == h.ids[r]) continue;
    if (index[r] != kNoRow) complex_ids_[index[r]] = groups_[r];
    const std::size_t carrier_row = row_of(h, groups_[r]);
    if (carrier_row != kNoRow && index[carrier_row] != kNoRow) complex_ids_[index[carrier_row]] = groups_[r];
  }
}

void DistributedBd::complex_forces() {
  // bd::Integrator::complex_forces: a carrier's force is its own from outside the complex plus its
  // adsorbed particles' from outside it, in increasing index (the part's order); an adsorbed
  // particle's force adds the forces from inside its complex.
  const Halo& h = *halo_;
  const std::vector<double> outside = h.part_values(comm_, f_, 3);
  const std::vector<std::size_t> index = owned_index(h);
  for (std::size_t r = 0; r < h.ids.size(); ++r) {
    if (groups_[r] == h.ids[r]) continue;
    const std::size_t carrier_row = row_of(h, groups_[r]);
    if (carrier_row == kNoRow || index[carrier_row] == kNoRow) continue;  // the carrier's owner sums it
    const std::size_t c = index[carrier_row];
    for (std::size_t k = 0; k < 3; ++k) f_[3 * c + k] += outside[3 * r + k];
  }
  for (std::size_t i = 0; i < ids_.size(); ++i)
    if (complex_ids_[i] != kFree && complex_ids_[i] != ids_[i])
      for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) f_[k] += f_within_[k];
}

void DistributedBd::follow_carriers(std::vector<double>& next) const {
  // bd::Integrator: dx_a += dx_carrier, then x += dx.
  const Halo& h = *halo_;
  const std::vector<double> part_dx = h.part_values(comm_, dx_, 3);
  for (std::size_t i = 0; i < ids_.size(); ++i) {
    if (complex_ids_[i] == kFree || complex_ids_[i] == ids_[i]) continue;
    const std::size_t carrier_row = row_of(h, complex_ids_[i]);  // in the part: within R_A
    for (std::size_t c = 0; c < 3; ++c)
      next[3 * i + c] = x_[3 * i + c] + (dx_[3 * i + c] + part_dx[3 * carrier_row + c]);
  }
}

std::array<std::uint64_t, 2> DistributedBd::complex_counts() const {
  std::array<std::uint64_t, 2> mine{0, 0}, all{0, 0};  // carriers with adsorbed particles, adsorbed particles
  for (std::size_t i = 0; i < complex_ids_.size(); ++i)
    if (complex_ids_[i] != kFree) ++mine[complex_ids_[i] == ids_[i] ? 0 : 1];
  check_mpi(MPI_Allreduce(mine.data(), all.data(), 2, MPI_UINT64_T, MPI_SUM, comm_.get()), "MPI_Allreduce");
  return all;
}

}  // namespace rpyfmm::mpi
