// rpyfmm::bd — complex membership of the SAC scheme (sac.hpp).
#include "rpyfmm/bd/sac.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

Complexes::Complexes(const rpy::Geometry& geometry, const std::vector<ParticleType>& type_table,
                     std::span<const std::optional<LangevinParticle>> inertia, std::span<const std::uint32_t> types,
                     double adsorption_factor, NeighbourOptions neighbours)
    : ntypes_(type_table.size()), types_(types.begin(), types.end()) {
  const char* where = "SAC scheme (integrator.scheme = \"sac\")";
  require(std::isfinite(adsorption_factor) && adsorption_factor > 0.0, ErrorCode::invalid_argument, where,
          "adsorption_factor must be finite and > 0");
  const auto carrier_type = [&](std::size_t t) { return t < inertia.size() && inertia[t].has_value(); };
  radius_.assign(ntypes_ * ntypes_, 0.0);
  double max_radius = 0.0;
  for (std::size_t t = 0; t < ntypes_; ++t) {
    for (std::size_t u = 0; u < ntypes_; ++u) {
      if (carrier_type(t) == carrier_type(u)) continue;
      const double ra = adsorption_factor * (type_table[t].radius + type_table[u].radius);
      radius_[t * ntypes_ + u] = ra;
      max_radius = std::max(max_radius, ra);
    }
  }
  const std::size_t n = types_.size();
  carrier_.assign(n, 0);
  std::size_t carriers = 0;
  for (std::size_t i = 0; i < n; ++i) {
    require(types_[i] < ntypes_, ErrorCode::invalid_input, where,
            "particle " + std::to_string(i) + " has an unknown type index " + std::to_string(types_[i]));
    carrier_[i] = carrier_type(types_[i]) ? 1 : 0;
    carriers += carrier_[i];
  }
  require(carriers > 0 && carriers < n, ErrorCode::invalid_input, where,
          "needs at least one carrier (Langevin type) and one adsorbing (Brownian) particle; got " +
              std::to_string(carriers) + " carriers among " + std::to_string(n) + " particles");
  list_.emplace(geometry, max_radius, neighbours);
  owner_.assign(n, kFree);
  offsets_.assign(n + 1, 0);
}

void Complexes::update(std::span<const double> x) {
  const std::size_t n = types_.size();
  require(x.size() == 3 * n, ErrorCode::invalid_input, "SAC scheme",
          "positions has " + std::to_string(x.size()) + " entries, expected 3N = " + std::to_string(3 * n));
  list_->update(x);
  const NeighbourList& list = *list_;
  // Each adsorber independently: the nearest carrier within R_A. Neighbours are sorted by index
  // and only a strictly smaller squared distance replaces the best, so equal distances go to the
  // lower carrier index. The list holds every pair closer than its cutoff (max R_A).
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t best = kFree;
    if (!carrier_[i]) {
      double best2 = 0.0;
      for (std::uint32_t j : list.neighbours(i)) {
        if (!carrier_[j]) continue;
        const double ra = radius_[types_[j] * ntypes_ + types_[i]];
        double d[3];
        list.separation(&x[3 * j], &x[3 * i], d);
        const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        if (r2 < ra * ra && (best == kFree || r2 < best2)) {
          best = j;
          best2 = r2;
        }
      }
    }
    owner_[i] = best;
  }
  // The adsorbed particles per carrier (counting sort over ascending i: each group ascending).
  std::fill(offsets_.begin(), offsets_.end(), 0);
  for (std::size_t i = 0; i < n; ++i)
    if (owner_[i] != kFree) ++offsets_[owner_[i] + 1];
  complexes_ = 0;
  for (std::size_t c = 0; c < n; ++c) {
    if (offsets_[c + 1] > 0) {
      owner_[c] = static_cast<std::uint32_t>(c);
      ++complexes_;
    }
    offsets_[c + 1] += offsets_[c];
  }
  members_.resize(offsets_[n]);
  fill_.assign(offsets_.begin(), offsets_.end() - 1);
  for (std::size_t i = 0; i < n; ++i)
    if (owner_[i] != kFree && !carrier_[i]) members_[fill_[owner_[i]]++] = static_cast<std::uint32_t>(i);
}

}  // namespace rpyfmm::bd
