// rpyfmm — fill_normal6 (random.hpp): normal6 for many indices at once, vectorized.
//
// Two passes per chunk of indices: Philox4x32-10 for the chunk's 3 blocks per index (AVX2:
// eight counters per instruction, 32 x 32 -> 64-bit products by vpmuludq; otherwise the
// portable loop), then Box-Muller on the 64-bit uniforms (random_detail::box_muller_bits, a
// branch-free loop that GCC vectorizes: this file is compiled with -fno-trapping-math and
// -fno-math-errno, which change no value, and -ffp-contract=off, so that every variant gives
// normal6's values bit for bit on a build without FMA contraction).
#include <algorithm>
#include <cstdint>
#include <string>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/random.hpp"

#if defined(__x86_64__)
#include <immintrin.h>
#define RPYFMM_RANDOM_X86 1
#endif

namespace rpyfmm::rpy {
namespace {

/// Indices per chunk: a multiple of 8 (the AVX2 Philox width); buffers stay in L1.
constexpr std::size_t kChunk = 64;

/// Philox4x32-10 multipliers and Weyl key increments (Salmon et al., SC'11; Random123).
constexpr std::uint32_t kPhiloxM0 = 0xD2511F53u;
constexpr std::uint32_t kPhiloxM1 = 0xCD9E8D57u;
constexpr std::uint32_t kPhiloxW0 = 0x9E3779B9u;
constexpr std::uint32_t kPhiloxW1 = 0xBB67AE85u;

/// Uniform words of one chunk: word w of block b of index k at words[(b * 4 + w) * kChunk + k].
struct ChunkWords {
  alignas(64) std::uint32_t w[3 * 4 * kChunk];
};

void philox_portable(const std::uint64_t* index, std::size_t m, std::uint64_t seed, std::uint64_t step,
                     std::uint32_t stream, ChunkWords& out) {
  const r123::Philox4x32 rng;
  for (std::size_t k = 0; k < m; ++k) {
    const auto key = random_detail::normal6_key(seed, index[k]);
    for (std::uint32_t b = 0; b < 3; ++b) {
      const auto r = rng(random_detail::normal6_counter(step, stream, index[k], b), key);
      for (int w = 0; w < 4; ++w) out.w[(b * 4 + w) * kChunk + k] = r.v[w];
    }
  }
}

#ifdef RPYFMM_RANDOM_X86
/// hi/lo 32-bit halves of a * M for eight unsigned 32-bit lanes.
__attribute__((target("avx2"))) inline void mulhilo8(__m256i a, std::uint32_t M, __m256i& hi, __m256i& lo) {
  const __m256i m = _mm256_set1_epi32(static_cast<int>(M));
  const __m256i even = _mm256_mul_epu32(a, m);                        // lanes 0, 2, 4, 6 as 64-bit products
  const __m256i odd = _mm256_mul_epu32(_mm256_srli_epi64(a, 32), m);  // lanes 1, 3, 5, 7
  lo = _mm256_blend_epi32(even, _mm256_slli_epi64(odd, 32), 0xAA);
  hi = _mm256_blend_epi32(_mm256_srli_epi64(even, 32), odd, 0xAA);
}

/// The same Philox4x32-10 rounds as r123::Philox4x32 on eight counters at once.
__attribute__((target("avx2"))) void philox_avx2(const std::uint64_t* index, std::size_t m, std::uint64_t seed,
                                                 std::uint64_t step, std::uint32_t stream, ChunkWords& out) {
  std::size_t k = 0;
  for (; k + 8 <= m; k += 8) {
    alignas(32) std::uint32_t lo[8], hi[8];
    for (int l = 0; l < 8; ++l) {
      lo[l] = static_cast<std::uint32_t>(index[k + l]);
      hi[l] = static_cast<std::uint32_t>(index[k + l] >> 32);
    }
    const __m256i index_lo = _mm256_load_si256(reinterpret_cast<const __m256i*>(lo));
    const __m256i key0 = _mm256_xor_si256(_mm256_set1_epi32(static_cast<int>(static_cast<std::uint32_t>(seed))),
                                          _mm256_load_si256(reinterpret_cast<const __m256i*>(hi)));
    const __m256i key1 = _mm256_set1_epi32(static_cast<int>(static_cast<std::uint32_t>(seed >> 32)));
    for (std::uint32_t b = 0; b < 3; ++b) {
      __m256i c0 = index_lo;
      __m256i c1 = _mm256_set1_epi32(static_cast<int>(stream + (b << 24)));
      __m256i c2 = _mm256_set1_epi32(static_cast<int>(static_cast<std::uint32_t>(step)));
      __m256i c3 = _mm256_set1_epi32(static_cast<int>(static_cast<std::uint32_t>(step >> 32)));
      __m256i k0 = key0;
      __m256i k1 = key1;
      for (int round = 0; round < 10; ++round) {
        __m256i hi0, lo0, hi1, lo1;
        mulhilo8(c0, kPhiloxM0, hi0, lo0);
        mulhilo8(c2, kPhiloxM1, hi1, lo1);
        c0 = _mm256_xor_si256(_mm256_xor_si256(hi1, c1), k0);
        c2 = _mm256_xor_si256(_mm256_xor_si256(hi0, c3), k1);
        c1 = lo1;
        c3 = lo0;
        k0 = _mm256_add_epi32(k0, _mm256_set1_epi32(static_cast<int>(kPhiloxW0)));
        k1 = _mm256_add_epi32(k1, _mm256_set1_epi32(static_cast<int>(kPhiloxW1)));
      }
      std::uint32_t* w = &out.w[b * 4 * kChunk + k];
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(w), c0);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(w + kChunk), c1);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(w + 2 * kChunk), c2);
      _mm256_storeu_si256(reinterpret_cast<__m256i*>(w + 3 * kChunk), c3);
    }
  }
  if (k < m) {  // tail: the portable rounds into the same slots
    ChunkWords tail;
    philox_portable(index + k, m - k, seed, step, stream, tail);
    for (std::uint32_t bw = 0; bw < 12; ++bw)
      for (std::size_t q = 0; q < m - k; ++q) out.w[bw * kChunk + k + q] = tail.w[bw * kChunk + q];
  }
}
#endif

