// rpyfmm — PSE real-space product (PSE.md Sec. 1.2, 6.2; [PSE] eq. 10 with App. A).
#include "real_space_sum.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

#include "kernels_common.hpp"
#include "rpyfmm/core/validate.hpp"

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_ADDRESS__)
#define RPYFMM_REAL_SPACE_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define RPYFMM_REAL_SPACE_CLONES
#endif

namespace rpyfmm::rpy::pse::detail {

namespace {

/// Positions and forces by slot, one array per axis.
struct SlotArrays {
  const double* x[3];
  const double* f[3];
};

/// One row of M_r F / M0 without the self term: u += sum_q [F (I - rr) + G rr] f_q over the
/// neighbour slots nb[0..count) of a particle at xi ([PSE] eq. 10, App. A via the linear table).
/// Branch-free, so that it vectorizes over neighbours (gathers): a coincident neighbour
/// (r = 0) gets 1/r = 0 and the table's r = 0 node F(0) = G(0), i.e. the block F(0) I.
RPYFMM_REAL_SPACE_CLONES void table_row(const int* nb, std::size_t count, const double xi[3], const SlotArrays& s,
                                        const double* table, double inv_dr, const double L[3], const double inv_L[3],
                                        double u[3]) {
  double ux = 0.0, uy = 0.0, uz = 0.0;
#pragma omp simd reduction(+ : ux, uy, uz)
  for (std::size_t q = 0; q < count; ++q) {
    const auto t = static_cast<std::size_t>(nb[q]);
    const double dx = minimum_image(xi[0] - s.x[0][t], L[0], inv_L[0]);
    const double dy = minimum_image(xi[1] - s.x[1][t], L[1], inv_L[1]);
    const double dz = minimum_image(xi[2] - s.x[2][t], L[2], inv_L[2]);
    const double r2 = dx * dx + dy * dy + dz * dz;
    const double r = std::sqrt(r2);
    const double inv_r = r2 > 0.0 ? 1.0 / r : 0.0;
    double w = r * inv_dr;
    const int j = static_cast<int>(w);
    w -= static_cast<double>(j);
    const double* e = table + 4 * j;
    const double F = e[0] + w * (e[2] - e[0]);
    const double G = e[1] + w * (e[3] - e[1]);
    const double fx = s.f[0][t], fy = s.f[1][t], fz = s.f[2][t];
    const double ex = dx * inv_r, ey = dy * inv_r, ez = dz * inv_r;
    const double proj = (G - F) * (ex * fx + ey * fy + ez * fz);
    ux += F * fx + proj * ex;
    uy += F * fy + proj * ey;
    uz += F * fz + proj * ez;
  }
  u[0] += ux;
  u[1] += uy;
  u[2] += uz;
}

}  // namespace

RealSpaceSum::RealSpaceSum(const PseParameters& p, const std::array<double, 3>& box, double viscosity, bool use_table)
    : p_(p),
      box_(box),
      m0_(1.0 / (6.0 * std::numbers::pi * viscosity * p.radius)),
      self_(real_space_self(p.xi, p.radius)),
      use_table_(use_table) {
  if (use_table_) table_ = PseRealSpaceTable(p.xi, p.radius, p.r_cut, p.tolerance / 10.0);
}

void RealSpaceSum::set_positions(std::span<const double> x) {
  const std::size_t n = x.size() / 3;
  require(n < static_cast<std::size_t>(std::numeric_limits<int>::max()), ErrorCode::invalid_input, "PseRpy",
          "too many particles for 32-bit neighbour indices");
  const double rc2 = p_.r_cut * p_.r_cut;
  std::array<int, 3> nc{};
  bool cells = true;
  for (int d = 0; d < 3; ++d) {
    nc[d] = static_cast<int>(std::floor(box_[d] / p_.r_cut));
    cells = cells && nc[d] >= 3;
  }
  // Slots: particles sorted by cell (counting sort, stable); without cells, the input order.
  std::vector<std::size_t> cell_begin;
  order_.resize(n);
  if (cells) {
    const std::size_t ncell = static_cast<std::size_t>(nc[0]) * nc[1] * nc[2];
    cell_begin.assign(ncell + 1, 0);
    std::vector<std::size_t> id(n);
    for (std::size_t i = 0; i < n; ++i) {
      int c[3];
      for (int d = 0; d < 3; ++d) c[d] = std::min(static_cast<int>(x[3 * i + d] / box_[d] * nc[d]), nc[d] - 1);
      id[i] = (static_cast<std::size_t>(c[0]) * nc[1] + c[1]) * nc[2] + c[2];
      ++cell_begin[id[i] + 1];
    }
    for (std::size_t c = 0; c < ncell; ++c) cell_begin[c + 1] += cell_begin[c];
    std::vector<std::size_t> fill(cell_begin.begin(), cell_begin.end() - 1);
    for (std::size_t i = 0; i < n; ++i) order_[fill[id[i]]++] = i;
  } else {
    for (std::size_t s = 0; s < n; ++s) order_[s] = s;
  }
  for (int d = 0; d < 3; ++d) {
    pos_[static_cast<std::size_t>(d)].resize(n);
    for (std::size_t s = 0; s < n; ++s)
      pos_[static_cast<std::size_t>(d)][s] = x[3 * order_[s] + static_cast<std::size_t>(d)];
  }
  const std::array<double, 3> inv = {1.0 / box_[0], 1.0 / box_[1], 1.0 / box_[2]};
  const auto& px = pos_[0];
  const auto& py = pos_[1];
  const auto& pz = pos_[2];
  // d2[q] = |x_s - x_{t0 + q}|^2 (minimum image), q < count.
  auto squared_distances = [&](std::size_t s, std::size_t t0, std::size_t count, double* __restrict d2) {
    const double xs = px[s], ys = py[s], zs = pz[s];
    const double* __restrict xt = px.data() + t0;
    const double* __restrict yt = py.data() + t0;
    const double* __restrict zt = pz.data() + t0;
#pragma omp simd
    for (std::size_t q = 0; q < count; ++q) {
      const double dx = minimum_image(xs - xt[q], box_[0], inv[0]);
      const double dy = minimum_image(ys - yt[q], box_[1], inv[1]);
      const double dz = minimum_image(zs - zt[q], box_[2], inv[2]);
      d2[q] = dx * dx + dy * dy + dz * dz;
    }
  };
  // Neighbour cells of cell c in ascending order: slots are numbered cell by cell, so each row
  // then lists its neighbours in ascending slot order without a sort. Without cells, one
  // pseudo-cell holds every slot.
  if (!cells) cell_begin = {0, n};
  const std::size_t ncell = cell_begin.size() - 1;
  auto neighbour_cells = [&](std::size_t c, std::array<std::size_t, 27>& out) -> int {
    if (!cells) {
      out[0] = 0;
      return 1;
    }
    const auto nyz = static_cast<std::size_t>(nc[1]) * static_cast<std::size_t>(nc[2]);
    const int c0[3] = {static_cast<int>(c / nyz), static_cast<int>((c / static_cast<std::size_t>(nc[2])) % nc[1]),
                       static_cast<int>(c % static_cast<std::size_t>(nc[2]))};
    int k = 0;
    for (int ax = -1; ax <= 1; ++ax)
      for (int ay = -1; ay <= 1; ++ay)
        for (int az = -1; az <= 1; ++az) {
          const int cx = (c0[0] + ax + nc[0]) % nc[0];
          const int cy = (c0[1] + ay + nc[1]) % nc[1];
          const int cz = (c0[2] + az + nc[2]) % nc[2];
          out[static_cast<std::size_t>(k++)] = (static_cast<std::size_t>(cx) * nc[1] + cy) * nc[2] + cz;
        }
    std::sort(out.begin(), out.end());  // 27 distinct cells: nc >= 3 along every axis
    return k;
  };
  // One pass: blocks of consecutive cells (consecutive slots) fill buffers of their own, which are
  // then concatenated in block order.
  const std::size_t block_cells = std::max<std::size_t>(1, ncell / 512);
  const std::size_t nblock = (ncell + block_cells - 1) / block_cells;
  std::vector<std::vector<int>> block_list(nblock);
  begin_.assign(n + 1, 0);
  const auto nb = static_cast<std::int64_t>(nblock);
#pragma omp parallel for schedule(dynamic, 1) if (n >= 2048)
  for (std::int64_t b = 0; b < nb; ++b) {
    std::array<std::size_t, 27> nbr{};
    std::vector<double> d2;  // squared distances to one neighbour cell's slots
    auto& out = block_list[static_cast<std::size_t>(b)];
    const std::size_t c_end = std::min(ncell, (static_cast<std::size_t>(b) + 1) * block_cells);
    for (std::size_t c = static_cast<std::size_t>(b) * block_cells; c < c_end; ++c) {
      const int m = neighbour_cells(c, nbr);
      for (std::size_t s = cell_begin[c]; s < cell_begin[c + 1]; ++s) {
        const std::size_t before = out.size();
        for (int k = 0; k < m; ++k) {
          const std::size_t cn = nbr[static_cast<std::size_t>(k)];
          const std::size_t t0 = cell_begin[cn], count = cell_begin[cn + 1] - t0;
          // Distances first (a loop that vectorizes), then a branch-free compaction: about one
          // candidate in six is kept, so a branch per candidate would mostly mispredict.
          d2.resize(std::max(d2.size(), count));
          squared_distances(s, t0, count, d2.data());
          std::size_t kept = out.size();
          out.resize(kept + count);
          for (std::size_t q = 0; q < count; ++q) {
            out[kept] = static_cast<int>(t0 + q);
            kept += static_cast<std::size_t>(d2[q] < rc2) & static_cast<std::size_t>(t0 + q != s);
          }
          out.resize(kept);
        }
        begin_[s + 1] = out.size() - before;
      }
    }
  }
  for (std::size_t s = 0; s < n; ++s) begin_[s + 1] += begin_[s];
  list_.resize(begin_[n]);
#pragma omp parallel for schedule(static) if (n >= 2048)
  for (std::int64_t b = 0; b < nb; ++b) {
    const auto& part = block_list[static_cast<std::size_t>(b)];
    const std::size_t first_slot = cell_begin[static_cast<std::size_t>(b) * block_cells];
    std::copy(part.begin(), part.end(), list_.begin() + static_cast<std::ptrdiff_t>(begin_[first_slot]));
  }
}

void RealSpaceSum::input_order_lists(std::vector<std::size_t>& begin, std::vector<int>& list) const {
  const std::size_t n = order_.size();
  std::vector<std::size_t> slot_of(n);
  for (std::size_t s = 0; s < n; ++s) slot_of[order_[s]] = s;
  begin.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) begin[i + 1] = begin[i] + (begin_[slot_of[i] + 1] - begin_[slot_of[i]]);
  list.resize(begin[n]);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t s = slot_of[i];
    auto out = list.begin() + static_cast<std::ptrdiff_t>(begin[i]);
    for (std::size_t q = begin_[s]; q < begin_[s + 1]; ++q)
      *out++ = static_cast<int>(order_[static_cast<std::size_t>(list_[q])]);
    std::sort(list.begin() + static_cast<std::ptrdiff_t>(begin[i]), out);
  }
}

