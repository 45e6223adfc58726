// Leaf grid fitted to a cloud (rpyfmm/fmm/leaf_grid.hpp; docs/theory/fmm.md).
#include "rpyfmm/fmm/leaf_grid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::fmm {

LeafGrid fit_leaf_grid(std::span<const double> sources, std::span<const double> targets, int occupancy,
                       double min_fill) {
  constexpr const char* where = "fit_leaf_grid";
  require(occupancy >= 1, ErrorCode::invalid_argument, where,
          "occupancy must be >= 1 point per leaf, got " + std::to_string(occupancy));
  require(min_fill >= 0.0 && min_fill <= 1.0, ErrorCode::invalid_argument, where,
          "min_fill must be in [0, 1], got " + std::to_string(min_fill));
  for (const auto& [pts, name] : {std::pair{sources, "sources"}, std::pair{targets, "targets"}}) {
    require(pts.size() % 3 == 0, ErrorCode::invalid_input, where,
            std::string(name) + " has " + std::to_string(pts.size()) + " entries, not a multiple of 3");
    require_finite(pts, where, name, 3);
  }
  const std::size_t n = sources.size() / 3 + targets.size() / 3;
  LeafGrid grid;
  if (n < 2) return grid;
  // Bounding cube of all points, as the octree takes it.
  std::array<double, 3> lo, hi;
  lo.fill(std::numeric_limits<double>::infinity());
  hi.fill(-std::numeric_limits<double>::infinity());
  for (const auto pts : {sources, targets})
    for (std::size_t j = 0; j < pts.size() / 3; ++j)
      for (int c = 0; c < 3; ++c) {
        lo[c] = std::min(lo[c], pts[3 * j + c]);
        hi[c] = std::max(hi[c], pts[3 * j + c]);
      }
  const double side = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  if (!(side > 0.0) || !std::isfinite(side)) return grid;
  // Occupied fraction of the bounding cube on a grid of ~8 points per cell (at most 32^3 cells).
  const int g = std::clamp(static_cast<int>(std::cbrt(double(n) / 8.0)), 2, 32);
  std::vector<char> occupied(std::size_t(g) * g * g, 0);
  for (const auto pts : {sources, targets})
    for (std::size_t j = 0; j < pts.size() / 3; ++j) {
      std::size_t cell = 0;
      for (int c = 0; c < 3; ++c) {
        const int i = std::clamp(static_cast<int>((pts[3 * j + c] - lo[c]) / side * g), 0, g - 1);
        cell = cell * g + std::size_t(i);
      }
      occupied[cell] = 1;
    }
  const double fill = double(std::count(occupied.begin(), occupied.end(), 1)) / double(occupied.size());
  if (fill < min_fill) return grid;
  // k boxes per side of ~occupancy points each: n = fill k^3 occupancy.
  const auto k = static_cast<int>(std::lround(std::cbrt(double(n) / (fill * occupancy))));
  if (k < 2) return grid;
  int level_boxes = 1;
  while (level_boxes < k) level_boxes *= 2;
  grid.root_scale = double(level_boxes) / double(k);
  grid.leaf_capacity = 2 * occupancy;
  return grid;
}

bool fitted_leaf_grid_pays(std::size_t points, std::size_t cube_leaves, int occupancy) noexcept {
  constexpr double kMinGain = 1.7;
  return occupancy > 0 && double(points) > kMinGain * double(occupancy) * double(cube_leaves);
}

LeafGrid choose_leaf_grid(const FittedGridRule& rule, std::span<const double> sources, std::span<const double> targets,
                          std::size_t cube_leaves, double cube_leaf_level_share) {
  const std::size_t points = sources.size() / 3 + targets.size() / 3;
  if (rule.occupancy == 0 || points < rule.min_points || points > rule.max_points) return {};
  const bool pays = rule.by_mean_occupancy && fitted_leaf_grid_pays(points, cube_leaves, rule.occupancy);
  const bool partial = !pays && cube_leaf_level_share < rule.partial_split_share;
  if (!pays && !partial) return {};
  const double min_fill = partial ? std::max(rule.min_fill, rule.partial_min_fill) : rule.min_fill;
  return fit_leaf_grid(sources, targets, rule.occupancy, min_fill);
}

}  // namespace rpyfmm::fmm
