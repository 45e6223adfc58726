// rpyfmm — PSE real-space product (PSE.md Sec. 1.2, 6.2; [PSE] eq. 10 with App. A).
#include "real_space_sum.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>

#include "kernels_common.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::pse::detail {

RealSpaceSum::RealSpaceSum(const PseParameters& p, const std::array<double, 3>& box, double viscosity,
                           bool use_table)
    : p_(p),
      box_(box),
      m0_(1.0 / (6.0 * std::numbers::pi * viscosity * p.radius)),
      self_(real_space_self(p.xi, p.radius)),
      use_table_(use_table) {
  if (use_table_) table_ = PseRealSpaceTable(p.xi, p.radius, p.r_cut, p.tolerance / 10.0);
}

void RealSpaceSum::set_positions(std::span<const double> x) {
  x_.assign(x.begin(), x.end());
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
  // Cell list (counting sort by cell, stable).
  std::vector<std::size_t> cell_begin;
  std::vector<int> cell_items;
  std::vector<std::array<int, 3>> cell_of(n);
  if (cells) {
    const std::size_t ncell = static_cast<std::size_t>(nc[0]) * nc[1] * nc[2];
    cell_begin.assign(ncell + 1, 0);
    std::vector<std::size_t> id(n);
    for (std::size_t i = 0; i < n; ++i) {
      for (int d = 0; d < 3; ++d)
        cell_of[i][d] = std::min(static_cast<int>(x[3 * i + d] / box_[d] * nc[d]), nc[d] - 1);
      id[i] = (static_cast<std::size_t>(cell_of[i][0]) * nc[1] + cell_of[i][1]) * nc[2] + cell_of[i][2];
      ++cell_begin[id[i] + 1];
    }
    for (std::size_t c = 0; c < ncell; ++c) cell_begin[c + 1] += cell_begin[c];
    cell_items.resize(n);
    std::vector<std::size_t> fill(cell_begin.begin(), cell_begin.end() - 1);
    for (std::size_t i = 0; i < n; ++i) cell_items[fill[id[i]]++] = static_cast<int>(i);
  }
  order_.resize(n);
  for (std::size_t q = 0; q < n; ++q) order_[q] = cells ? static_cast<std::size_t>(cell_items[q]) : q;
  const std::array<double, 3> inv = {1.0 / box_[0], 1.0 / box_[1], 1.0 / box_[2]};
  auto close = [&](std::size_t i, std::size_t j) {
    const double dx = minimum_image(x[3 * i] - x[3 * j], box_[0], inv[0]);
    const double dy = minimum_image(x[3 * i + 1] - x[3 * j + 1], box_[1], inv[1]);
    const double dz = minimum_image(x[3 * i + 2] - x[3 * j + 2], box_[2], inv[2]);
    return dx * dx + dy * dy + dz * dz < rc2;
  };
  // visit(i, fn): calls fn(j) for every j != i within r_cut.
  auto visit = [&](std::size_t i, auto&& fn) {
    if (!cells) {
      for (std::size_t j = 0; j < n; ++j)
        if (j != i && close(i, j)) fn(j);
      return;
    }
    for (int ax = -1; ax <= 1; ++ax)
      for (int ay = -1; ay <= 1; ++ay)
        for (int az = -1; az <= 1; ++az) {
          const int cx = (cell_of[i][0] + ax + nc[0]) % nc[0];
          const int cy = (cell_of[i][1] + ay + nc[1]) % nc[1];
          const int cz = (cell_of[i][2] + az + nc[2]) % nc[2];
          const std::size_t c = (static_cast<std::size_t>(cx) * nc[1] + cy) * nc[2] + cz;
          for (std::size_t q = cell_begin[c]; q < cell_begin[c + 1]; ++q) {
            const auto j = static_cast<std::size_t>(cell_items[q]);
            if (j != i && close(i, j)) fn(j);
          }
        }
  };
  begin_.assign(n + 1, 0);
  const auto ni = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(dynamic, 256) if (n >= 2048)
  for (std::int64_t i = 0; i < ni; ++i) {
    std::size_t count = 0;
    visit(static_cast<std::size_t>(i), [&](std::size_t) { ++count; });
    begin_[static_cast<std::size_t>(i) + 1] = count;
  }
  for (std::size_t i = 0; i < n; ++i) begin_[i + 1] += begin_[i];
  list_.resize(begin_[n]);
#pragma omp parallel for schedule(dynamic, 256) if (n >= 2048)
  for (std::int64_t i = 0; i < ni; ++i) {
    const std::size_t b = begin_[static_cast<std::size_t>(i)];
    std::size_t q = b;
    visit(static_cast<std::size_t>(i), [&](std::size_t j) { list_[q++] = static_cast<int>(j); });
    std::sort(list_.begin() + static_cast<std::ptrdiff_t>(b), list_.begin() + static_cast<std::ptrdiff_t>(q));
  }
}

