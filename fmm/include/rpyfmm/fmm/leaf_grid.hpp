// rpyfmm::fmm — leaves of a chosen occupancy: the leaf capacity and root scale that fit the
// octree's leaf grid to a point cloud (FmmOptions::leaf_capacity, FmmOptions::root_scale).
//
// An octree over the bounding cube of a uniform cloud has leaves of N / 8^L points: the
// occupancy moves in factor-8 steps (N = 1e5: 24 or 195 points). Enlarging the root to 2^L / k
// bounding-cube sides, anchored at the low corner, makes k boxes per side span the cloud at
// level L, so k can be any integer: leaves of about N / (fill k^3) points, where fill is the
// fraction of the bounding cube the points occupy (docs/theory/fmm.md).
#pragma once

#include <cstddef>
#include <span>

namespace rpyfmm::fmm {

/// A leaf grid: the octree parameters that give it.
struct LeafGrid {
  int leaf_capacity = 0;  // 0: no fitted grid (keep the bounding-cube tree)
  double root_scale = 1.0;
  [[nodiscard]] bool fitted() const noexcept { return leaf_capacity > 0; }
};

/// The grid whose leaves hold about `occupancy` points of `sources` and `targets` together (both
/// 3N, xyz interleaved; targets may be empty), or no grid (fitted() false) where the points fill
/// less than `min_fill` of their bounding cube, or where fewer than two boxes per side would
/// result. The fill is measured on a histogram of ~8 points per cell (at most 32^3 cells); the
/// capacity is 2 x occupancy, so that leaves of ~occupancy points stay and their parents (~8x)
/// split. O(N). Throws rpyfmm::Error for occupancy < 1, min_fill outside [0, 1], coordinate
/// arrays whose length is not a multiple of 3, or non-finite coordinates.
[[nodiscard]] LeafGrid fit_leaf_grid(std::span<const double> sources, std::span<const double> targets, int occupancy,
                                     double min_fill = 0.0);

/// Whether a fitted grid of `occupancy` points per leaf can pay for `points` points whose
/// bounding-cube tree has `cube_leaves` leaves: only where that tree's leaves hold on average more
/// than 1.7 x the target (cost ~ occupancy / target + target / occupancy; closer to the target the
/// fitted tree's extra level and partial boxes at the far faces cost more than they save; measured:
/// FmmRpy at N = 3e5 and 1e-6, 73 points per leaf in the bounding cube, fitted 6% slower).
[[nodiscard]] bool fitted_leaf_grid_pays(std::size_t points, std::size_t cube_leaves, int occupancy) noexcept;

/// When a fitted grid replaces the bounding-cube tree: a measured rule per caller and tolerance
/// (LaplaceFmm's automatic leaves, FmmRpy's; FmmOptions::fitted_grid).
struct FittedGridRule {
  int occupancy = 0;                           // target points per leaf; 0: never fit
  std::size_t min_points = 0, max_points = 0;  // point counts (sources + targets) where it applies
  double min_fill = 0.0;  // fit only clouds that fill at least this much of their cube (fit_leaf_grid)
  // Fit where the bounding-cube tree's leaves hold well above the occupancy (fitted_leaf_grid_pays).
  bool by_mean_occupancy = true;
  // Also fit where the bounding-cube tree is partly split: fewer than this share of the points in
  // its most populated leaf level (TreeStats::leaf_level_share); 0: never. Such clouds must fill at
  // least partial_min_fill (and min_fill) of their cube.
  double partial_split_share = 0.0;
  double partial_min_fill = 0.0;
};

/// The grid that `rule` chooses for `sources` and `targets` (as fit_leaf_grid), whose bounding-cube
/// tree has `cube_leaves` leaves and leaf-level share `cube_leaf_level_share`; no grid (fitted()
/// false) where the rule does not apply or fit_leaf_grid finds none.
[[nodiscard]] LeafGrid choose_leaf_grid(const FittedGridRule& rule, std::span<const double> sources,
                                        std::span<const double> targets, std::size_t cube_leaves,
                                        double cube_leaf_level_share);

}  // namespace rpyfmm::fmm