void RealSpaceSum::apply(const double* forces, double* out, std::size_t nrhs, bool accumulate) const {
  // U_i = M0 [ F(0) F_i + sum_{j in r_cut} (F (I - rr) + G rr) F_j ]   ([PSE] eq. 10, A1-A4)
  const std::size_t n = order_.size();
  const std::size_t stride = 3 * n;
  const std::array<double, 3> inv = {1.0 / box_[0], 1.0 / box_[1], 1.0 / box_[2]};
  const auto ni = static_cast<std::int64_t>(n);
  const bool par = n * nrhs >= 512;
  // Forces in slot order: work_[(3 r + d) n + s] = F_r[3 order_[s] + d].
  work_.resize(3 * n * nrhs);
#pragma omp parallel for schedule(static) if (par)
  for (std::int64_t s = 0; s < ni; ++s) {
    const std::size_t i = order_[static_cast<std::size_t>(s)];
    for (std::size_t r = 0; r < nrhs; ++r)
      for (std::size_t d = 0; d < 3; ++d)
        work_[(3 * r + d) * n + static_cast<std::size_t>(s)] = forces[r * stride + 3 * i + d];
  }
  auto store = [&](std::size_t r, std::size_t i, const double* u) {
    for (std::size_t d = 0; d < 3; ++d) {
      double& o = out[r * stride + 3 * i + d];
      o = accumulate ? o + m0_ * u[d] : m0_ * u[d];
    }
  };
  if (use_table_) {
    const double* table = table_.data().data();
    const double inv_dr = 1.0 / table_.dr();
    const double L[3] = {box_[0], box_[1], box_[2]};
    const double inv_L[3] = {inv[0], inv[1], inv[2]};
#pragma omp parallel for schedule(dynamic, 64) if (par)
    for (std::int64_t ss = 0; ss < ni; ++ss) {
      const auto s = static_cast<std::size_t>(ss);
      const double xs[3] = {pos_[0][s], pos_[1][s], pos_[2][s]};
      for (std::size_t r = 0; r < nrhs; ++r) {
        const double* f = work_.data() + 3 * r * n;
        const SlotArrays arrays{{pos_[0].data(), pos_[1].data(), pos_[2].data()}, {f, f + n, f + 2 * n}};
        double u[3] = {self_ * f[s], self_ * f[n + s], self_ * f[2 * n + s]};
        table_row(list_.data() + begin_[s], begin_[s + 1] - begin_[s], xs, arrays, table, inv_dr, L, inv_L, u);
        store(r, order_[s], u);
      }
    }
    return;
  }
  // Closed forms evaluated per pair (PseOptions::real_space_table = false: the reference the
  // table is measured against).
#pragma omp parallel for schedule(dynamic, 64) if (par)
  for (std::int64_t ss = 0; ss < ni; ++ss) {
    const auto s = static_cast<std::size_t>(ss);
    for (std::size_t r = 0; r < nrhs; ++r) {
      const double* f = work_.data() + 3 * r * n;
      double u[3] = {self_ * f[s], self_ * f[n + s], self_ * f[2 * n + s]};
      for (std::size_t q = begin_[s]; q < begin_[s + 1]; ++q) {
        const auto t = static_cast<std::size_t>(list_[q]);
        const double d[3] = {minimum_image(pos_[0][s] - pos_[0][t], box_[0], inv[0]),
                             minimum_image(pos_[1][s] - pos_[1][t], box_[1], inv[1]),
                             minimum_image(pos_[2][s] - pos_[2][t], box_[2], inv[2])};
        const double ft[3] = {f[t], f[n + t], f[2 * n + t]};
        const double dist = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (dist == 0.0) {  // coincident particles: F(0) = G(0), the block is F(0) I
          for (int c = 0; c < 3; ++c) u[c] += self_ * ft[c];
          continue;
        }
        const FG v = real_space_fg(dist, p_.xi, p_.radius);
        pair_block_add(d[0], d[1], d[2], dist, v.f, v.g, ft, u);
      }
      store(r, order_[s], u);
    }
  }
}

}  // namespace rpyfmm::rpy::pse::detail
