// rpyfmm — the candidate filters of the PSE neighbour-list build (neighbour_lists.cpp) with
// AVX-512 and AVX2 intrinsics.
#include "list_filter.hpp"

#if defined(RPYFMM_HAVE_DIRECT_AVX512)

#include <cstdint>

namespace rpyfmm::rpy::pse::detail {

// GCC 12's AVX-512 headers start gathers and conversions from _mm512_undefined_*, which trips
// its own uninitialized-use warnings in this translation unit.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

/// Compares eight candidates per step and stores the kept slots with one masked compress.
RPYFMM_DIRECT_AVX512 std::size_t pairs_within_avx512(const double* xt, const double* yt, const double* zt,
                                                     std::size_t t0, std::size_t count, const double xs[3],
                                                     const double shift[3], double rc2, int* out) {
  const __m512d x = _mm512_set1_pd(xs[0]), y = _mm512_set1_pd(xs[1]), z = _mm512_set1_pd(xs[2]);
  const __m512d sx = _mm512_set1_pd(shift[0]), sy = _mm512_set1_pd(shift[1]), sz = _mm512_set1_pd(shift[2]);
  const __m512d r2 = _mm512_set1_pd(rc2);
  const __m512i lane = _mm512_set_epi32(0, 0, 0, 0, 0, 0, 0, 0, 7, 6, 5, 4, 3, 2, 1, 0);
  std::size_t used = 0;
  for (std::size_t q = 0; q < count; q += 8) {
    const auto live = static_cast<__mmask8>(count - q >= 8 ? 0xFF : (1u << (count - q)) - 1u);
    const __m512d dx = _mm512_sub_pd(_mm512_sub_pd(x, _mm512_maskz_loadu_pd(live, xt + t0 + q)), sx);
    const __m512d dy = _mm512_sub_pd(_mm512_sub_pd(y, _mm512_maskz_loadu_pd(live, yt + t0 + q)), sy);
    const __m512d dz = _mm512_sub_pd(_mm512_sub_pd(z, _mm512_maskz_loadu_pd(live, zt + t0 + q)), sz);
    const __m512d d2 =
        _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)), _mm512_mul_pd(dz, dz));
    const __mmask8 keep = _mm512_mask_cmp_pd_mask(live, d2, r2, _CMP_LT_OQ);
    const __m512i idx = _mm512_add_epi32(_mm512_set1_epi32(static_cast<int>(t0 + q)), lane);
    _mm512_storeu_si512(out + used, _mm512_maskz_compress_epi32(keep, idx));
    used += static_cast<std::size_t>(__builtin_popcount(keep));
  }
  return used;
}

namespace {

/// _mm_shuffle_epi8 controls that move the 32-bit lanes set in a 4-bit mask to the front, in
/// order (the rest zeroed): the compaction of pairs_within_avx2.
struct CompactTable {
  alignas(16) std::uint8_t control[16][16];
  constexpr CompactTable() : control{} {
    for (int m = 0; m < 16; ++m) {
      int k = 0;
      for (int lane = 0; lane < 4; ++lane)
        if ((m >> lane) & 1) {
          for (int b = 0; b < 4; ++b) control[m][4 * k + b] = static_cast<std::uint8_t>(4 * lane + b);
          ++k;
        }
      for (int b = 4 * k; b < 16; ++b) control[m][b] = 0x80;
    }
  }
};
constexpr CompactTable kCompact{};

}  // namespace

/// Four candidates per step, the kept slots moved to the front by a byte shuffle from a
/// 16-entry table (kCompact). Compiled for AVX2 without FMA, so rounded as pairs_within_avx512.
__attribute__((target("avx2"))) std::size_t pairs_within_avx2(const double* xt, const double* yt, const double* zt,
                                                              std::size_t t0, std::size_t count, const double xs[3],
                                                              const double shift[3], double rc2, std::size_t skip,
                                                              int* out) {
  const __m256d x = _mm256_set1_pd(xs[0]), y = _mm256_set1_pd(xs[1]), z = _mm256_set1_pd(xs[2]);
  const __m256d sx = _mm256_set1_pd(shift[0]), sy = _mm256_set1_pd(shift[1]), sz = _mm256_set1_pd(shift[2]);
  const __m256d r2 = _mm256_set1_pd(rc2);
  const __m128i lane = _mm_setr_epi32(0, 1, 2, 3);
  std::size_t used = 0;
  for (std::size_t q = 0; q < count; q += 4) {
    const std::size_t left = count - q;
    __m256d vx, vy, vz;
    if (left >= 4) {
      vx = _mm256_loadu_pd(xt + t0 + q);
      vy = _mm256_loadu_pd(yt + t0 + q);
      vz = _mm256_loadu_pd(zt + t0 + q);
    } else {
      const __m256i live =
          _mm256_cmpgt_epi64(_mm256_set1_epi64x(static_cast<long long>(left)), _mm256_setr_epi64x(0, 1, 2, 3));
      vx = _mm256_maskload_pd(xt + t0 + q, live);
      vy = _mm256_maskload_pd(yt + t0 + q, live);
      vz = _mm256_maskload_pd(zt + t0 + q, live);
    }
    const __m256d dx = _mm256_sub_pd(_mm256_sub_pd(x, vx), sx);
    const __m256d dy = _mm256_sub_pd(_mm256_sub_pd(y, vy), sy);
    const __m256d dz = _mm256_sub_pd(_mm256_sub_pd(z, vz), sz);
    const __m256d d2 =
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz));
    unsigned keep = static_cast<unsigned>(_mm256_movemask_pd(_mm256_cmp_pd(d2, r2, _CMP_LT_OQ)));
    if (left < 4) keep &= (1u << left) - 1u;
    if (skip - (t0 + q) < 4) keep &= ~(1u << (skip - (t0 + q)));
    const __m128i idx = _mm_add_epi32(_mm_set1_epi32(static_cast<int>(t0 + q)), lane);
    const __m128i control = _mm_load_si128(reinterpret_cast<const __m128i*>(kCompact.control[keep]));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + used), _mm_shuffle_epi8(idx, control));
    used += static_cast<std::size_t>(__builtin_popcount(keep));
  }
  return used;
}
#pragma GCC diagnostic pop

}  // namespace rpyfmm::rpy::pse::detail

#endif  // RPYFMM_HAVE_DIRECT_AVX512
