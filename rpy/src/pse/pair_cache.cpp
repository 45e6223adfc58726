// rpyfmm — the pair cache's storage (pair_cache.hpp).
#include "pair_cache.hpp"

#include <cstdint>

namespace rpyfmm::rpy::pse::detail {

void PairCacheStore::plan(bool usable, CacheLayout layout, const std::vector<std::size_t>& begin,
                          const std::vector<std::size_t>& upper) {
  const std::size_t n = begin.size() - 1;
  chunk_begin_.assign(n + 1, 0);
  for (std::size_t s = 0; s < n; ++s) chunk_begin_[s + 1] = chunk_begin_[s] + (begin[s + 1] - upper[s] + 7) / 8;
  const std::size_t value_bytes = precision_ == PairCache::single_precision ? sizeof(float) : sizeof(double);
  bytes_ = layout == CacheLayout::row_entries ? 5 * value_bytes * begin[n] : 40 * value_bytes * chunk_begin_[n];
  const bool keep = precision_ != PairCache::off && usable && bytes_ <= limit_;
  state_ = keep ? CacheState::empty : CacheState::off;
  if (!keep) {
    store_.reset();
    capacity_ = 0;
    return;
  }
  // Grown with 25% headroom and never value-initialized (the filling product writes every
  // value): the pair count changes a little at every step, and a std::vector would copy and
  // zero-fill tens of MB whenever it grows.
  const std::size_t need = bytes_ / sizeof(double) + 8;
  if (capacity_ < need) {
    store_.reset();
    capacity_ = need + need / 4;
    store_ = std::make_unique_for_overwrite<double[]>(capacity_);
  }
}

void* PairCacheStore::data() const {
  double* c = store_.get();
  return c + (8 - (reinterpret_cast<std::uintptr_t>(c) / sizeof(double)) % 8) % 8;  // 64-byte aligned
}

}  // namespace rpyfmm::rpy::pse::detail
