// rpyfmm::bd — the silica-alumina complexes (SACs) of Algorithm 2 of Tran et al. (2015)
// (Sec. 4.2; docs/theory/bd.md Sec. 9).
//
// Large inertial particles (the Langevin types, "carriers": alumina in the paper) adsorb small
// Brownian ones ("adsorbers": silica). A small particle whose centre lies closer than
//     R_A = adsorption_factor x (a_carrier + a_adsorber)        (paper: R_A = 1.05 (a_A + a_S))
// to a carrier's centre is adsorbed to it. Within R_A of several carriers, the paper picks one
// arbitrarily; here the rule is deterministic: the carrier at the smallest centre-to-centre
// distance (compared as squared distances), ties to the lower carrier index. A carrier and its
// adsorbed particles form one complex; membership depends only on the current positions, so it
// is recomputed at every step and a restart needs no stored membership.
//
// Detection runs over a Verlet list of radius max R_A (neighbour_list.hpp, cell grid + dynamic
// rebuild test of the paper's Algorithm 1): O(N) per step, not O(N_carriers x N_adsorbers).
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/langevin.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"

namespace rpyfmm::bd {

/// The SAC scheme's options ([integrator] scheme = "sac", adsorption_factor).
struct SacOptions {
  bool enabled = false;
  /// R_A / (a_carrier + a_adsorber), > 0 (the paper's 1.05).
  double adsorption_factor = 1.05;
};

/// Complex membership of the particles of a run (see the header).
class Complexes {
 public:
  /// owner() of a particle in no complex.
  static constexpr std::uint32_t kFree = std::numeric_limits<std::uint32_t>::max();

  Complexes() = default;
  /// Carriers: the types t with inertia[t] set; adsorbers: the others. Throws unless the factor
  /// is finite and > 0 and both kinds exist among `types` (N particle types).
  Complexes(const rpy::Geometry& geometry, const std::vector<ParticleType>& type_table,
            std::span<const std::optional<LangevinParticle>> inertia, std::span<const std::uint32_t> types,
            double adsorption_factor, NeighbourOptions neighbours = {});

  /// Recomputes the membership at `positions` (3N). Deterministic, independent of the thread count
  /// and of when the list was last rebuilt.
  void update(std::span<const double> positions);

  [[nodiscard]] bool empty() const { return owner_.empty(); }
  /// N entries: the carrier index of the particle's complex (a carrier with adsorbed particles:
  /// its own index), or kFree.
  [[nodiscard]] std::span<const std::uint32_t> owner() const { return owner_; }
  /// Whether particle i is a carrier type.
  [[nodiscard]] bool is_carrier(std::size_t i) const { return carrier_[i] != 0; }
  /// The adsorbed particles of carrier c, ascending (empty when c has none or is no carrier).
  [[nodiscard]] std::span<const std::uint32_t> adsorbed(std::size_t c) const {
    return {members_.data() + offsets_[c], offsets_[c + 1] - offsets_[c]};
  }
  /// Carriers with at least one adsorbed particle.
  [[nodiscard]] std::size_t count() const { return complexes_; }
  /// Adsorbed particles in all complexes.
  [[nodiscard]] std::size_t adsorbed_total() const { return members_.size(); }
  /// Mean adsorbed particles per complex (0 without complexes).
  [[nodiscard]] double mean_adsorbed() const {
    return complexes_ == 0 ? 0.0 : static_cast<double>(members_.size()) / static_cast<double>(complexes_);
  }
  /// R_A between the types of particles i and j when one is a carrier and the other an adsorber
  /// (else 0).
  [[nodiscard]] double adsorption_radius(std::uint32_t type_i, std::uint32_t type_j) const {
    return radius_[type_i * ntypes_ + type_j];
  }

 private:
  std::size_t ntypes_ = 0;
  std::vector<double> radius_;          // ntypes^2: R_A between a carrier and an adsorber type, else 0
  std::vector<std::uint32_t> types_;    // N
  std::vector<char> carrier_;           // N: 1 = carrier
  std::optional<NeighbourList> list_;   // radius max R_A
  std::vector<std::uint32_t> owner_;    // N
  std::vector<std::size_t> offsets_;    // N + 1: adsorbed particles of carrier c in members_
  std::vector<std::uint32_t> members_;  // adsorbed particles grouped by carrier, ascending
  std::vector<std::size_t> fill_;       // N: work array of update()
  std::size_t complexes_ = 0;
};

}  // namespace rpyfmm::bd
