// rpyfmm — the colouring of the PSE half rows (real_space_sum.hpp): each pair is evaluated once,
// from its lower slot s, which adds the pair's block to row s and to row t > s. A row thus writes
// to its own slot and to larger slots among the 27 cells around it; the cell grid is cut along x
// and y (where they have >= 4 cells) into blocks of >= 2 cells, an even number per axis, and
// blocks of one colour (their parities along the cut axes) never write to the same slot, so each
// colour runs in parallel without atomics (docs/theory/pse.md). Private.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace rpyfmm::rpy::pse::detail {

struct SlotRange {
  std::size_t begin, end;
};

/// Per colour: blocks, each a list of slot ranges.
using HalfBlocks = std::array<std::vector<std::vector<SlotRange>>, 4>;

/// The blocks of the cell grid with nc cells per axis (>= 3 each) whose cells start at the slots
/// cell_begin (CSR over cells, ids (x nc_y + y) nc_z + z).
void plan_half_blocks(const std::array<int, 3>& nc, const std::vector<std::size_t>& cell_begin, HalfBlocks& out);

/// row(s, r) for every half row s and rhs r: colours one after another, the blocks of one colour
/// in parallel.
template <class Row>
void sweep_half_rows(const HalfBlocks& colours, std::size_t n, std::size_t nrhs, Row&& row) {
  for (const auto& colour : colours) {
    const auto nblock = static_cast<std::int64_t>(colour.size());
#pragma omp parallel for schedule(dynamic, 1) if (n * nrhs >= 512)
    for (std::int64_t b = 0; b < nblock; ++b)
      for (const auto& range : colour[static_cast<std::size_t>(b)])
        for (std::size_t s = range.begin; s < range.end; ++s)
          for (std::size_t r = 0; r < nrhs; ++r) row(s, r);
  }
}

}  // namespace rpyfmm::rpy::pse::detail
