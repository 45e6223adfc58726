#include "rpyfmm/bd/neighbour_list.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "device/cell_binning.hpp"
#include "device/cell_grid.hpp"
#include "device/minimum_image.hpp"
#include "device/verlet_rows.hpp"
#include "rpyfmm/core/cell_sort.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

NeighbourList::NeighbourList(rpy::Geometry geometry, double cutoff, NeighbourOptions options)
    : geometry_(geometry), periodic_(geometry.is_periodic()), cutoff_(cutoff), skin_(options.skin), options_(options) {
  const char* where = "NeighbourList";
  require(std::isfinite(cutoff) && cutoff >= 0.0, ErrorCode::invalid_argument, where,
          "cutoff must be finite and >= 0, got " + format_number(cutoff));
  require(std::isfinite(options.skin) && options.skin >= 0.0, ErrorCode::invalid_argument, where,
          "skin must be finite and >= 0, got " + format_number(options.skin));
  require(options.fixed_interval >= 0, ErrorCode::invalid_argument, where, "fixed_interval must be >= 0");
  if (skin_ == 0.0) skin_ = 0.3 * cutoff_;
  if (periodic_) {
    box_ = geometry.box();
    for (int c = 0; c < 3; ++c) {
      inv_box_[c] = 1.0 / box_[c];
      require(list_radius() <= 0.5 * box_[c], ErrorCode::invalid_argument, where,
              "cutoff + skin = " + format_number(list_radius()) + " exceeds half the box length " +
                  format_number(box_[c]) + " (minimum image would fail)");
    }
  }
}

