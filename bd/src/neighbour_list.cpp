#include "rpyfmm/bd/neighbour_list.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "rpyfmm/core/cell_sort.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

NeighbourList::NeighbourList(rpy::Geometry geometry, double cutoff, NeighbourOptions options)
    : geometry_(geometry), periodic_(geometry.is_periodic()), cutoff_(cutoff), skin_(options.skin), options_(options) {
  const char* where = "NeighbourList";
  require(std::isfinite(cutoff) && cutoff >= 0.0, ErrorCode::invalid_argument, where,
          "cutoff must be finite and >= 0, got " + std::to_string(cutoff));
  require(std::isfinite(options.skin) && options.skin >= 0.0, ErrorCode::invalid_argument, where,
          "skin must be finite and >= 0, got " + std::to_string(options.skin));
  require(options.fixed_interval >= 0, ErrorCode::invalid_argument, where, "fixed_interval must be >= 0");
  if (skin_ == 0.0) skin_ = 0.3 * cutoff_;
  if (periodic_) {
    box_ = geometry.box();
    for (int c = 0; c < 3; ++c) {
      inv_box_[c] = 1.0 / box_[c];
      require(list_radius() <= 0.5 * box_[c], ErrorCode::invalid_argument, where,
              "cutoff + skin = " + std::to_string(list_radius()) + " exceeds half the box length " +
                  std::to_string(box_[c]) + " (minimum image would fail)");
    }
  }
}

bool NeighbourList::update(std::span<const double> positions) {
  bool rebuild = reference_.size() != positions.size();
  if (!rebuild && cutoff_ > 0.0) {
    if (options_.fixed_interval > 0) {
      rebuild = steps_since_build_ >= static_cast<std::size_t>(options_.fixed_interval);
    } else {
      // GPU BD paper (Eurographics 2015), Algorithm 1, line 15: has any particle moved more than skin/2?
      const double limit2 = 0.25 * skin_ * skin_;
      const std::size_t n = positions.size() / 3;
      int moved = 0;
#pragma omp parallel for schedule(static) reduction(|| : moved) if (n >= 4096)
      for (std::size_t i = 0; i < n; ++i) {
        double d2 = 0.0;
        for (int c = 0; c < 3; ++c) {
          const double d = positions[3 * i + c] - reference_[3 * i + c];
          d2 += d * d;
        }
        moved = moved || (d2 > limit2);
      }
      rebuild = moved != 0;
    }
  }
  if (rebuild) {
    build(positions);
  } else {
    ++steps_since_build_;
  }
  return rebuild;
}

void NeighbourList::build(std::span<const double> positions) {
  require(positions.size() % 3 == 0 && !positions.empty(), ErrorCode::invalid_input, "NeighbourList::build",
          "positions must hold 3N > 0 entries");
  const std::size_t n = positions.size() / 3;
  require(n < std::numeric_limits<std::uint32_t>::max(), ErrorCode::invalid_input, "NeighbourList::build",
          "too many particles");
  require(pair_rl2_.empty() || types_.size() == n, ErrorCode::invalid_input, "NeighbourList::build",
          "the pair cut-offs were set for " + std::to_string(types_.size()) + " particles, not " + std::to_string(n));
  reference_.assign(positions.begin(), positions.end());
  steps_since_build_ = 1;
  ++rebuilds_;
  offsets_.assign(n + 1, 0);
  indices_.clear();
  if (cutoff_ == 0.0) return;
  if (n < 64) {
    build_all_pairs(positions);
  } else {
    build_cells(positions);
  }
}

