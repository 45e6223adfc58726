// rpyfmm::bd::device — one particle's Verlet row: every j != i within its pair's list radius
// r_c(t_i, t_j) + skin at the build, sorted by j (Tran et al. (2015), Sec. 3.1 and Algorithm 1,
// line 7; docs/theory/bd.md). One implementation for all engines: the CPU engine's NeighbourList
// (bd/src/neighbour_list.cpp) visits the same cells and pairs with its own sink (rows appended
// to per-thread buffers), the device engines in two passes, count then fill, so that the rows
// sit in one array at offsets from a prefix sum (the CPU engine's layout). Sorted rows make the
// order of a particle's pair-force sum that of the CPU engine.
//
// Candidates come from the 27 cells around the particle's own (cell_binning.hpp): a neighbour
// cell across a periodic face carries its image shift, added to x_i, and the test d^2 < r_L^2
// reads the wrapped positions in slot order. Where the rows come from all pairs instead (fewer
// than 64 particles, or a periodic grid with fewer than 3 cells a side), visit_all_pairs
// compares every pair with the minimum image.
#pragma once

#include <cstdint>

#include "cell_grid.hpp"
#include "insertion_sort.hpp"
#include "minimum_image.hpp"
#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::bd::device {

/// The squared list radius of each pair of types (ntypes x ntypes; 0: never listed).
struct ListRadii {
  const double* rl2 = nullptr;
  std::uint32_t ntypes = 1;
};

/// The particles in slot order (after gather_slot).
struct SlotView {
  const std::uint32_t* order = nullptr;    ///< slot -> particle
  const std::uint32_t* start = nullptr;    ///< cell -> first slot (cells + 1)
  const std::uint32_t* cell_of = nullptr;  ///< particle -> cell
  const double* xs = nullptr;              ///< wrapped positions by slot
  const std::uint32_t* ts = nullptr;       ///< types by slot
};

/// Where a visit puts the neighbours it finds: counted only (row null: the count pass), or
/// also written to row (the fill pass, into the space the count pass sized).
struct RowSink {
  std::uint32_t* row = nullptr;  ///< nullptr: count only
  std::uint64_t size = 0;
  RPYFMM_HOST_DEVICE void add(std::uint32_t j) {
    if (row != nullptr) row[size] = j;
    ++size;
  }
};

/// Adds to `sink` (RowSink, or any type with add(j)) the neighbours (particle indices, unsorted)
/// of the particle in `slot` from the 27 cells around its cell.
template <class Sink>
RPYFMM_HOST_DEVICE inline void visit_stencil(std::uint32_t slot, const CellGrid& g, const SlotView& s,
                                             const ListRadii& radii, Sink& sink) {
  const std::uint64_t home = s.cell_of[s.order[slot]];
  const std::int64_t h[3] = {
      static_cast<std::int64_t>(home / static_cast<std::uint64_t>(g.nc[1] * g.nc[2])),
      static_cast<std::int64_t>((home / static_cast<std::uint64_t>(g.nc[2])) % static_cast<std::uint64_t>(g.nc[1])),
      static_cast<std::int64_t>(home % static_cast<std::uint64_t>(g.nc[2]))};
  const double* xi = s.xs + 3 * static_cast<std::uint64_t>(slot);
  const double* rl2 = radii.rl2 + static_cast<std::uint64_t>(s.ts[slot]) * radii.ntypes;
  for (std::int64_t dx = -1; dx <= 1; ++dx) {
    for (std::int64_t dy = -1; dy <= 1; ++dy) {
      for (std::int64_t dz = -1; dz <= 1; ++dz) {
        std::int64_t k[3] = {h[0] + dx, h[1] + dy, h[2] + dz};
        double shift[3] = {0.0, 0.0, 0.0};  // added to xi - xj: the image across a face
        bool skip = false;
        for (int c = 0; c < 3; ++c) {
          if (g.wrap) {  // k in [-1, nc]
            if (k[c] < 0) {
              k[c] += g.nc[c];
              shift[c] = g.box[c];
            } else if (k[c] >= g.nc[c]) {
              k[c] -= g.nc[c];
              shift[c] = -g.box[c];
            }
          } else if (k[c] < 0 || k[c] >= g.nc[c]) {
            skip = true;
          }
        }
        if (skip) continue;
        const std::uint64_t cell = g.index(k[0], k[1], k[2]);
        const double xi0 = xi[0] + shift[0], xi1 = xi[1] + shift[1], xi2 = xi[2] + shift[2];
        for (std::uint32_t t = s.start[cell]; t < s.start[cell + 1]; ++t) {
          const double* xt = s.xs + 3 * static_cast<std::uint64_t>(t);
          const double d0 = xi0 - xt[0], d1 = xi1 - xt[1], d2 = xi2 - xt[2];
          if (d0 * d0 + d1 * d1 + d2 * d2 < rl2[s.ts[t]] && t != slot) sink.add(s.order[t]);
        }
      }
    }
  }
}

