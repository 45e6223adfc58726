// rpyfmm — the tree of cells over one rank's owned particles, in key order (docs/mpi.md,
// "Distributed Laplace FMM"): the cells of the global octree (prefixes of the Morton or Hilbert keys
// of SfcPartition) that hold this rank's particles, split while they hold more than a capacity, with
// the tight bounding box of their particles. The locally essential tree is cut from it. Nothing here
// decodes a key into coordinates: a cell's children are the runs of equal next digit, in the
// curve's order, and its geometry is its particles' box, so both curves give valid trees.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace rpyfmm::mpi::detail {

/// An axis-aligned box [lo, hi].
struct Box {
  std::array<double, 3> lo{}, hi{};
};

/// The cube that a cell's anterpolation uses: centre and half-side (the largest half-extent of
/// the tight box; 0 when its particles coincide).
struct Cube {
  std::array<double, 3> center{};
  double half = 0.0;
};

/// A cell: owned particles [begin, end) (a contiguous range of the owned order), its level (0: the
/// whole key cube), its children [first_child, first_child + child_count) in `cells`, and the
/// tight box of its particles.
struct Cell {
  std::size_t begin = 0, end = 0;
  int level = 0;
  std::uint32_t first_child = 0, child_count = 0;
  Box box;
  [[nodiscard]] std::size_t size() const { return end - begin; }
  [[nodiscard]] bool leaf() const { return child_count == 0; }
};

/// cells[0] is the root (all owned particles); empty when there are none.
struct CellTree {
  std::vector<Cell> cells;
};

/// Not collective. keys: the owned particles' keys (Morton or Hilbert, SfcPartition), increasing;
/// positions: 3 per particle in the same order. A cell is split into its non-empty octants while it
/// holds more than `capacity` (>= 1) particles and lies above the keys' finest level (21).
[[nodiscard]] CellTree build_cell_tree(std::span<const std::uint64_t> keys, std::span<const double> positions,
                                       std::size_t capacity);

/// A cover of the tree's particles by at most `max_boxes` tight boxes (>= 1): the deepest
/// frontier of cells (leaves above it kept) with no more than that many cells; empty for an empty
/// tree.
[[nodiscard]] std::vector<Box> region_cover(const CellTree& tree, std::size_t max_boxes);

/// The cube of a cell (Cube above).
[[nodiscard]] Cube cell_cube(const Cell& cell);

/// The Euclidean distance between a cube and a box (0 when they touch or overlap).
[[nodiscard]] double distance(const Cube& cube, const Box& box);

}  // namespace rpyfmm::mpi::detail