void RealSpaceSum::apply(const double* forces, double* out, std::size_t nrhs, bool accumulate) const {
  // U_i = M0 [ F(0) F_i + sum_{j in r_cut} (F (I - rr) + G rr) F_j ]   ([PSE] eq. 10, A1-A4)
  const std::size_t n = x_.size() / 3;
  const std::size_t stride = 3 * n;
  const std::array<double, 3> inv = {1.0 / box_[0], 1.0 / box_[1], 1.0 / box_[2]};
  const auto ni = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(dynamic, 64) if (n * nrhs >= 512)
  for (std::int64_t ii = 0; ii < ni; ++ii) {
    // Cell order: consecutive particles share most neighbours, whose positions and forces
    // then come from cache (each particle's sum is the same whatever the visiting order).
    const std::size_t i = order_[static_cast<std::size_t>(ii)];
    // Small fixed-size accumulator per rhs; large blocks (dense assembly) loop rhs in chunks.
    constexpr std::size_t kChunk = 16;
    for (std::size_t r0 = 0; r0 < nrhs; r0 += kChunk) {
      const std::size_t nr = std::min(kChunk, nrhs - r0);
      double u[3 * kChunk];
      for (std::size_t r = 0; r < nr; ++r)
        for (int d = 0; d < 3; ++d) u[3 * r + d] = self_ * forces[(r0 + r) * stride + 3 * i + d];
      for (std::size_t q = begin_[i]; q < begin_[i + 1]; ++q) {
        const auto j = static_cast<std::size_t>(list_[q]);
        const double dx = minimum_image(x_[3 * i] - x_[3 * j], box_[0], inv[0]);
        const double dy = minimum_image(x_[3 * i + 1] - x_[3 * j + 1], box_[1], inv[1]);
        const double dz = minimum_image(x_[3 * i + 2] - x_[3 * j + 2], box_[2], inv[2]);
        const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
        if (r == 0.0) {  // coincident particles: F(0) = G(0), the block is F(0) I
          for (std::size_t k = 0; k < nr; ++k)
            for (int d = 0; d < 3; ++d) u[3 * k + d] += self_ * forces[(r0 + k) * stride + 3 * j + d];
          continue;
        }
        double F;
        double G;
        if (use_table_) {
          table_fg(table_.data().data(), 1.0 / table_.dr(), r, F, G);
        } else {
          const FG v = real_space_fg(r, p_.xi, p_.radius);
          F = v.f;
          G = v.g;
        }
        for (std::size_t k = 0; k < nr; ++k)
          pair_block_add(dx, dy, dz, r, F, G, forces + (r0 + k) * stride + 3 * j, u + 3 * k);
      }
      for (std::size_t r = 0; r < nr; ++r)
        for (int d = 0; d < 3; ++d) {
          double& o = out[(r0 + r) * stride + 3 * i + d];
          o = accumulate ? o + m0_ * u[3 * r + d] : m0_ * u[3 * r + d];
        }
    }
  }
}

}  // namespace rpyfmm::rpy::pse::detail
