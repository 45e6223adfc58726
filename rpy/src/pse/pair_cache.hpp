// rpyfmm — the pair cache of the PSE real-space sum (real_space_sum.hpp): each pair's values
// F - F(0), G - G(0), e_x, e_y, e_z, kept by the first product after set_positions and read by
// the later products with the same positions instead of evaluating the pair again. The fill
// rounds the values to the cache's precision before using them, so that every product applies
// the same operator. F and G are kept as differences from their r = 0 values (the table's first
// node), which a coincident pair thus gets back exactly in float too: its block stays equal to
// the self block, and M_r stays exactly singular (positive semidefinite) with coincident
// particles. Private.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

namespace rpyfmm::rpy::pse::detail {

/// Storage of the pair cache: none, or the five values of each pair in float or in double.
enum class PairCache { off, single_precision, double_precision };

/// The layout, which follows the rows that read it:
///  - half_chunks (AVX-512 half rows): per half row s, chunks [chunk_begin[s], chunk_begin[s + 1])
///    of eight pairs, each five vectors of eight lanes (padding lanes included);
///  - row_entries (portable rows): five arrays with one value per entry of the full rows.
enum class CacheLayout { half_chunks, row_entries };

/// The state for the current positions: not kept, kept but not yet filled, filled.
enum class CacheState { off, empty, filled };

class PairCacheStore {
 public:
  PairCacheStore(PairCache precision, std::size_t limit_bytes) : precision_(precision), limit_(limit_bytes) {}

  /// Plans the cache for new positions whose rows are CSR `begin` and whose half rows start at
  /// `upper`; kept (state empty) where `usable` (the rows read a cache), the precision is not off
  /// and it fits in the limit, else released (state off).
  void plan(bool usable, CacheLayout layout, const std::vector<std::size_t>& begin,
            const std::vector<std::size_t>& upper);

  [[nodiscard]] CacheState state() const { return state_; }
  /// After the product that filled it.
  void mark_filled() const {
    if (state_ == CacheState::empty) state_ = CacheState::filled;
  }
  [[nodiscard]] PairCache precision() const { return precision_; }
  [[nodiscard]] std::size_t kept_bytes() const { return state_ != CacheState::off ? bytes_ : 0; }
  /// half_chunks: the first chunk of every half row.
  [[nodiscard]] const std::vector<std::size_t>& chunk_begin() const { return chunk_begin_; }
  /// The values, 64-byte aligned.
  [[nodiscard]] void* data() const;

 private:
  PairCache precision_;
  std::size_t limit_;
  mutable CacheState state_ = CacheState::off;
  std::size_t bytes_ = 0;
  std::vector<std::size_t> chunk_begin_;
  std::unique_ptr<double[]> store_;  // 64-byte aligned inside (data())
  std::size_t capacity_ = 0;         // doubles allocated
};

}  // namespace rpyfmm::rpy::pse::detail