void NeighbourList::set_pair_cutoffs(std::span<const std::uint32_t> particle_types, std::span<const double> cutoffs,
                                     std::size_t ntypes) {
  const char* where = "NeighbourList::set_pair_cutoffs";
  require(ntypes > 0 && cutoffs.size() == ntypes * ntypes, ErrorCode::invalid_argument, where,
          "cutoffs must hold ntypes^2 = " + std::to_string(ntypes * ntypes) + " entries, got " +
              std::to_string(cutoffs.size()));
  for (std::size_t k = 0; k < cutoffs.size(); ++k) {
    require(std::isfinite(cutoffs[k]) && cutoffs[k] >= 0.0 && cutoffs[k] <= cutoff_, ErrorCode::invalid_argument, where,
            "cutoff of type pair (" + std::to_string(k / ntypes) + ", " + std::to_string(k % ntypes) +
                ") must lie in [0, " + std::to_string(cutoff_) + "], got " + std::to_string(cutoffs[k]));
  }
  for (std::size_t i = 0; i < particle_types.size(); ++i) {
    require(particle_types[i] < ntypes, ErrorCode::invalid_argument, where,
            "particle " + std::to_string(i) + " has type " + std::to_string(particle_types[i]) + ", not below " +
                std::to_string(ntypes));
  }
  types_.assign(particle_types.begin(), particle_types.end());
  ntypes_ = ntypes;
  pair_rl2_.resize(cutoffs.size());
  for (std::size_t k = 0; k < cutoffs.size(); ++k) {
    const double rl = cutoffs[k] + skin_;
    pair_rl2_[k] = cutoffs[k] > 0.0 ? rl * rl : 0.0;
  }
}

namespace {

/// The squared list radius of each pair of types, and each particle's type (in the order rows
/// read them): one type and one radius for all without set_pair_cutoffs.
struct PairRadii {
  std::vector<std::uint32_t> type;  // per particle, in the order of the positions given
  std::vector<double> rl2;          // ntypes x ntypes
  std::size_t ntypes = 1;
  [[nodiscard]] const double* row(std::uint32_t t) const { return rl2.data() + t * ntypes; }
};

}  // namespace

void NeighbourList::build_all_pairs(std::span<const double> x) {
  const std::size_t n = x.size() / 3;
  const bool per_pair = !pair_rl2_.empty();
  const double rl2 = list_radius() * list_radius();
  for (std::size_t i = 0; i < n; ++i) {
    const double* row = per_pair ? pair_rl2_.data() + types_[i] * ntypes_ : nullptr;
    for (std::size_t j = 0; j < n; ++j) {
      if (j == i) continue;
      double d[3];
      separation(&x[3 * i], &x[3 * j], d);
      const double limit = per_pair ? row[types_[j]] : rl2;
      if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < limit) indices_.push_back(static_cast<std::uint32_t>(j));
    }
    offsets_[i + 1] = indices_.size();
  }
}

namespace {

/// The cell grid of a build: cells of side >= r_L, so that a particle's neighbours lie in the 27
/// cells around its own; `wrap` when the periodic 27-cell stencil is distinct (>= 3 cells a side).
struct CellGrid {
  std::array<double, 3> lo{}, extent{}, box{}, inv_box{};
  std::array<long, 3> nc{};
  bool periodic = false;
  bool wrap = false;

