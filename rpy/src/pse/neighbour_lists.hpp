// rpyfmm — the neighbour lists of the PSE real-space sum (real_space_sum.hpp): a cell grid of
// cells of edge >= r_cut, the slot order (particles sorted by cell), and per slot the neighbour
// slots within r_cut (minimum image) as CSR rows in ascending slot order. Private.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <vector>

namespace rpyfmm::rpy::pse::detail {

/// Cells per axis (floor(L / r_cut)); `cells`: >= 3 along every axis, so that the 27 cells
/// around a cell are distinct and hold every pair within r_cut. Without cells, one pseudo-cell
/// holds every particle (minimum image).
struct CellGrid {
  std::array<int, 3> nc{};
  bool cells = true;
};
[[nodiscard]] CellGrid cell_grid(const std::array<double, 3>& box, double r_cut);

/// The slot order: order[s] is the input index of slot s, particles sorted by cell (counting
/// sort, stable); without cells, the input order. Returns the first slot of every cell and the
/// end (CSR over cells; {0, n} without cells). x: positions wrapped into [0, L).
std::vector<std::size_t> sort_into_cells(std::span<const double> x, const std::array<double, 3>& box,
                                         const CellGrid& grid, std::vector<std::size_t>& order);

/// pos[d][s] = x[3 order[s] + d].
void gather_positions(std::span<const double> x, const std::vector<std::size_t>& order,
                      std::array<std::vector<double>, 3>& pos);

/// CSR rows: row s is list[begin[s] .. begin[s + 1]).
struct Rows {
  const std::size_t* begin;
  const int* list;
};

/// The list build's input: the grid, its cells' slot ranges, positions by slot, and whether only
/// the pairs t > s are listed (half lists: the neighbour cells of larger id and the later slots
/// of the own cell, half the distance checks).
struct ListRequest {
  const CellGrid& grid;
  const std::vector<std::size_t>& cell_begin;
  const std::array<std::vector<double>, 3>& pos;
  std::array<double, 3> box;
  double r_cut;
  bool half;
};

/// The neighbour slots within r_cut of every slot (r > 0, or coincident particles), ascending.
/// block_lists: per-block scratch whose memory the next build reuses.
void build_neighbour_lists(const ListRequest& request, std::vector<std::vector<int>>& block_lists,
                           std::vector<std::size_t>& begin, std::vector<int>& list);

/// upper[s]: the first entry of row s with a larger slot, i.e. the start of its half row (the
/// rows are ascending, so the half row is the row's tail; with half lists, the whole row).
void half_row_starts(const std::vector<std::size_t>& begin, const std::vector<int>& list, bool half_lists,
                     std::vector<std::size_t>& upper);

/// The full rows from half lists: row t = its lower part {s < t : t in half row s}, ascending,
/// then its half row.
void derive_full_rows(const std::vector<std::size_t>& begin, const std::vector<int>& list,
                      std::vector<std::size_t>& full_begin, std::vector<int>& full_list);

}  // namespace rpyfmm::rpy::pse::detail
