// rpyfmm::bd — cell list + Verlet neighbour list with a skin (Tran et al. (2015), Sec. 3.1 and
// Algorithm 1; docs/theory/bd.md).
//
// Every particle i stores all j != i with |x_i - x_j| < r_L = r_c + skin at the
// last build, sorted by j. The list is rebuilt only when some particle has moved
// more than skin/2 since the last build (Algorithm 1, lines 15-16): then no
// pair can have come closer than r_c unseen. Sorting makes the order in which
// forces are summed independent of when the list was built, so trajectories do
// not depend on the rebuild schedule (restarts continue bitwise identically).
//
// Open geometry: the cell grid spans the particles' bounding box at each build
// (the box grows with the particles). Periodic geometry: minimum image, r_L must
// not exceed half the smallest box length; positions may be unwrapped.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::bd {

struct NeighbourOptions {
  /// Skin r_L - r_c (> 0 when a cutoff is set). 0 = automatic: 0.3 r_c.
  double skin = 0.0;
  /// 0 = dynamic rebuild test (Tran et al. (2015), Algorithm 1); n > 0 = rebuild every n steps
  /// regardless (the fixed-interval strategy of its Table 1, for comparison only:
  /// it can miss pairs when particles move fast).
  int fixed_interval = 0;
};

class NeighbourList {
 public:
  /// `cutoff` r_c >= 0 (0: no pair interactions, the list stays empty).
  NeighbourList(rpy::Geometry geometry, double cutoff, NeighbourOptions options = {});

  /// Rebuilds when needed (first call, moved > skin/2, or fixed interval reached).
  /// Returns true when it rebuilt. `positions` is 3N, finite.
  bool update(std::span<const double> positions);
  /// Unconditional rebuild.
  void build(std::span<const double> positions);
  /// A list radius per pair of particle types (each interaction kind with its own cut-off, as
  /// Tran et al. (2015), Sec. 4.2, keep one list per kind): from the next build, a pair (i, j) is listed
  /// only within cutoffs[t_i * ntypes + t_j] + skin (a cut-off of 0: never, the pair does not
  /// interact). The skin and the rebuild test stay those of cutoff(), the largest, so no pair can
  /// come within its own cut-off unlisted: sums over the rows skip the same pairs beyond their
  /// cut-offs and give the same result bit for bit as with one radius for all, from much shorter
  /// rows where small particles interact over shorter ranges than large ones. Throws unless
  /// `cutoffs` holds ntypes^2 finite values in [0, cutoff()] and every type is < ntypes;
  /// particle_types must hold one entry per particle of the positions built.
  void set_pair_cutoffs(std::span<const std::uint32_t> particle_types, std::span<const double> cutoffs,
                        std::size_t ntypes);

  [[nodiscard]] double cutoff() const { return cutoff_; }
  [[nodiscard]] double list_radius() const { return cutoff_ + skin_; }
  [[nodiscard]] double skin() const { return skin_; }
  [[nodiscard]] std::size_t rebuilds() const { return rebuilds_; }
  [[nodiscard]] std::size_t size() const { return offsets_.empty() ? 0 : offsets_.size() - 1; }
  /// Neighbours of particle i (indices j, sorted).
  [[nodiscard]] std::span<const std::uint32_t> neighbours(std::size_t i) const {
    return {indices_.data() + offsets_[i], offsets_[i + 1] - offsets_[i]};
  }
  [[nodiscard]] std::size_t pair_entries() const { return indices_.size(); }
  [[nodiscard]] const rpy::Geometry& geometry() const { return geometry_; }

  /// d = x_i - x_j, minimum image in a periodic box.
  void separation(const double* xi, const double* xj, double d[3]) const {
    for (int c = 0; c < 3; ++c) {
      d[c] = xi[c] - xj[c];
      if (periodic_) d[c] -= box_[c] * std::nearbyint(d[c] * inv_box_[c]);
    }
  }

 private:
  void build_all_pairs(std::span<const double> positions);
  void build_cells(std::span<const double> positions);
  /// The squared list radius of each pair of types (set_pair_cutoffs), or `single` set to the one
  /// r_L^2 of all pairs without them.
  [[nodiscard]] std::span<const double> squared_list_radii(std::vector<double>& single) const;
  /// Each particle's type (all 0 without set_pair_cutoffs).
  [[nodiscard]] std::vector<std::uint32_t> particle_types(std::size_t n) const;

  rpy::Geometry geometry_;
  bool periodic_;
  std::array<double, 3> box_{};
  std::array<double, 3> inv_box_{};
  double cutoff_;
  double skin_;
  NeighbourOptions options_;
  std::size_t rebuilds_ = 0;
  std::size_t steps_since_build_ = 0;
  std::vector<double> reference_;  // positions at the last build
  std::vector<std::size_t> offsets_;
  std::vector<std::uint32_t> indices_;
  // set_pair_cutoffs: each particle's type and (r_c(t1, t2) + skin)^2 per pair of types (0: never
  // listed); empty: one radius for all.
  std::vector<std::uint32_t> types_;
  std::vector<double> pair_rl2_;
  std::size_t ntypes_ = 0;
};

}  // namespace rpyfmm::bd
