// rpyfmm — the tree of cells over a rank's owned particles (cell_tree.hpp).
#include "cell_tree.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rpyfmm/mpi/partition.hpp"

namespace rpyfmm::mpi::detail {
namespace {

// The digit (0..7) of a key at `level` + 1: the three key bits below the level's prefix, the rank of
// the child cell along the curve (its octant for Morton keys; partition.hpp).
unsigned digit(std::uint64_t key, int level) {
  return static_cast<unsigned>(key >> (3 * (kMortonBitsPerAxis - level - 1))) & 7u;
}

Box tight_box(std::span<const double> positions, std::size_t begin, std::size_t end) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  Box b{{kInf, kInf, kInf}, {-kInf, -kInf, -kInf}};
  for (std::size_t i = begin; i < end; ++i) {
    for (std::size_t d = 0; d < 3; ++d) {
      b.lo[d] = std::min(b.lo[d], positions[3 * i + d]);
      b.hi[d] = std::max(b.hi[d], positions[3 * i + d]);
    }
  }
  return b;
}

}  // namespace

CellTree build_cell_tree(std::span<const std::uint64_t> keys, std::span<const double> positions, std::size_t capacity) {
  CellTree tree;
  if (keys.empty()) return tree;
  tree.cells.push_back(Cell{0, keys.size(), 0, 0, 0, tight_box(positions, 0, keys.size())});
  // Breadth first: the children of a cell are appended together, so they are contiguous.
  for (std::size_t c = 0; c < tree.cells.size(); ++c) {
    const Cell parent = tree.cells[c];
    if (parent.size() <= capacity || parent.level >= kMortonBitsPerAxis) continue;
    tree.cells[c].first_child = static_cast<std::uint32_t>(tree.cells.size());
    std::size_t begin = parent.begin;
    for (unsigned k = 0; k < 8 && begin < parent.end; ++k) {
      const auto stop = std::partition_point(keys.begin() + static_cast<std::ptrdiff_t>(begin),
                                             keys.begin() + static_cast<std::ptrdiff_t>(parent.end),
                                             [&](std::uint64_t key) { return digit(key, parent.level) <= k; });
      const auto end = static_cast<std::size_t>(stop - keys.begin());
      if (end == begin) continue;
      tree.cells.push_back(Cell{begin, end, parent.level + 1, 0, 0, tight_box(positions, begin, end)});
      ++tree.cells[c].child_count;
      begin = end;
    }
  }
  return tree;
}

std::vector<Box> region_cover(const CellTree& tree, std::size_t max_boxes) {
  if (tree.cells.empty()) return {};
  std::vector<std::uint32_t> frontier{0};
  for (;;) {
    std::vector<std::uint32_t> next;
    for (std::uint32_t c : frontier) {
      const Cell& cell = tree.cells[c];
      if (cell.leaf()) {
        next.push_back(c);
      } else {
        for (std::uint32_t k = 0; k < cell.child_count; ++k) next.push_back(cell.first_child + k);
      }
    }
    if (next.size() > max_boxes || next.size() == frontier.size()) break;
    frontier = std::move(next);
  }
  std::vector<Box> boxes;
  boxes.reserve(frontier.size());
  for (std::uint32_t c : frontier) boxes.push_back(tree.cells[c].box);
  return boxes;
}

Cube cell_cube(const Cell& cell) {
  Cube cube;
  for (std::size_t d = 0; d < 3; ++d) {
    cube.center[d] = 0.5 * cell.box.lo[d] + 0.5 * cell.box.hi[d];
    cube.half = std::max(cube.half, 0.5 * cell.box.hi[d] - 0.5 * cell.box.lo[d]);
  }
  return cube;
}

double distance(const Cube& cube, const Box& box) {
  std::array<double, 3> gap{};
  for (std::size_t d = 0; d < 3; ++d) {
    gap[d] = std::max({0.0, box.lo[d] - (cube.center[d] + cube.half), (cube.center[d] - cube.half) - box.hi[d]});
  }
  return std::hypot(gap[0], gap[1], gap[2]);  // without overflow of the squares
}

}  // namespace rpyfmm::mpi::detail
