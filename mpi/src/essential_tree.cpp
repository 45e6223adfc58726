// rpyfmm — the cells one rank sends to another (essential_tree.hpp).
#include "essential_tree.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rpyfmm::mpi::detail {
namespace {

// The distance from a cube to the nearest box of a region.
double nearest_distance(const Cube& cube, std::span<const Box> region) {
  double nearest = std::numeric_limits<double>::infinity();
  for (const Box& box : region) nearest = std::min(nearest, distance(cube, box));
  return nearest;
}

// A distance in units of the cube's half-side (infinite for a cube of side 0 away from every box).
double relative_distance(double nearest, const Cube& cube) {
  if (nearest == 0.0) return 0.0;
  return cube.half > 0.0 ? nearest / cube.half : std::numeric_limits<double>::infinity();
}

}  // namespace

int order_at(double tolerance, double eta, int max_order) {
  const double rho = eta + std::sqrt(1.0 + eta * eta);
  int p = 2;
  while (p < max_order && std::pow(rho, -p) > 0.1 * tolerance) ++p;
  return p;
}

int compressed_order(const Cube& cube, std::size_t particles, std::span<const Box> region,
                     const Acceptance& acceptance) {
  const double nearest = nearest_distance(cube, region);
  const double eta = relative_distance(nearest, cube);
  if (eta < acceptance.separation || nearest < acceptance.min_distance) return 0;
  const int p =
      acceptance.fixed_order > 0 ? acceptance.fixed_order : order_at(acceptance.tolerance, eta, acceptance.max_order);
  const auto nodes = static_cast<std::size_t>(p) * static_cast<std::size_t>(p) * static_cast<std::size_t>(p);
  return particles > nodes ? p : 0;
}

EssentialCells essential_cells(const CellTree& tree, std::span<const Box> region, const Acceptance& acceptance) {
  EssentialCells sent;
  if (tree.cells.empty() || region.empty()) return sent;
  std::vector<std::uint32_t> stack{0};
  while (!stack.empty()) {
    const std::uint32_t c = stack.back();
    stack.pop_back();
    const Cell& cell = tree.cells[c];
    if (const int p = compressed_order(cell_cube(cell), cell.size(), region, acceptance); p > 0) {
      sent.compressed.push_back(Compressed{c, p});
    } else if (cell.leaf()) {
      sent.halo.push_back(c);
    } else {
      // Opened: its children are smaller, so further in units of their size and of lower order, and
      // they never send more values than its particles. In reverse, so that cells are sent in
      // increasing order of their particles.
      for (std::uint32_t k = cell.child_count; k-- > 0;) stack.push_back(cell.first_child + k);
    }
  }
  return sent;
}

}  // namespace rpyfmm::mpi::detail