/// Box-Muller over the chunk: out[6 k + 2 b + {0, 1}] from block b's words (u0 = w0:w1, u1 = w2:w3).
#define RPYFMM_BOX_MULLER_CHUNK_BODY                                                  \
  for (std::uint32_t b = 0; b < 3; ++b) {                                             \
    const std::uint32_t* w0 = &words.w[(b * 4 + 0) * kChunk];                         \
    const std::uint32_t* w1 = w0 + kChunk;                                            \
    const std::uint32_t* w2 = w1 + kChunk;                                            \
    const std::uint32_t* w3 = w2 + kChunk;                                            \
    _Pragma("omp simd") for (std::size_t k = 0; k < m; ++k) {                         \
      const std::uint64_t u0 = (static_cast<std::uint64_t>(w0[k]) << 32) | w1[k];     \
      const std::uint64_t u1 = (static_cast<std::uint64_t>(w2[k]) << 32) | w3[k];     \
      random_detail::box_muller_bits(u0, u1, g0[b * kChunk + k], g1[b * kChunk + k]); \
    }                                                                                 \
  }

void box_muller_portable(const ChunkWords& words, std::size_t m, double* g0, double* g1) {
  RPYFMM_BOX_MULLER_CHUNK_BODY
}

#ifdef RPYFMM_RANDOM_X86
__attribute__((target("avx2"))) void box_muller_avx2(const ChunkWords& words, std::size_t m, double* g0, double* g1) {
  RPYFMM_BOX_MULLER_CHUNK_BODY
}
#endif

#undef RPYFMM_BOX_MULLER_CHUNK_BODY

bool cpu_has_avx2() {
#ifdef RPYFMM_RANDOM_X86
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
#else
  return false;
#endif
}

}  // namespace

void fill_normal6(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                  std::span<double> out) {
  require(out.size() == 6 * index.size(), ErrorCode::invalid_input, "fill_normal6",
          "output length " + std::to_string(out.size()) + " is not 6 x " + std::to_string(index.size()) + " indices");
  require(stream < (1u << 24), ErrorCode::invalid_argument, "fill_normal6",
          "stream " + std::to_string(stream) + " must be below 2^24 (the top byte selects the Philox block)");
  const bool avx2 = cpu_has_avx2();
  ChunkWords words;
  alignas(64) double g0[3 * kChunk];
  alignas(64) double g1[3 * kChunk];
  for (std::size_t start = 0; start < index.size(); start += kChunk) {
    const std::size_t m = std::min(kChunk, index.size() - start);
#ifdef RPYFMM_RANDOM_X86
    if (avx2) {
      philox_avx2(index.data() + start, m, seed, step, stream, words);
      box_muller_avx2(words, m, g0, g1);
    } else
#endif
    {
      philox_portable(index.data() + start, m, seed, step, stream, words);
      box_muller_portable(words, m, g0, g1);
    }
    double* o = out.data() + 6 * start;
    for (std::size_t k = 0; k < m; ++k)
      for (std::uint32_t b = 0; b < 3; ++b) {
        o[6 * k + 2 * b] = g0[b * kChunk + k];
        o[6 * k + 2 * b + 1] = g1[b * kChunk + k];
      }
  }
  (void)avx2;
}

}  // namespace rpyfmm::rpy
