// rpyfmm::bd::device — the cell grid of a neighbour-list build (Tran et al. (2015), Sec. 3.1: a
// uniform grid of cells of edge >= r_L = r_c + skin, so that a particle's neighbours lie in the
// 27 cells around its own): the grid, the cell of a position and the wrapped coordinates. One
// implementation for all engines: the CPU engine's NeighbourList (bd/src/neighbour_list.cpp)
// and the device engines bin with it, so the same cells give the same image shifts and the same
// in-or-out decisions for every pair, bit for bit.
#pragma once

#include <math.h>  // ::floor

#include <algorithm>
#include <cstdint>

#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::bd::device {

struct CellGrid {
  double lo[3] = {0.0, 0.0, 0.0};
  double extent[3] = {1.0, 1.0, 1.0};
  double box[3] = {0.0, 0.0, 0.0};
  double inv_box[3] = {0.0, 0.0, 0.0};
  std::int64_t nc[3] = {1, 1, 1};
  bool periodic = false;
  /// Periodic with >= 3 cells a side: the 27-cell stencil names 27 distinct cells.
  bool wrap = false;

  [[nodiscard]] RPYFMM_HOST_DEVICE std::uint64_t cells() const {
    return static_cast<std::uint64_t>(nc[0] * nc[1] * nc[2]);
  }
  [[nodiscard]] RPYFMM_HOST_DEVICE std::uint64_t index(std::int64_t k0, std::int64_t k1, std::int64_t k2) const {
    return static_cast<std::uint64_t>((k0 * nc[1] + k1) * nc[2] + k2);
  }
  /// Coordinate c of v, wrapped into [0, L) in a periodic box.
  [[nodiscard]] RPYFMM_HOST_DEVICE double wrapped(double v, int c) const {
    return periodic ? v - box[c] * ::floor(v * inv_box[c]) : v;
  }
  /// The cell coordinate along axis c of a position's coordinate v (clamped into the grid).
  [[nodiscard]] RPYFMM_HOST_DEVICE std::int64_t cell_coord(double v, int c) const {
    const double u = wrapped(v - lo[c], c);
    const auto k = static_cast<std::int64_t>(u / extent[c] * static_cast<double>(nc[c]));
    return k < 0 ? 0 : (k > nc[c] - 1 ? nc[c] - 1 : k);
  }
  /// The cell of the particle at x (3 coordinates).
  [[nodiscard]] RPYFMM_HOST_DEVICE std::uint64_t cell_of(const double* x) const {
    return index(cell_coord(x[0], 0), cell_coord(x[1], 1), cell_coord(x[2], 2));
  }
};

/// The grid for n particles within [lo, hi] (open geometry: their bounding box; periodic: lo and
/// hi ignored, the box) and list radius rl: cells of edge >= rl, at most ~ 2n cells.
inline CellGrid make_cell_grid(const double lo[3], const double hi[3], double rl, std::uint64_t n, bool periodic,
                               const double box[3]) {
  CellGrid g;
  g.periodic = periodic;
  for (int c = 0; c < 3; ++c) {
    g.box[c] = periodic ? box[c] : 0.0;
    g.inv_box[c] = periodic ? 1.0 / box[c] : 0.0;
    g.lo[c] = periodic ? 0.0 : lo[c];
    g.extent[c] = periodic ? box[c] : std::max(hi[c] - lo[c], 1e-300);
    g.nc[c] = std::max<std::int64_t>(1, static_cast<std::int64_t>(::floor(g.extent[c] / rl)));
  }
  // Keep the grid at most ~ 2N cells (sparse open clouds).
  while (static_cast<double>(g.nc[0]) * static_cast<double>(g.nc[1]) * static_cast<double>(g.nc[2]) >
         2.0 * static_cast<double>(n) + 27.0) {
    for (auto& v : g.nc) v = std::max<std::int64_t>(1, v / 2);
  }
  g.wrap = periodic && g.nc[0] >= 3 && g.nc[1] >= 3 && g.nc[2] >= 3;
  return g;
}

/// The grid of a build of the n particles at x (3n unwrapped coordinates): open geometry, their
/// bounding box; periodic, the box.
inline CellGrid cell_grid_of(const double* x, std::uint64_t n, double rl, bool periodic, const double box[3]) {
  double lo[3] = {x[0], x[1], x[2]}, hi[3] = {x[0], x[1], x[2]};
  if (!periodic) {
    for (std::uint64_t i = 0; i < n; ++i) {
      for (int c = 0; c < 3; ++c) {
        lo[c] = std::min(lo[c], x[3 * i + c]);
        hi[c] = std::max(hi[c], x[3 * i + c]);
      }
    }
  }
  return make_cell_grid(lo, hi, rl, n, periodic, box);
}

}  // namespace rpyfmm::bd::device