  [[nodiscard]] std::size_t cells() const { return static_cast<std::size_t>(nc[0] * nc[1] * nc[2]); }
  [[nodiscard]] std::size_t index(const std::array<long, 3>& k) const {
    return static_cast<std::size_t>((k[0] * nc[1] + k[1]) * nc[2] + k[2]);
  }
  /// Coordinate c of x, wrapped into [0, L) in a periodic box.
  [[nodiscard]] double wrapped(double v, int c) const { return periodic ? v - box[c] * std::floor(v * inv_box[c]) : v; }
  [[nodiscard]] long cell_coord(double v, int c) const {
    const double u = wrapped(v - lo[c], c);
    const long k = static_cast<long>(u / extent[c] * static_cast<double>(nc[c]));
    return std::clamp(k, 0L, nc[c] - 1);
  }
};

CellGrid cell_grid(std::span<const double> x, double rl, bool periodic, const std::array<double, 3>& box,
                   const std::array<double, 3>& inv_box) {
  const std::size_t n = x.size() / 3;
  CellGrid g;
  g.periodic = periodic;
  g.box = box;
  g.inv_box = inv_box;
  for (int c = 0; c < 3; ++c) {
    if (periodic) {
      g.lo[c] = 0.0;
      g.extent[c] = box[c];
    } else {
      double mn = x[c], mx = x[c];
      for (std::size_t i = 0; i < n; ++i) {
        mn = std::min(mn, x[3 * i + c]);
        mx = std::max(mx, x[3 * i + c]);
      }
      g.lo[c] = mn;
      g.extent[c] = std::max(mx - mn, 1e-300);
    }
    g.nc[c] = std::max(1L, static_cast<long>(std::floor(g.extent[c] / rl)));
  }
  // Keep the grid at most ~ 2N cells (sparse open clouds).
  while (static_cast<double>(g.nc[0]) * g.nc[1] * g.nc[2] > 2.0 * static_cast<double>(n) + 27.0) {
    for (auto& v : g.nc) v = std::max(1L, v / 2);
  }
  g.wrap = periodic && g.nc[0] >= 3 && g.nc[1] >= 3 && g.nc[2] >= 3;
  return g;
}

/// Particles sorted into cells (rpyfmm/core/cell_sort.hpp): coord[i] is particle i's cell, the
/// particles of cell k are order[start[k] .. start[k + 1]).
struct CellBins {
  std::vector<std::array<long, 3>> coord;
  std::vector<std::size_t> start, order;
};

CellBins sort_into_cells(std::span<const double> x, const CellGrid& g) {
  const std::size_t n = x.size() / 3;
  CellBins s{std::vector<std::array<long, 3>>(n), {}, {}};
  std::vector<std::size_t> id(n);
  for (std::size_t i = 0; i < n; ++i) {
    s.coord[i] = {g.cell_coord(x[3 * i], 0), g.cell_coord(x[3 * i + 1], 1), g.cell_coord(x[3 * i + 2], 2)};
    id[i] = g.index(s.coord[i]);
  }
  rpyfmm::CellSort sorted;
  sort_by_cell(id, g.cells(), sorted);
  s.start = std::move(sorted.cell_begin);
  s.order = std::move(sorted.order);
  return s;
}

/// The positions in cell order (wrapped into [0, L) in a periodic box).
std::vector<double> positions_in_cell_order(std::span<const double> x, const CellGrid& g,
                                            const std::vector<std::size_t>& order) {
  const std::size_t n = order.size();
  std::vector<double> xs(3 * n);
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (std::size_t s = 0; s < n; ++s)
    for (int c = 0; c < 3; ++c) xs[3 * s + c] = g.wrapped(x[3 * order[s] + c], c);
  return xs;
}

/// Appends to `buf` the neighbours (input indices, unsorted) of the particle in `slot`: the
/// candidates of the 27 cells around its cell within their pair's list radius (radii: types in
/// cell order). A neighbour cell across a periodic face carries its image shift, so no rounding
/// per candidate.
inline void append_row(std::vector<std::uint32_t>& buf, std::size_t slot, const CellGrid& g, const CellBins& cs,
                       const std::vector<double>& xs, const PairRadii& radii) {
  const std::array<long, 3>& home = cs.coord[cs.order[slot]];
  const double* xi = &xs[3 * slot];
  const double* rl2 = radii.row(radii.type[slot]);
  for (long dx = -1; dx <= 1; ++dx) {
    for (long dy = -1; dy <= 1; ++dy) {
      for (long dz = -1; dz <= 1; ++dz) {
        std::array<long, 3> k{home[0] + dx, home[1] + dy, home[2] + dz};
        std::array<double, 3> shift{0.0, 0.0, 0.0};  // added to xi - xj: the image across a face
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
        const std::size_t cell = g.index(k);
        const double xi0 = xi[0] + shift[0], xi1 = xi[1] + shift[1], xi2 = xi[2] + shift[2];
        for (std::size_t t = cs.start[cell]; t < cs.start[cell + 1]; ++t) {
          const double d0 = xi0 - xs[3 * t], d1 = xi1 - xs[3 * t + 1], d2 = xi2 - xs[3 * t + 2];
          if (d0 * d0 + d1 * d1 + d2 * d2 < rl2[radii.type[t]] && t != slot)
            buf.push_back(static_cast<std::uint32_t>(cs.order[t]));
        }
      }
    }
  }
}

constexpr std::size_t kChunk = 2048;  // slots per row buffer

/// The rows in cell order, in chunks of consecutive slots (each chunk one growing buffer: no
/// allocation per particle), each row sorted; count[i] = the length of particle i's row.
std::vector<std::vector<std::uint32_t>> rows_by_chunk(const CellGrid& g, const CellBins& cs,
                                                      const std::vector<double>& xs, const PairRadii& radii,
                                                      std::vector<std::uint32_t>& count) {
  const std::size_t n = cs.order.size();
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  std::vector<std::vector<std::uint32_t>> chunk_lists(chunks);
#pragma omp parallel for schedule(dynamic, 1) if (n >= 1024)
  for (std::size_t ch = 0; ch < chunks; ++ch) {
    auto& buf = chunk_lists[ch];
    for (std::size_t slot = ch * kChunk; slot < std::min(n, (ch + 1) * kChunk); ++slot) {
      const std::size_t before = buf.size();
      append_row(buf, slot, g, cs, xs, radii);
      std::sort(buf.begin() + static_cast<std::ptrdiff_t>(before), buf.end());
      count[cs.order[slot]] = static_cast<std::uint32_t>(buf.size() - before);
    }
  }
  return chunk_lists;
}

/// Concatenates the chunks' rows in particle order (offsets: prefix sums of count).
void concatenate_rows(const std::vector<std::vector<std::uint32_t>>& chunk_lists, const std::vector<std::size_t>& order,
                      const std::vector<std::uint32_t>& count, std::vector<std::size_t>& offsets,
                      std::vector<std::uint32_t>& indices) {
  const std::size_t n = order.size();
  for (std::size_t i = 0; i < n; ++i) offsets[i + 1] = offsets[i] + count[i];
  indices.resize(offsets[n]);
  const std::size_t chunks = chunk_lists.size();
#pragma omp parallel for schedule(dynamic, 1) if (n >= 1024)
  for (std::size_t ch = 0; ch < chunks; ++ch) {
    const std::uint32_t* from = chunk_lists[ch].data();
    for (std::size_t slot = ch * kChunk; slot < std::min(n, (ch + 1) * kChunk); ++slot) {
      const std::size_t i = order[slot];
      std::copy(from, from + count[i], indices.begin() + static_cast<std::ptrdiff_t>(offsets[i]));
      from += count[i];
    }
  }
}

}  // namespace

