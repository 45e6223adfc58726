#include "rpyfmm/bd/neighbour_list.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

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
      // 001 Algorithm 1, line 15: has any particle moved more than skin/2?
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

void NeighbourList::build_all_pairs(std::span<const double> x) {
  const std::size_t n = x.size() / 3;
  const double rl2 = list_radius() * list_radius();
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j) {
      if (j == i) continue;
      double d[3];
      separation(&x[3 * i], &x[3 * j], d);
      if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < rl2) indices_.push_back(static_cast<std::uint32_t>(j));
    }
    offsets_[i + 1] = indices_.size();
  }
}

void NeighbourList::build_cells(std::span<const double> x) {
  const std::size_t n = x.size() / 3;
  const double rl = list_radius();
  const double rl2 = rl * rl;
  // Cell grid: side >= r_L so that neighbours lie in the 27 surrounding cells.
  std::array<double, 3> lo{}, extent{};
  std::array<long, 3> nc{};
  for (int c = 0; c < 3; ++c) {
    if (periodic_) {
      lo[c] = 0.0;
      extent[c] = box_[c];
    } else {
      double mn = x[c], mx = x[c];
      for (std::size_t i = 0; i < n; ++i) {
        mn = std::min(mn, x[3 * i + c]);
        mx = std::max(mx, x[3 * i + c]);
      }
      lo[c] = mn;
      extent[c] = std::max(mx - mn, 1e-300);
    }
    nc[c] = std::max(1L, static_cast<long>(std::floor(extent[c] / rl)));
  }
  // Keep the grid at most ~ 2N cells (sparse open clouds).
  while (static_cast<double>(nc[0]) * nc[1] * nc[2] > 2.0 * static_cast<double>(n) + 27.0) {
    for (auto& v : nc) v = std::max(1L, v / 2);
  }
  const bool wrap = periodic_ && nc[0] >= 3 && nc[1] >= 3 && nc[2] >= 3;
  if (periodic_ && !wrap) {  // too few cells for the 27-cell stencil to be distinct
    build_all_pairs(x);
    return;
  }
  const std::size_t ncell = static_cast<std::size_t>(nc[0] * nc[1] * nc[2]);
  auto cell_coord = [&](std::size_t i, int c) {
    double v = x[3 * i + c] - lo[c];
    if (periodic_) v -= box_[c] * std::floor(v * inv_box_[c]);
    long k = static_cast<long>(v / extent[c] * static_cast<double>(nc[c]));
    return std::clamp(k, 0L, nc[c] - 1);
  };
  std::vector<std::array<long, 3>> coord(n);
  std::vector<std::size_t> start(ncell + 1, 0), order(n);
  for (std::size_t i = 0; i < n; ++i) {
    coord[i] = {cell_coord(i, 0), cell_coord(i, 1), cell_coord(i, 2)};
    ++start[static_cast<std::size_t>((coord[i][0] * nc[1] + coord[i][1]) * nc[2] + coord[i][2]) + 1];
  }
  for (std::size_t k = 0; k < ncell; ++k) start[k + 1] += start[k];
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t i = 0; i < n; ++i)
      order[fill[static_cast<std::size_t>((coord[i][0] * nc[1] + coord[i][1]) * nc[2] + coord[i][2])]++] = i;
  }
  // The rows in cell order, in chunks of consecutive slots (each chunk one growing buffer: no
  // allocation per particle), reading the candidates' positions from a copy in cell order (a
  // row's candidates then lie in a few contiguous runs; read in input order, the cache misses
  // dominated the build). In a periodic box the copy is wrapped into [0, L) and a neighbour
  // cell across a face carries its image shift, so no rounding per candidate. Each particle's
  // neighbours are then sorted, and the chunks concatenated in particle order.
  std::vector<double> xs(3 * n);
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (std::size_t s = 0; s < n; ++s) {
    for (int c = 0; c < 3; ++c) {
      double v = x[3 * order[s] + c];
      if (periodic_) v -= box_[c] * std::floor(v * inv_box_[c]);
      xs[3 * s + c] = v;
    }
  }
  constexpr std::size_t kChunk = 2048;
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  std::vector<std::vector<std::uint32_t>> chunk_lists(chunks);
  std::vector<std::uint32_t> count(n);
#pragma omp parallel for schedule(dynamic, 1) if (n >= 1024)
  for (std::size_t ch = 0; ch < chunks; ++ch) {
    auto& buf = chunk_lists[ch];
    for (std::size_t slot = ch * kChunk; slot < std::min(n, (ch + 1) * kChunk); ++slot) {
      const std::size_t i = order[slot];
      const double* xi = &xs[3 * slot];
      const std::size_t before = buf.size();
      for (long dx = -1; dx <= 1; ++dx) {
        for (long dy = -1; dy <= 1; ++dy) {
          for (long dz = -1; dz <= 1; ++dz) {
            std::array<long, 3> k{coord[i][0] + dx, coord[i][1] + dy, coord[i][2] + dz};
            std::array<double, 3> shift{0.0, 0.0, 0.0};  // added to xi - xj: the image across a face
            bool skip = false;
            for (int c = 0; c < 3; ++c) {
              if (wrap) {  // k in [-1, nc]
                if (k[c] < 0) {
                  k[c] += nc[c];
                  shift[c] = box_[c];
                } else if (k[c] >= nc[c]) {
                  k[c] -= nc[c];
                  shift[c] = -box_[c];
                }
              } else if (k[c] < 0 || k[c] >= nc[c]) {
                skip = true;
              }
            }
            if (skip) continue;
            const auto cell = static_cast<std::size_t>((k[0] * nc[1] + k[1]) * nc[2] + k[2]);
            const double xi0 = xi[0] + shift[0], xi1 = xi[1] + shift[1], xi2 = xi[2] + shift[2];
            for (std::size_t t = start[cell]; t < start[cell + 1]; ++t) {
              const double d0 = xi0 - xs[3 * t], d1 = xi1 - xs[3 * t + 1], d2 = xi2 - xs[3 * t + 2];
              if (d0 * d0 + d1 * d1 + d2 * d2 < rl2 && t != slot) buf.push_back(static_cast<std::uint32_t>(order[t]));
            }
          }
        }
      }
      std::sort(buf.begin() + static_cast<std::ptrdiff_t>(before), buf.end());
      count[i] = static_cast<std::uint32_t>(buf.size() - before);
    }
  }
  for (std::size_t i = 0; i < n; ++i) offsets_[i + 1] = offsets_[i] + count[i];
  indices_.resize(offsets_[n]);
#pragma omp parallel for schedule(dynamic, 1) if (n >= 1024)
  for (std::size_t ch = 0; ch < chunks; ++ch) {
    const std::uint32_t* from = chunk_lists[ch].data();
    for (std::size_t slot = ch * kChunk; slot < std::min(n, (ch + 1) * kChunk); ++slot) {
      const std::size_t i = order[slot];
      std::copy(from, from + count[i], indices_.begin() + static_cast<std::ptrdiff_t>(offsets_[i]));
      from += count[i];
    }
  }
}

}  // namespace rpyfmm::bd
