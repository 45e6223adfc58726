// rpyfmm — particles sorted by cell: the part of a cell list that the BD neighbour list
// (bd/src/neighbour_list.cpp) and the PSE real-space lists (rpy/src/pse/neighbour_lists.cpp) share.
// Each computes its particles' cells on its own grid (open or periodic, its own cell size), sorts
// them here, then builds its rows from the slot order (BD: Verlet rows with a skin, in particle
// order; PSE: slot-ordered rows with SIMD distance filters and half lists).
#pragma once

#include <cstddef>
#include <span>
#include <vector>

namespace rpyfmm {

/// Items sorted by cell: order[s] is the item in slot s; cell k holds the slots
/// [cell_begin[k], cell_begin[k + 1]).
struct CellSort {
  std::vector<std::size_t> order;
  std::vector<std::size_t> cell_begin;
};

/// Stable counting sort of the items by cell_of[i] < cells: within a cell, slots keep the items'
/// input order, so the order is a function of the cells alone (same on every thread count).
inline void sort_by_cell(std::span<const std::size_t> cell_of, std::size_t cells, CellSort& out) {
  out.cell_begin.assign(cells + 1, 0);
  for (std::size_t k : cell_of) ++out.cell_begin[k + 1];
  for (std::size_t k = 0; k < cells; ++k) out.cell_begin[k + 1] += out.cell_begin[k];
  std::vector<std::size_t> fill(out.cell_begin.begin(), out.cell_begin.end() - 1);
  out.order.resize(cell_of.size());
  for (std::size_t i = 0; i < cell_of.size(); ++i) out.order[fill[cell_of[i]]++] = i;
}

}  // namespace rpyfmm