// Cell-list build: sort the particles into cells of side >= r_L, then each row from the 27
// cells around a particle's own, reading the candidates' positions from a copy in cell order
// (a row's candidates then lie in a few contiguous runs; read in input order, the cache misses
// dominated the build). Rows are built in cell order and concatenated in particle order.
void NeighbourList::build_cells(std::span<const double> x) {
  const double rl = list_radius();
  const CellGrid grid = cell_grid(x, rl, periodic_, box_, inv_box_);
  if (periodic_ && !grid.wrap) {  // too few cells for the 27-cell stencil to be distinct
    build_all_pairs(x);
    return;
  }
  const CellBins cells = sort_into_cells(x, grid);
  const std::vector<double> xs = positions_in_cell_order(x, grid, cells.order);
  // The types in cell order with the radii of set_pair_cutoffs, or one type of radius r_L.
  PairRadii radii;
  if (pair_rl2_.empty()) {
    radii.type.assign(cells.order.size(), 0);
    radii.rl2 = {rl * rl};
  } else {
    radii.type.resize(cells.order.size());
    for (std::size_t slot = 0; slot < cells.order.size(); ++slot) radii.type[slot] = types_[cells.order[slot]];
    radii.rl2 = pair_rl2_;
    radii.ntypes = ntypes_;
  }
  std::vector<std::uint32_t> count(cells.order.size());
  const auto chunk_lists = rows_by_chunk(grid, cells, xs, radii, count);
  concatenate_rows(chunk_lists, cells.order, count, offsets_, indices_);
}

}  // namespace rpyfmm::bd
