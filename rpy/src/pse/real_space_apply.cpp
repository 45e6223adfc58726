// rpyfmm — the products of the PSE real-space sum (real_space_sum.hpp):
//   U_i = M0 [ F(0) F_i + sum_{j within r_cut} (F (I - ee) + G ee) F_j ]
// ([PSE] eq. 10 with eqs. A1-A4; docs/theory/pse.md), by the row kernel that set_positions chose.
#include <algorithm>
#include <cstdint>
#include <type_traits>

#include "pair_rows.hpp"
#include "pair_rows_avx512.hpp"
#include "real_space_sum.hpp"

namespace rpyfmm::rpy::pse::detail {

void RealSpaceSum::apply(const double* forces, double* out, std::size_t nrhs, bool accumulate) const {
  // Where the pair cache is kept, the first product after set_positions fills it and every
  // product (this one included) applies the blocks as kept, rounded to the cache's precision: the
  // operator is the same whatever was called before (docs/reproducibility.md).
  apply_mapped(forces, out, nrhs, accumulate, order_.data());
}

void RealSpaceSum::apply_slots(const double* forces, double* out, std::size_t nrhs) const {
  apply_mapped(forces, out, nrhs, false, nullptr);
}

void RealSpaceSum::apply_mapped(const double* forces, double* out, std::size_t nrhs, bool accumulate,
                                const std::size_t* map) const {
  switch (kernel_) {
    case RowKernel::half_avx512:
    case RowKernel::full_avx512:
      apply_avx512(forces, out, nrhs, accumulate, map);
      return;
    case RowKernel::table:
      gather_forces(forces, nrhs, map);
      apply_table_rows(out, nrhs, accumulate, map);
      return;
    case RowKernel::closed_form:
      gather_forces(forces, nrhs, map);
      apply_closed_forms(out, nrhs, accumulate, map);
      return;
  }
}

RealSpaceSum::Frame RealSpaceSum::frame() const {
  return {use_table_ ? table_.data().data() : nullptr,
          use_table_ ? 1.0 / table_.dr() : 0.0,
          {box_[0], box_[1], box_[2]},
          {1.0 / box_[0], 1.0 / box_[1], 1.0 / box_[2]}};
}

template <class Force, class Row>
void RealSpaceSum::for_each_row(double* out, std::size_t nrhs, bool accumulate, const std::size_t* map, Force&& force,
                                Row&& row) const {
  const std::size_t n = order_.size();
  const std::size_t stride = 3 * n;
  const auto ni = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(dynamic, 64) if (n * nrhs >= 512)
  for (std::int64_t ss = 0; ss < ni; ++ss) {
    const auto s = static_cast<std::size_t>(ss);
    const std::size_t i = map != nullptr ? map[s] : s;
    for (std::size_t r = 0; r < nrhs; ++r) {
      double u[3] = {self_ * force(s, r, 0), self_ * force(s, r, 1), self_ * force(s, r, 2)};
      row(s, r, u);
      for (std::size_t d = 0; d < 3; ++d) {
        double& o = out[r * stride + 3 * i + d];
        o = accumulate ? o + m0_ * u[d] : m0_ * u[d];
      }
    }
  }
}

// ---- AVX-512 rows ----

RealSpaceSum::PackedRows RealSpaceSum::pack_rows(const double* forces, std::size_t nrhs, const std::size_t* map,
                                                 bool cached) const {
  // Rows per slot and rhs, filled straight from the input forces: x, y, z, fx, fy, fz, 0, 0 (8
  // doubles, 64-byte aligned) where the pairs are evaluated, or fx, fy, fz, 0 (4 doubles) where
  // the pair cache holds them (later products with these positions). With half rows, also the
  // zeroed sums.
  const std::size_t n = order_.size();
  const bool half = kernel_ == RowKernel::half_avx512;
  PackedRows pk{nullptr, nullptr, cached ? std::size_t{4} : std::size_t{8}, cached ? std::size_t{0} : std::size_t{3}};
  const std::size_t width = pk.width, force_at = pk.force_at;
  // (Never shrunk: growing back would zero-fill the tail at every switch of width.)
  if (packed_.size() < width * (n * nrhs + 1)) packed_.resize(width * (n * nrhs + 1));
  double* packed = packed_.data();
  packed += (width - (reinterpret_cast<std::uintptr_t>(packed) / sizeof(double)) % width) % width;
  if (half) acc_.resize(4 * n * nrhs + 4);
  double* acc = acc_.data();  // rows of 4 doubles, 32-byte aligned
  if (half) acc += (4 - (reinterpret_cast<std::uintptr_t>(acc) / sizeof(double)) % 4) % 4;
  const std::size_t stride = 3 * n;
#pragma omp parallel for schedule(static) if (n * nrhs >= 512)
  for (std::int64_t ss = 0; ss < static_cast<std::int64_t>(n); ++ss) {
    const auto s = static_cast<std::size_t>(ss);
    const std::size_t i = map != nullptr ? map[s] : s;
    for (std::size_t r = 0; r < nrhs; ++r) {
      double* row = packed + width * (r * n + s);
      for (std::size_t d = 0; d < 3; ++d) {
        if (!cached) row[d] = pos_[d][s];
        row[force_at + d] = forces[r * stride + 3 * i + d];
      }
      std::fill(row + force_at + 3, row + width, 0.0);
      if (half) std::fill_n(acc + 4 * (r * n + s), 4, 0.0);
    }
  }
  pk.packed = packed;
  pk.acc = acc;
  return pk;
}

void RealSpaceSum::apply_avx512(const double* forces, double* out, std::size_t nrhs, bool accumulate,
                                const std::size_t* map) const {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  const std::size_t n = order_.size();
  const bool half = kernel_ == RowKernel::half_avx512;
  const bool cached = half && cache_.state() == CacheState::filled;
  const PackedRows pk = pack_rows(forces, nrhs, map, cached);
  auto packed_force = [&](std::size_t s, std::size_t r, std::size_t d) {
    return pk.packed[pk.width * (r * n + s) + pk.force_at + d];
  };
  if (half) {
    if (cached) {
      apply_cached_avx512(pk.packed, nrhs, pk.acc);
    } else {
      apply_half_avx512(pk.packed, nrhs, pk.acc);
    }
    const double* acc = pk.acc;
    for_each_row(out, nrhs, accumulate, map, packed_force, [&](std::size_t s, std::size_t r, double* u) {
      for (std::size_t d = 0; d < 3; ++d) u[d] += acc[4 * (r * n + s) + d];
    });
    return;
  }
  const Rows rows = full_rows();
  const Frame f = frame();
  for_each_row(out, nrhs, accumulate, map, packed_force, [&](std::size_t s, std::size_t r, double* u) {
    packed_row_avx512(rows.list + rows.begin[s], rows.begin[s + 1] - rows.begin[s], s, pk.packed + 8 * r * n, f.table,
                      f.inv_dr, f.L, f.inv_L, u);
  });
#else
  (void)forces, (void)out, (void)nrhs, (void)accumulate, (void)map;
#endif
}

void RealSpaceSum::apply_half_avx512(const double* packed, std::size_t nrhs, double* acc) const {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  const std::size_t n = order_.size();
  const Frame f = frame();
  const auto& chunk_begin = cache_.chunk_begin();
  auto sweep = [&](auto* cache) {  // void*: no cache
    using T = std::remove_pointer_t<decltype(cache)>;
    sweep_half_rows(half_blocks_, n, nrhs, [&](std::size_t s, std::size_t r) {
      T* chunk = nullptr;
      if constexpr (!std::is_void_v<T>) chunk = cache + 40 * chunk_begin[s];
      packed_half_row_avx512(list_.data() + upper_[s], begin_[s + 1] - upper_[s], s, packed + 8 * r * n, f.table,
                             f.inv_dr, f.L, f.inv_L, acc + 4 * r * n, chunk);
    });
  };
  if (cache_.state() != CacheState::empty)
    sweep(static_cast<void*>(nullptr));
  else if (cache_.precision() == PairCache::single_precision)
    sweep(static_cast<float*>(cache_.data()));
  else
    sweep(static_cast<double*>(cache_.data()));
  cache_.mark_filled();
#else
  (void)packed, (void)nrhs, (void)acc;
#endif
}

void RealSpaceSum::apply_cached_avx512(const double* forces, std::size_t nrhs, double* acc) const {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  const std::size_t n = order_.size();
  const auto& chunk_begin = cache_.chunk_begin();
  auto sweep = [&](const auto* cache) {
    sweep_half_rows(half_blocks_, n, nrhs, [&](std::size_t s, std::size_t r) {
      cached_half_row_avx512(list_.data() + upper_[s], begin_[s + 1] - upper_[s], s, forces + 4 * r * n,
                             cache + 40 * chunk_begin[s], table_.data().data(), acc + 4 * r * n);
    });
  };
  if (cache_.precision() == PairCache::single_precision)
    sweep(static_cast<const float*>(cache_.data()));
  else
    sweep(static_cast<const double*>(cache_.data()));
#else
  (void)forces, (void)nrhs, (void)acc;
#endif
}

// ---- portable rows ----

void RealSpaceSum::gather_forces(const double* forces, std::size_t nrhs, const std::size_t* map) const {
  const std::size_t n = order_.size();
  const std::size_t stride = 3 * n;
  work_.resize(3 * n * nrhs);
#pragma omp parallel for schedule(static) if (n * nrhs >= 512)
  for (std::int64_t s = 0; s < static_cast<std::int64_t>(n); ++s) {
    const std::size_t i = map != nullptr ? map[s] : static_cast<std::size_t>(s);
    for (std::size_t r = 0; r < nrhs; ++r)
      for (std::size_t d = 0; d < 3; ++d)
        work_[(3 * r + d) * n + static_cast<std::size_t>(s)] = forces[r * stride + 3 * i + d];
  }
}

void RealSpaceSum::apply_table_rows(double* out, std::size_t nrhs, bool accumulate, const std::size_t* map) const {
  const std::size_t n = order_.size();
  const Rows rows = full_rows();
  const Frame fr = frame();
  const CacheState cache = cache_.state();
  auto slot_force = [&](std::size_t s, std::size_t r, std::size_t d) { return work_[(3 * r + d) * n + s]; };
  auto rows_with = [&](auto c) {  // c: RowCache<T>, or nullptr without the cache
    for_each_row(out, nrhs, accumulate, map, slot_force, [&](std::size_t s, std::size_t r, double* u) {
      const double* f = work_.data() + 3 * r * n;
      const double xs[3] = {pos_[0][s], pos_[1][s], pos_[2][s]};
      const SlotArrays arrays{{pos_[0].data(), pos_[1].data(), pos_[2].data()}, {f, f + n, f + 2 * n}};
      const int* nb = rows.list + rows.begin[s];
      const std::size_t count = rows.begin[s + 1] - rows.begin[s];
      if constexpr (std::is_same_v<decltype(c), std::nullptr_t>) {
        table_row(nb, count, xs, arrays, fr.table, fr.inv_dr, fr.L, fr.inv_L, u);
      } else if (cache == CacheState::filled) {
        cached_row(nb, count, arrays, fr.table, c, rows.begin[s], u);
      } else {
        fill_row(nb, count, xs, arrays, fr.table, fr.inv_dr, fr.L, fr.inv_L, c, rows.begin[s], u);
      }
    });
  };
  if (cache == CacheState::off) {
    rows_with(nullptr);
  } else if (cache_.precision() == PairCache::single_precision) {
    rows_with(RowCache<float>{static_cast<float*>(cache_.data()), rows.begin[n]});
  } else {
    rows_with(RowCache<double>{static_cast<double*>(cache_.data()), rows.begin[n]});
  }
  cache_.mark_filled();
}

void RealSpaceSum::apply_closed_forms(double* out, std::size_t nrhs, bool accumulate, const std::size_t* map) const {
  const std::size_t n = order_.size();
  const Rows rows = full_rows();
  const Frame fr = frame();
  auto slot_force = [&](std::size_t s, std::size_t r, std::size_t d) { return work_[(3 * r + d) * n + s]; };
  for_each_row(out, nrhs, accumulate, map, slot_force, [&](std::size_t s, std::size_t r, double* u) {
    const double* f = work_.data() + 3 * r * n;
    const double xs[3] = {pos_[0][s], pos_[1][s], pos_[2][s]};
    const SlotArrays arrays{{pos_[0].data(), pos_[1].data(), pos_[2].data()}, {f, f + n, f + 2 * n}};
    closed_form_row(rows.list + rows.begin[s], rows.begin[s + 1] - rows.begin[s], xs, arrays, fr.L, fr.inv_L, self_,
                    p_.xi, p_.radius, u);
  });
}

}  // namespace rpyfmm::rpy::pse::detail