bool NeighbourList::update(std::span<const double> positions) {
  bool rebuild = reference_.size() != positions.size();
  if (!rebuild && cutoff_ > 0.0) {
    if (options_.fixed_interval > 0) {
      rebuild = steps_since_build_ >= static_cast<std::size_t>(options_.fixed_interval);
    } else {
      // Tran et al. (2015), Algorithm 1, line 15: has any particle moved more than skin/2?
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
                ") must lie in [0, " + format_number(cutoff_) + "], got " + format_number(cutoffs[k]));
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

/// A row sink (device/verlet_rows.hpp) appending to a growing buffer: no allocation per row.
struct AppendSink {
  std::vector<std::uint32_t>* buf;
  void add(std::uint32_t j) { buf->push_back(j); }
};

}  // namespace

std::span<const double> NeighbourList::squared_list_radii(std::vector<double>& single) const {
  if (!pair_rl2_.empty()) return pair_rl2_;
  single = {list_radius() * list_radius()};
  return single;
}

std::vector<std::uint32_t> NeighbourList::particle_types(std::size_t n) const {
  return pair_rl2_.empty() ? std::vector<std::uint32_t>(n, 0) : types_;
}

void NeighbourList::build_all_pairs(std::span<const double> x) {
  const auto n = static_cast<std::uint32_t>(x.size() / 3);
  std::vector<double> single;
  const std::span<const double> rl2 = squared_list_radii(single);
  const device::ListRadii radii{rl2.data(), static_cast<std::uint32_t>(single.empty() ? ntypes_ : 1)};
  const std::vector<std::uint32_t> type = particle_types(n);
  device::MinimumImage image{periodic_, {box_[0], box_[1], box_[2]}, {inv_box_[0], inv_box_[1], inv_box_[2]}};
  AppendSink sink{&indices_};
  for (std::uint32_t i = 0; i < n; ++i) {
    device::visit_all_pairs(i, n, x.data(), type.data(), image, radii, sink);
    offsets_[i + 1] = indices_.size();
  }
}

namespace {

/// Particles sorted into the cells of a grid (rpyfmm/core/cell_sort.hpp's stable counting sort)
/// and their wrapped positions and types in slot order: the arrays of a device::SlotView.
struct SlotArrays {
  std::vector<std::uint32_t> cell_of, order, start, ts;
  std::vector<double> xs;
  [[nodiscard]] device::SlotView view() const {
    return {order.data(), start.data(), cell_of.data(), xs.data(), ts.data()};
  }
};

SlotArrays sort_into_cells(std::span<const double> x, const std::vector<std::uint32_t>& type,
                           const device::CellGrid& g) {
  const std::size_t n = x.size() / 3;
  SlotArrays a;
  a.cell_of.resize(n);
  std::vector<std::size_t> id(n);
  for (std::size_t i = 0; i < n; ++i) {
    id[i] = g.cell_of(&x[3 * i]);
    a.cell_of[i] = static_cast<std::uint32_t>(id[i]);
  }
  rpyfmm::CellSort sorted;
  sort_by_cell(id, g.cells(), sorted);
  a.order.assign(sorted.order.begin(), sorted.order.end());
  a.start.assign(sorted.cell_begin.begin(), sorted.cell_begin.end());
  a.xs.resize(3 * n);
  a.ts.resize(n);
  const device::CellBins bins{nullptr, nullptr, nullptr, nullptr, a.order.data()};
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (std::size_t s = 0; s < n; ++s)
    device::gather_slot(static_cast<std::uint32_t>(s), x.data(), type.data(), g, bins, a.xs.data(), a.ts.data());
  return a;
}

constexpr std::size_t kChunk = 2048;  // slots per row buffer

/// The rows in cell order, in chunks of consecutive slots (each chunk one growing buffer: no
/// allocation per particle), each row sorted; count[i] = the length of particle i's row.
std::vector<std::vector<std::uint32_t>> rows_by_chunk(const device::CellGrid& g, const device::SlotView& slots,
                                                      const device::ListRadii& radii,
                                                      std::vector<std::uint32_t>& count) {
  const std::size_t n = count.size();
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  std::vector<std::vector<std::uint32_t>> chunk_lists(chunks);
#pragma omp parallel for schedule(dynamic, 1) if (n >= 1024)
  for (std::size_t ch = 0; ch < chunks; ++ch) {
    auto& buf = chunk_lists[ch];
    AppendSink sink{&buf};
    for (std::size_t slot = ch * kChunk; slot < std::min(n, (ch + 1) * kChunk); ++slot) {
      const std::size_t before = buf.size();
      device::visit_stencil(static_cast<std::uint32_t>(slot), g, slots, radii, sink);
      std::sort(buf.begin() + static_cast<std::ptrdiff_t>(before), buf.end());
      count[slots.order[slot]] = static_cast<std::uint32_t>(buf.size() - before);
    }
  }
  return chunk_lists;
}

/// Concatenates the chunks' rows in particle order (offsets: prefix sums of count).
void concatenate_rows(const std::vector<std::vector<std::uint32_t>>& chunk_lists,
                      const std::vector<std::uint32_t>& order, const std::vector<std::uint32_t>& count,
                      std::vector<std::size_t>& offsets, std::vector<std::uint32_t>& indices) {
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

// Cell-list build: sort the particles into cells of side >= r_L (device/cell_grid.hpp, the grid
// every engine uses), then each row from the 27 cells around a particle's own
// (device/verlet_rows.hpp), reading the candidates' positions from a copy in cell order (a row's
// candidates then lie in a few contiguous runs; read in input order, the cache misses dominated
// the build). Rows are built in cell order and concatenated in particle order.
void NeighbourList::build_cells(std::span<const double> x) {
  const std::size_t n = x.size() / 3;
  const device::CellGrid grid = device::cell_grid_of(x.data(), n, list_radius(), periodic_, box_.data());
  if (periodic_ && !grid.wrap) {  // too few cells for the 27-cell stencil to be distinct
    build_all_pairs(x);
    return;
  }
  require(grid.cells() < std::numeric_limits<std::uint32_t>::max(), ErrorCode::invalid_input, "NeighbourList::build",
          "too many cells for 32-bit cell indices");
  const SlotArrays slots = sort_into_cells(x, particle_types(n), grid);
  std::vector<double> single;
  const std::span<const double> rl2 = squared_list_radii(single);
  const device::ListRadii radii{rl2.data(), static_cast<std::uint32_t>(single.empty() ? ntypes_ : 1)};
  std::vector<std::uint32_t> count(n);
  const auto chunk_lists = rows_by_chunk(grid, slots.view(), radii, count);
  concatenate_rows(chunk_lists, slots.order, count, offsets_, indices_);
}

}  // namespace rpyfmm::bd