/// Adds to `sink` the neighbours of particle i among all n particles (unwrapped positions x,
/// types by particle), the minimum image in a periodic box.
template <class Sink>
RPYFMM_HOST_DEVICE inline void visit_all_pairs(std::uint32_t i, std::uint32_t n, const double* x,
                                               const std::uint32_t* type, const MinimumImage& image,
                                               const ListRadii& radii, Sink& sink) {
  const double* rl2 = radii.rl2 + static_cast<std::uint64_t>(type[i]) * radii.ntypes;
  for (std::uint32_t j = 0; j < n; ++j) {
    if (j == i) continue;
    double d[3];
    image.separation(x + 3 * static_cast<std::uint64_t>(i), x + 3 * static_cast<std::uint64_t>(j), d);
    if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < rl2[type[j]]) sink.add(j);
  }
}

/// The rows being built: the count pass writes particle i's row length to offsets[i + 1] (a scan
/// then turns them into offsets, offsets[0] = 0), the fill pass writes the rows.
struct RowsBuild {
  std::uint64_t* offsets = nullptr;  ///< n + 1
  std::uint32_t* indices = nullptr;  ///< offsets[n]
};

/// Count pass over the cells, for the particle in `slot`.
RPYFMM_HOST_DEVICE inline void count_row_from_cells(std::uint32_t slot, const CellGrid& g, const SlotView& s,
                                                    const ListRadii& radii, const RowsBuild& rows) {
  RowSink sink;
  visit_stencil(slot, g, s, radii, sink);
  rows.offsets[s.order[slot] + 1ull] = sink.size;
}

/// Fill pass over the cells, for the particle in `slot`: its row, sorted.
RPYFMM_HOST_DEVICE inline void fill_row_from_cells(std::uint32_t slot, const CellGrid& g, const SlotView& s,
                                                   const ListRadii& radii, const RowsBuild& rows) {
  RowSink sink{rows.indices + rows.offsets[s.order[slot]], 0};
  visit_stencil(slot, g, s, radii, sink);
  insertion_sort(sink.row, sink.size);
}

/// Count pass over all pairs, for particle i.
RPYFMM_HOST_DEVICE inline void count_row_from_all(std::uint32_t i, std::uint32_t n, const double* x,
                                                  const std::uint32_t* type, const MinimumImage& image,
                                                  const ListRadii& radii, const RowsBuild& rows) {
  RowSink sink;
  visit_all_pairs(i, n, x, type, image, radii, sink);
  rows.offsets[i + 1ull] = sink.size;
}

/// Fill pass over all pairs, for particle i (ascending j: sorted as found).
RPYFMM_HOST_DEVICE inline void fill_row_from_all(std::uint32_t i, std::uint32_t n, const double* x,
                                                 const std::uint32_t* type, const MinimumImage& image,
                                                 const ListRadii& radii, const RowsBuild& rows) {
  RowSink sink{rows.indices + rows.offsets[i], 0};
  visit_all_pairs(i, n, x, type, image, radii, sink);
}

}  // namespace rpyfmm::bd::device
