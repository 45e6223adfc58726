// rpyfmm::bd::device — particles sorted into the cells of a CellGrid by a counting sort, one
// stage per function (one thread per particle, slot or cell in a kernel; a loop on the host):
//
//   bin_particle   cell of particle i and its rank among the cell's particles (atomic count);
//   (exclusive scan of the counts: each cell's first slot)
//   place_particle particle i into slot start[cell] + rank;
//   sort_cell      a cell's slots by particle index: the ranks of concurrent threads come in any
//                  order, sorted they give the stable order of rpyfmm::sort_by_cell
//                  (rpyfmm/core/cell_sort.hpp), so the slot order is a function of the positions;
//   gather_slot    the wrapped position and the type of the particle in each slot.
//
// The slots run along the grid, so that the rows built from them (verlet_rows.hpp) read their
// candidates from a few contiguous runs: the locality of the sort by hash key of Tran et al. (2015)
// (Algorithm 1, line 4).
#pragma once

#include <cstdint>

#include "atomics.hpp"
#include "cell_grid.hpp"
#include "insertion_sort.hpp"
#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::bd::device {

/// The arrays of one binning (device or host memory; cells = grid.cells()).
struct CellBins {
  std::uint32_t* cell_of = nullptr;  ///< per particle: its cell
  std::uint32_t* rank = nullptr;     ///< per particle: its place among its cell's particles
  std::uint32_t* count = nullptr;    ///< per cell + 1: particles counted (zeroed before binning)
  std::uint32_t* start = nullptr;    ///< per cell + 1: first slot (exclusive scan of count)
  std::uint32_t* order = nullptr;    ///< per slot: the particle in it
};

RPYFMM_HOST_DEVICE inline void bin_particle(std::uint32_t i, const double* x, const CellGrid& grid,
                                            const CellBins& bins) {
  const auto cell = static_cast<std::uint32_t>(grid.cell_of(x + 3 * static_cast<std::uint64_t>(i)));
  bins.cell_of[i] = cell;
  bins.rank[i] = fetch_increment(&bins.count[cell]);
}

RPYFMM_HOST_DEVICE inline void place_particle(std::uint32_t i, const CellBins& bins) {
  bins.order[bins.start[bins.cell_of[i]] + bins.rank[i]] = i;
}

RPYFMM_HOST_DEVICE inline void sort_cell(std::uint64_t cell, const CellBins& bins) {
  insertion_sort(bins.order + bins.start[cell], bins.start[cell + 1] - bins.start[cell]);
}

/// xs (3 per slot): the slot's particle's position wrapped into the box; ts: its type.
RPYFMM_HOST_DEVICE inline void gather_slot(std::uint32_t slot, const double* x, const std::uint32_t* type,
                                           const CellGrid& grid, const CellBins& bins, double* xs, std::uint32_t* ts) {
  const std::uint64_t i = bins.order[slot];
  for (int c = 0; c < 3; ++c) xs[3 * static_cast<std::uint64_t>(slot) + c] = grid.wrapped(x[3 * i + c], c);
  ts[slot] = type[i];
}

}  // namespace rpyfmm::bd::device
