// rpyfmm — the neighbour lists of the PSE real-space sum: cell grid, slot order, list build
// (docs/theory/pse.md).
#include "neighbour_lists.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

#include "kernels_common.hpp"
#include "list_filter.hpp"
#include "rpyfmm/core/cell_sort.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "window_avx2.hpp"

namespace rpyfmm::rpy::pse::detail {

CellGrid cell_grid(const std::array<double, 3>& box, double r_cut) {
  CellGrid g;
  for (int d = 0; d < 3; ++d) {
    g.nc[d] = static_cast<int>(std::floor(box[d] / r_cut));
    g.cells = g.cells && g.nc[d] >= 3;
  }
  return g;
}

std::vector<std::size_t> sort_into_cells(std::span<const double> x, const std::array<double, 3>& box,
                                         const CellGrid& grid, std::vector<std::size_t>& order) {
  const std::size_t n = x.size() / 3;
  order.resize(n);
  if (!grid.cells) {
    for (std::size_t s = 0; s < n; ++s) order[s] = s;
    return {0, n};
  }
  const auto& nc = grid.nc;
  const std::size_t ncell = static_cast<std::size_t>(nc[0]) * nc[1] * nc[2];
  std::vector<std::size_t> id(n);
  // Cell ids in parallel (divisions), the sort serially.
#pragma omp parallel for schedule(static) if (n >= 16384)
  for (std::int64_t ii = 0; ii < static_cast<std::int64_t>(n); ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    int c[3];
    for (int d = 0; d < 3; ++d) c[d] = std::min(static_cast<int>(x[3 * i + d] / box[d] * nc[d]), nc[d] - 1);
    id[i] = (static_cast<std::size_t>(c[0]) * nc[1] + c[1]) * nc[2] + c[2];
  }
  CellSort sorted;
  sort_by_cell(id, ncell, sorted);
  order = std::move(sorted.order);
  return std::move(sorted.cell_begin);
}

void gather_positions(std::span<const double> x, const std::vector<std::size_t>& order,
                      std::array<std::vector<double>, 3>& pos) {
  const std::size_t n = order.size();
  for (auto& p : pos) p.resize(n);
  // One pass (x is read at random, a particle's three coordinates share a cache line), fetching
  // a few slots ahead.
  constexpr std::size_t ahead = 8;
#pragma omp parallel for schedule(static) if (n >= 16384)
  for (std::int64_t ss = 0; ss < static_cast<std::int64_t>(n); ++ss) {
    const auto s = static_cast<std::size_t>(ss);
    if (s + ahead < n) __builtin_prefetch(&x[3 * order[s + ahead]]);
    const double* xi = &x[3 * order[s]];
    pos[0][s] = xi[0];
    pos[1][s] = xi[1];
    pos[2][s] = xi[2];
  }
}

namespace {

/// A run of consecutive neighbour cells [first, end) with one image shift.
struct CellRun {
  std::size_t first, end;
  double shift[3];
};

/// The candidate filter of the list build: the AVX-512 one for half lists where the AVX-512
/// kernels run, the AVX2 one for full lists on a cell grid where AVX2 runs, else the portable one.
enum class ListFilter { portable, avx2, avx512 };

struct ListBuild {
  const ListRequest& in;
  std::array<double, 3> inv;  // 1 / L
  double rc2;
  ListFilter filter;
};

/// The 27 neighbour cells of cell c in ascending id order, merged into runs of consecutive ids
/// with the same image shift (a z column of three cells is one run of consecutive slots unless
/// it wraps): slots are numbered cell by cell, so each row then lists its neighbours in
/// ascending slot order without a sort. The shift along an axis is +L where the neighbour cell
/// wrapped past the last layer, -L where it wrapped below the first, else 0: with >= 3 cells of
/// edge >= r_cut per axis, a pair within r_cut has that image as its minimum image (any other
/// image is >= L - 2 h >= h >= r_cut away along the axis), and x_s - x_t -+ L is rounded as
/// minimum_image rounds it. Without cells, the one pseudo-cell (minimum image).
int neighbour_runs(const CellGrid& grid, const std::array<double, 3>& box, std::size_t c,
                   std::array<CellRun, 27>& out) {
  if (!grid.cells) {
    out[0] = {0, 1, {0.0, 0.0, 0.0}};
    return 1;
  }
  const auto& nc = grid.nc;
  const auto nyz = static_cast<std::size_t>(nc[1]) * static_cast<std::size_t>(nc[2]);
  const int c0[3] = {static_cast<int>(c / nyz), static_cast<int>((c / static_cast<std::size_t>(nc[2])) % nc[1]),
                     static_cast<int>(c % static_cast<std::size_t>(nc[2]))};
  std::array<CellRun, 27> one{};
  int k = 0;
  for (int ax = -1; ax <= 1; ++ax)
    for (int ay = -1; ay <= 1; ++ay)
      for (int az = -1; az <= 1; ++az) {
        const int a[3] = {ax, ay, az};
        int id[3];
        CellRun& r = one[static_cast<std::size_t>(k++)];
        for (int d = 0; d < 3; ++d) {
          const int u = c0[d] + a[d];
          id[d] = (u + nc[d]) % nc[d];
          r.shift[d] = u >= nc[d] ? box[static_cast<std::size_t>(d)] : u < 0 ? -box[static_cast<std::size_t>(d)] : 0.0;
        }
        r.first = (static_cast<std::size_t>(id[0]) * nc[1] + id[1]) * nc[2] + id[2];
        r.end = r.first + 1;
      }
  // 27 distinct cells: nc >= 3 along every axis.
  std::sort(one.begin(), one.end(), [](const CellRun& p, const CellRun& q) { return p.first < q.first; });
  int m = 0;
  for (const CellRun& r : one) {
    CellRun* last = m > 0 ? &out[static_cast<std::size_t>(m - 1)] : nullptr;
    if (last != nullptr && last->end == r.first && last->shift[0] == r.shift[0] && last->shift[1] == r.shift[1] &&
        last->shift[2] == r.shift[2]) {
      last->end = r.end;
    } else {
      out[static_cast<std::size_t>(m++)] = r;
    }
  }
  return m;
}

/// d2[q] = |x_s - x_{t0 + q} - shift|^2, q < count: the neighbour's periodic image is fixed per
/// neighbour cell (neighbour_runs); without cells (shift null), minimum image.
void squared_distances(const ListBuild& b, std::size_t s, std::size_t t0, std::size_t count, const double* shift,
                       double* __restrict d2) {
  const auto& pos = b.in.pos;
  const double xs = pos[0][s], ys = pos[1][s], zs = pos[2][s];
  const double* __restrict xt = pos[0].data() + t0;
  const double* __restrict yt = pos[1].data() + t0;
  const double* __restrict zt = pos[2].data() + t0;
  if (shift == nullptr) {
    const auto& box = b.in.box;
#pragma omp simd
    for (std::size_t q = 0; q < count; ++q) {
      const double dx = minimum_image(xs - xt[q], box[0], b.inv[0]);
      const double dy = minimum_image(ys - yt[q], box[1], b.inv[1]);
      const double dz = minimum_image(zs - zt[q], box[2], b.inv[2]);
      d2[q] = dx * dx + dy * dy + dz * dz;
    }
    return;
  }
  const double sx = shift[0], sy = shift[1], sz = shift[2];
#pragma omp simd
  for (std::size_t q = 0; q < count; ++q) {
    const double dx = (xs - xt[q]) - sx, dy = (ys - yt[q]) - sy, dz = (zs - zt[q]) - sz;
    d2[q] = dx * dx + dy * dy + dz * dz;
  }
}

/// Per thread: the block's entries go to a buffer that only grows (no zero-fill per candidate
/// cell, no shared vector headers written per candidate: the per-block lists' headers are
/// adjacent in memory, and writing them from two threads at every resize made the build slower
/// with 2 threads than with 1), then are copied out once per block.
struct BuildScratch {
  std::array<CellRun, 27> runs{};
  std::vector<double> d2;  // squared distances to one run's slots
  std::vector<int> buf;
};

/// The portable filter: out[used ...] = the slots t0 .. t0 + count - 1 within r_cut of slot s
/// (never s itself); returns the new count. Distances first (a loop that vectorizes), then a
/// branch-free compaction: about one candidate in six is kept, so a branch per candidate would
/// mostly mispredict. Not inlined into the list build, whose hot loops then ran 15-25% slower at
/// the scalar level (2026-12-05, 2-core AMD EPYC VM, AVX2, 32000 particles).
[[gnu::noinline]] std::size_t portable_within(const ListBuild& b, std::size_t s, std::size_t t0, std::size_t count,
                                              const double* shift, BuildScratch& w, int* out, std::size_t used) {
  if (w.d2.size() < count) w.d2.resize(count);
  squared_distances(b, s, t0, count, b.in.grid.cells ? shift : nullptr, w.d2.data());
  for (std::size_t q = 0; q < count; ++q) {
    out[used] = static_cast<int>(t0 + q);
    used += static_cast<std::size_t>(w.d2[q] < b.rc2) & static_cast<std::size_t>(t0 + q != s);
  }
  return used;
}

/// Appends to w.buf (from entry `used`) the slots t0 .. t0 + count - 1 within r_cut of slot s
/// (never s itself) by the build's filter and returns the new count.
std::size_t append_within(const ListBuild& b, std::size_t s, std::size_t t0, std::size_t count, const double* shift,
                          BuildScratch& w, std::size_t used) {
  if (w.buf.size() < used + count + 16) w.buf.resize(2 * (used + count + 16));
  int* out = w.buf.data();
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  const auto& pos = b.in.pos;
  if (b.filter != ListFilter::portable) {
    const double xs[3] = {pos[0][s], pos[1][s], pos[2][s]};
    if (b.filter == ListFilter::avx512)  // half lists: t0 > s, so the own slot is never a candidate
      return used +
             pairs_within_avx512(pos[0].data(), pos[1].data(), pos[2].data(), t0, count, xs, shift, b.rc2, out + used);
    return used +
           pairs_within_avx2(pos[0].data(), pos[1].data(), pos[2].data(), t0, count, xs, shift, b.rc2, s, out + used);
  }
#endif
  return portable_within(b, s, t0, count, shift, w, out, used);
}

/// The rows of the slots of cells [c_begin, c_end) into w.buf; counts[s] = the length of row s.
/// Returns the entries written.
std::size_t build_block(const ListBuild& b, std::size_t c_begin, std::size_t c_end, BuildScratch& w,
                        std::size_t* counts) {
  const auto& cell_begin = b.in.cell_begin;
  const bool half = b.in.half;
  std::size_t used = 0;
  for (std::size_t c = c_begin; c < c_end; ++c) {
    const int m = neighbour_runs(b.in.grid, b.in.box, c, w.runs);
    for (std::size_t s = cell_begin[c]; s < cell_begin[c + 1]; ++s) {
      const std::size_t before = used;
      for (int k = 0; k < m; ++k) {
        const CellRun& run = w.runs[static_cast<std::size_t>(k)];
        if (half && run.end <= c) continue;
        // Half lists: the cells of larger id and the later slots of the own cell.
        const std::size_t t0 = !half ? cell_begin[run.first] : run.first > c ? cell_begin[run.first] : s + 1;
        used = append_within(b, s, t0, cell_begin[run.end] - t0, run.shift, w, used);
      }
      counts[s] = used - before;
    }
  }
  return used;
}

ListFilter choose_filter(const ListRequest& in) {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  if (in.half) return ListFilter::avx512;  // half lists are asked for where the AVX-512 kernels run
  if (in.grid.cells && avx2_window_kernels(1)) return ListFilter::avx2;  // CPU and toggle: window_avx2.hpp
#else
  (void)in;
#endif
  return ListFilter::portable;
}

}  // namespace

void build_neighbour_lists(const ListRequest& request, std::vector<std::vector<int>>& block_lists,
                           std::vector<std::size_t>& begin, std::vector<int>& list) {
  const ListBuild b{request,
                    {1.0 / request.box[0], 1.0 / request.box[1], 1.0 / request.box[2]},
                    request.r_cut * request.r_cut,
                    choose_filter(request)};
  const auto& cell_begin = request.cell_begin;
  const std::size_t n = request.pos[0].size();
  const std::size_t ncell = cell_begin.size() - 1;
  // One pass: blocks of consecutive cells (consecutive slots) fill buffers of their own, which are
  // then concatenated in block order.
  const std::size_t block_cells = std::max<std::size_t>(1, ncell / 512);
  const std::size_t nblock = (ncell + block_cells - 1) / block_cells;
  block_lists.resize(nblock);
  begin.assign(n + 1, 0);
  const auto nb = static_cast<std::int64_t>(nblock);
#pragma omp parallel if (n >= 2048)
  {
    BuildScratch w;
#pragma omp for schedule(dynamic, 1)
    for (std::int64_t bb = 0; bb < nb; ++bb) {
      const auto k = static_cast<std::size_t>(bb);
      const std::size_t used = build_block(b, k * block_cells, std::min(ncell, (k + 1) * block_cells), w, &begin[1]);
      block_lists[k].assign(w.buf.begin(), w.buf.begin() + static_cast<std::ptrdiff_t>(used));
    }
  }
  for (std::size_t s = 0; s < n; ++s) begin[s + 1] += begin[s];
  list.resize(begin[n]);
#pragma omp parallel for schedule(static) if (n >= 2048)
  for (std::int64_t bb = 0; bb < nb; ++bb) {
    const auto& part = block_lists[static_cast<std::size_t>(bb)];
    const std::size_t first_slot = cell_begin[static_cast<std::size_t>(bb) * block_cells];
    std::copy(part.begin(), part.end(), list.begin() + static_cast<std::ptrdiff_t>(begin[first_slot]));
  }
}

void half_row_starts(const std::vector<std::size_t>& begin, const std::vector<int>& list, bool half_lists,
                     std::vector<std::size_t>& upper) {
  const std::size_t n = begin.size() - 1;
  upper.resize(n);
  for (std::size_t s = 0; s < n; ++s) {
    if (half_lists) {
      upper[s] = begin[s];
      continue;
    }
    const auto row_begin = list.begin() + static_cast<std::ptrdiff_t>(begin[s]);
    const auto row_end = list.begin() + static_cast<std::ptrdiff_t>(begin[s + 1]);
    upper[s] =
        begin[s] + static_cast<std::size_t>(std::upper_bound(row_begin, row_end, static_cast<int>(s)) - row_begin);
  }
}

void derive_full_rows(const std::vector<std::size_t>& begin, const std::vector<int>& list,
                      std::vector<std::size_t>& full_begin, std::vector<int>& full_list) {
  const std::size_t n = begin.size() - 1;
  full_begin.assign(n + 1, 0);
  for (std::size_t s = 0; s < n; ++s) {
    full_begin[s + 1] += begin[s + 1] - begin[s];
    for (std::size_t q = begin[s]; q < begin[s + 1]; ++q) ++full_begin[static_cast<std::size_t>(list[q]) + 1];
  }
  for (std::size_t s = 0; s < n; ++s) full_begin[s + 1] += full_begin[s];
  full_list.resize(full_begin[n]);
  std::vector<std::size_t> fill(full_begin.begin(), full_begin.end() - 1);
  for (std::size_t s = 0; s < n; ++s) {  // row s's lower part is complete: it comes from rows < s
    for (std::size_t q = begin[s]; q < begin[s + 1]; ++q) full_list[fill[s]++] = list[q];
    for (std::size_t q = begin[s]; q < begin[s + 1]; ++q)
      full_list[fill[static_cast<std::size_t>(list[q])]++] = static_cast<int>(s);
  }
}

}  // namespace rpyfmm::rpy::pse::detail
