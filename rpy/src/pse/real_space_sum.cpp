// rpyfmm — PSE real-space sum: the plan and the neighbour lists of set_positions
// ([PSE] eq. 10 with App. A; docs/theory/pse.md). The products are in real_space_apply.cpp.
#include "real_space_sum.hpp"

#include <algorithm>
#include <limits>
#include <numbers>

#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"

namespace rpyfmm::rpy::pse::detail {

RealSpaceSum::RealSpaceSum(const PseParameters& p, const std::array<double, 3>& box, double viscosity, bool use_table,
                           PairCache cache, std::size_t cache_limit_bytes, bool full_lists)
    : p_(p),
      box_(box),
      m0_(1.0 / (6.0 * std::numbers::pi * viscosity * p.radius)),
      self_(real_space_self(p.xi, p.radius)),
      use_table_(use_table),
      full_lists_only_(full_lists),
      cache_(cache, cache_limit_bytes) {
  if (use_table_) table_ = PseRealSpaceTable(p.xi, p.radius, p.r_cut, p.tolerance / 10.0);
}

void RealSpaceSum::set_positions(std::span<const double> x) {
  const std::size_t n = x.size() / 3;
  require(n < static_cast<std::size_t>(std::numeric_limits<int>::max()), ErrorCode::invalid_input, "PseRpy",
          "too many particles for 32-bit neighbour indices");
  const CellGrid grid = cell_grid(box_, p_.r_cut);
  const std::vector<std::size_t> cell_begin = sort_into_cells(x, box_, grid, order_);
  gather_positions(x, order_, pos_);
  choose_plan(grid);
  const bool half_lists = lists_ == ListLayout::half;
  build_neighbour_lists({grid, cell_begin, pos_, box_, p_.r_cut, half_lists}, block_lists_, begin_, list_);
  half_row_starts(begin_, list_, half_lists, upper_);
  if (kernel_ == RowKernel::half_avx512) {
    plan_half_blocks(grid.nc, cell_begin, half_blocks_);
  } else {
    for (auto& colour : half_blocks_) colour.clear();
  }
  const bool cache_usable = kernel_ == RowKernel::half_avx512 || kernel_ == RowKernel::table;
  cache_.plan(cache_usable, kernel_ == RowKernel::table ? CacheLayout::row_entries : CacheLayout::half_chunks, begin_,
              upper_);
}

void RealSpaceSum::choose_plan(const CellGrid& grid) {
  // The plan follows the instruction-set level at set_positions (lists, cache layout, row kernels).
  bool avx512 = false;
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  avx512 = simd_level() == SimdLevel::avx512;
#endif
  if (!use_table_) {
    kernel_ = RowKernel::closed_form;
  } else if (!avx512) {
    kernel_ = RowKernel::table;
  } else {
    kernel_ = grid.cells ? RowKernel::half_avx512 : RowKernel::full_avx512;
  }
  lists_ = kernel_ == RowKernel::half_avx512 && !full_lists_only_ ? ListLayout::half : ListLayout::full;
}

Rows RealSpaceSum::full_rows() const {
  if (lists_ == ListLayout::full) return {begin_.data(), list_.data()};
  if (lists_ == ListLayout::half) {
    derive_full_rows(begin_, list_, full_begin_, full_list_);
    lists_ = ListLayout::half_and_full;
  }
  return {full_begin_.data(), full_list_.data()};
}

void RealSpaceSum::input_order_lists(std::vector<std::size_t>& begin, std::vector<int>& list) const {
  const std::size_t n = order_.size();
  const Rows rows = full_rows();
  std::vector<std::size_t> slot_of(n);
  for (std::size_t s = 0; s < n; ++s) slot_of[order_[s]] = s;
  begin.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) begin[i + 1] = begin[i] + (rows.begin[slot_of[i] + 1] - rows.begin[slot_of[i]]);
  list.resize(begin[n]);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t s = slot_of[i];
    auto out = list.begin() + static_cast<std::ptrdiff_t>(begin[i]);
    for (std::size_t q = rows.begin[s]; q < rows.begin[s + 1]; ++q)
      *out++ = static_cast<int>(order_[static_cast<std::size_t>(rows.list[q])]);
    std::sort(list.begin() + static_cast<std::ptrdiff_t>(begin[i]), out);
  }
}

RealSpaceSum::SlotLists RealSpaceSum::slot_lists() const {
  const std::size_t n = order_.size();
  const Rows rows = full_rows();
  return {order_, {rows.begin, n + 1}, {rows.list, rows.begin[n]}};
}

void RealSpaceSum::to_slots(const double* in, double* out) const {
  const std::size_t n = order_.size();
  for (std::size_t s = 0; s < n; ++s)
    for (std::size_t d = 0; d < 3; ++d) out[3 * s + d] = in[3 * order_[s] + d];
}

void RealSpaceSum::from_slots(const double* in, double* out) const {
  const std::size_t n = order_.size();
  for (std::size_t s = 0; s < n; ++s)
    for (std::size_t d = 0; d < 3; ++d) out[3 * order_[s] + d] = in[3 * s + d];
}

}  // namespace rpyfmm::rpy::pse::detail
