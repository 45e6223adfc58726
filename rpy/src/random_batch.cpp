// rpyfmm — fill_normal and fill_normal6 (random.hpp): normal3 / normal6 / normal6f for many
// indices at once, vectorized.
//
// Two passes per chunk of indices: Philox4x32-10 for the chunk's 3 blocks per index (AVX-512:
// sixteen counters per instruction, AVX2: eight, 32 x 32 -> 64-bit products by vpmuludq;
// otherwise the portable loop), then Box-Muller on the uniforms (random_detail::box_muller_bits in
// double, box_muller_bits_f in single precision: a branch-free loop that GCC vectorizes; this
// file is compiled with -fno-trapping-math and -fno-math-errno, which change no value, and
// -ffp-contract=off, so that every variant gives normal6's / normal6f's values bit for bit on a
// build without FMA contraction).
#include <algorithm>
#include <cstdint>
#include <string>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/rpy/random.hpp"

#if defined(RPYFMM_HAVE_X86_KERNELS)
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

/// The Philox blocks drawn per index: block b uses counter (index_lo, c1[b], step_lo, step_hi)
/// and key (seed_lo ^ index_hi, seed_hi). normal6: c1 = stream + 2^24 b, b < 3; normal3:
/// c1 = stream, stream ^ 2^31.
struct Blocks {
  std::uint32_t c1[3];
  std::uint32_t count;
};

void philox_portable(const std::uint64_t* index, std::size_t m, std::uint64_t seed, std::uint64_t step,
                     const Blocks& blocks, ChunkWords& out) {
  const r123::Philox4x32 rng;
  for (std::size_t k = 0; k < m; ++k) {
    const auto key = random_detail::normal6_key(seed, index[k]);
    for (std::uint32_t b = 0; b < blocks.count; ++b) {
      const auto r = rng(random_detail::philox_counter(index[k], blocks.c1[b], step), key);
      for (int w = 0; w < 4; ++w) out.w[(b * 4 + w) * kChunk + k] = r.v[w];
    }
  }
}

#ifdef RPYFMM_RANDOM_X86
#define RPYFMM_RANDOM_TARGET_AVX2 __attribute__((target("avx2")))
#define RPYFMM_RANDOM_TARGET_AVX512 __attribute__((target("avx512f")))

/// Eight unsigned 32-bit lanes (AVX2).
struct Avx2Lanes {
  static constexpr std::size_t width = 8;
  using V = __m256i;
  RPYFMM_RANDOM_TARGET_AVX2 static V load(const std::uint32_t* p) {
    return _mm256_load_si256(reinterpret_cast<const V*>(p));
  }
  RPYFMM_RANDOM_TARGET_AVX2 static void store(std::uint32_t* p, V v) {
    _mm256_storeu_si256(reinterpret_cast<V*>(p), v);
  }
  RPYFMM_RANDOM_TARGET_AVX2 static V set1(std::uint32_t v) { return _mm256_set1_epi32(static_cast<int>(v)); }
  RPYFMM_RANDOM_TARGET_AVX2 static V bxor(V a, V b) { return _mm256_xor_si256(a, b); }
  RPYFMM_RANDOM_TARGET_AVX2 static V add(V a, V b) { return _mm256_add_epi32(a, b); }
  /// hi/lo 32-bit halves of a * M, lane by lane (32 x 32 -> 64-bit products by vpmuludq).
  RPYFMM_RANDOM_TARGET_AVX2 static void mulhilo(V a, std::uint32_t M, V& hi, V& lo) {
    const V m = set1(M);
    const V even = _mm256_mul_epu32(a, m);                        // lanes 0, 2, 4, 6 as 64-bit products
    const V odd = _mm256_mul_epu32(_mm256_srli_epi64(a, 32), m);  // lanes 1, 3, 5, 7
    lo = _mm256_blend_epi32(even, _mm256_slli_epi64(odd, 32), 0xAA);
    hi = _mm256_blend_epi32(_mm256_srli_epi64(even, 32), odd, 0xAA);
  }
};

/// Sixteen unsigned 32-bit lanes (AVX-512F).
struct Avx512Lanes {
  static constexpr std::size_t width = 16;
  using V = __m512i;
  RPYFMM_RANDOM_TARGET_AVX512 static V load(const std::uint32_t* p) { return _mm512_load_si512(p); }
  RPYFMM_RANDOM_TARGET_AVX512 static void store(std::uint32_t* p, V v) { _mm512_storeu_si512(p, v); }
  RPYFMM_RANDOM_TARGET_AVX512 static V set1(std::uint32_t v) { return _mm512_set1_epi32(static_cast<int>(v)); }
  RPYFMM_RANDOM_TARGET_AVX512 static V bxor(V a, V b) { return _mm512_xor_si512(a, b); }
  RPYFMM_RANDOM_TARGET_AVX512 static V add(V a, V b) { return _mm512_add_epi32(a, b); }
  /// As Avx2Lanes::mulhilo. The maskz forms with all lanes set: GCC 12's plain ones read an
  /// undefined register and trip -Wmaybe-uninitialized in its own header.
  RPYFMM_RANDOM_TARGET_AVX512 static void mulhilo(V a, std::uint32_t M, V& hi, V& lo) {
    constexpr __mmask8 all = 0xFF;
    const V m = set1(M);
    const V even = _mm512_maskz_mul_epu32(all, a, m);
    const V odd = _mm512_maskz_mul_epu32(all, _mm512_maskz_srli_epi64(all, a, 32), m);
    lo = _mm512_mask_blend_epi32(0xAAAA, even, _mm512_maskz_slli_epi64(all, odd, 32));
    hi = _mm512_mask_blend_epi32(0xAAAA, _mm512_maskz_srli_epi64(all, even, 32), odd);
  }
};

/// The same Philox4x32-10 rounds as r123::Philox4x32 on L::width counters at once. The last
/// group of a chunk that is not a multiple of the width repeats its last index in the spare
/// lanes: their words land in slots m ... k + width - 1 < kChunk, which nothing reads. Expanded
/// inside functions compiled for L's instruction set (a macro: the target attribute of a
/// function cannot come from a template parameter).
#define RPYFMM_PHILOX_CHUNK_BODY(L)                                                    \
  for (std::size_t k = 0; k < m; k += L::width) {                                      \
    alignas(64) std::uint32_t lo[L::width], hi[L::width];                              \
    for (std::size_t l = 0; l < L::width; ++l) {                                       \
      const std::uint64_t i = index[std::min(k + l, m - 1)];                           \
      lo[l] = static_cast<std::uint32_t>(i);                                           \
      hi[l] = static_cast<std::uint32_t>(i >> 32);                                     \
    }                                                                                  \
    const L::V index_lo = L::load(lo);                                                 \
    const L::V key0 = L::bxor(L::set1(static_cast<std::uint32_t>(seed)), L::load(hi)); \
    const L::V key1 = L::set1(static_cast<std::uint32_t>(seed >> 32));                 \
    for (std::uint32_t b = 0; b < blocks.count; ++b) {                                 \
      L::V c0 = index_lo;                                                              \
      L::V c1 = L::set1(blocks.c1[b]);                                                 \
      L::V c2 = L::set1(static_cast<std::uint32_t>(step));                             \
      L::V c3 = L::set1(static_cast<std::uint32_t>(step >> 32));                       \
      L::V k0 = key0;                                                                  \
      L::V k1 = key1;                                                                  \
      for (int round = 0; round < 10; ++round) {                                       \
        L::V hi0, lo0, hi1, lo1;                                                       \
        L::mulhilo(c0, kPhiloxM0, hi0, lo0);                                           \
        L::mulhilo(c2, kPhiloxM1, hi1, lo1);                                           \
        c0 = L::bxor(L::bxor(hi1, c1), k0);                                            \
        c2 = L::bxor(L::bxor(hi0, c3), k1);                                            \
        c1 = lo1;                                                                      \
        c3 = lo0;                                                                      \
        k0 = L::add(k0, L::set1(kPhiloxW0));                                           \
        k1 = L::add(k1, L::set1(kPhiloxW1));                                           \
      }                                                                                \
      std::uint32_t* w = &out.w[b * 4 * kChunk + k];                                   \
      L::store(w, c0);                                                                 \
      L::store(w + kChunk, c1);                                                        \
      L::store(w + 2 * kChunk, c2);                                                    \
      L::store(w + 3 * kChunk, c3);                                                    \
    }                                                                                  \
  }

RPYFMM_RANDOM_TARGET_AVX2 void philox_avx2(const std::uint64_t* index, std::size_t m, std::uint64_t seed,
                                           std::uint64_t step, const Blocks& blocks, ChunkWords& out) {
  RPYFMM_PHILOX_CHUNK_BODY(Avx2Lanes);
}

RPYFMM_RANDOM_TARGET_AVX512 void philox_avx512(const std::uint64_t* index, std::size_t m, std::uint64_t seed,
                                               std::uint64_t step, const Blocks& blocks, ChunkWords& out) {
  RPYFMM_PHILOX_CHUNK_BODY(Avx512Lanes);
}

#undef RPYFMM_PHILOX_CHUNK_BODY
#endif

/// The Box-Muller transforms: Mapping::bits (normal6: box_muller_bits for double values,
/// box_muller_bits_f for float ones) or Mapping::r123 (normal3: box_muller_r123).
enum class Mapping { bits, r123 };

/// Box-Muller over the chunk: g0/g1[b * kChunk + k] from block b's words of index k (a branch-free
/// loop the compiler vectorizes; inlined into the ISA-specific functions below).
template <Mapping M, class Real>
[[gnu::always_inline]] inline void box_muller_chunk(const ChunkWords& words, std::size_t m, std::uint32_t blocks,
                                                    Real* g0, Real* g1) {
  for (std::uint32_t b = 0; b < blocks; ++b) {
    const std::uint32_t* w0 = &words.w[(b * 4 + 0) * kChunk];
    const std::uint32_t* w1 = w0 + kChunk;
    const std::uint32_t* w2 = w1 + kChunk;
    const std::uint32_t* w3 = w2 + kChunk;
    Real* h0 = g0 + b * kChunk;
    Real* h1 = g1 + b * kChunk;
#pragma omp simd
    for (std::size_t k = 0; k < m; ++k) {
      if constexpr (M == Mapping::r123) {
        random_detail::box_muller_r123((static_cast<std::uint64_t>(w0[k]) << 32) | w1[k],
                                       (static_cast<std::uint64_t>(w2[k]) << 32) | w3[k], h0[k], h1[k]);
      } else {
        random_detail::box_muller_words(w0[k], w1[k], w2[k], w3[k], h0[k], h1[k]);
      }
    }
  }
}

template <Mapping M, class Real>
void box_muller_portable(const ChunkWords& words, std::size_t m, std::uint32_t blocks, Real* g0, Real* g1) {
  box_muller_chunk<M>(words, m, blocks, g0, g1);
}
#ifdef RPYFMM_RANDOM_X86
template <Mapping M, class Real>
RPYFMM_RANDOM_TARGET_AVX2 void box_muller_avx2(const ChunkWords& words, std::size_t m, std::uint32_t blocks, Real* g0,
                                               Real* g1) {
  box_muller_chunk<M>(words, m, blocks, g0, g1);
}
template <Mapping M, class Real>
__attribute__((target("avx512f,avx512dq,prefer-vector-width=512"))) void box_muller_avx512(const ChunkWords& words,
                                                                                           std::size_t m,
                                                                                           std::uint32_t blocks,
                                                                                           Real* g0, Real* g1) {
  box_muller_chunk<M>(words, m, blocks, g0, g1);
}
#endif

/// Philox and Box-Muller for the m <= kChunk indices of one chunk, on the widest instruction
/// set simd_level() names.
template <Mapping M, class Real>
void draw_chunk(const std::uint64_t* index, std::size_t m, std::uint64_t seed, std::uint64_t step, const Blocks& blocks,
                ChunkWords& words, Real* g0, Real* g1) {
#ifdef RPYFMM_RANDOM_X86
  if (simd_level() == SimdLevel::avx512) {
    philox_avx512(index, m, seed, step, blocks, words);
    box_muller_avx512<M>(words, m, blocks.count, g0, g1);
    return;
  }
  if (simd_level() == SimdLevel::avx2) {
    philox_avx2(index, m, seed, step, blocks, words);
    box_muller_avx2<M>(words, m, blocks.count, g0, g1);
    return;
  }
#endif
  philox_portable(index, m, seed, step, blocks, words);
  box_muller_portable<M>(words, m, blocks.count, g0, g1);
}

/// Checks shared by both precisions. The messages are built only on failure: this runs once per
/// line of modes (PSE wave noise).
void check_fill_normal6(std::size_t indices, std::size_t out_size, std::uint32_t stream) {
  if (out_size != 6 * indices) {
    fail(ErrorCode::invalid_input, "fill_normal6",
         "output length " + std::to_string(out_size) + " is not 6 x " + std::to_string(indices) + " indices");
  }
  if (stream >= (1u << 24)) {
    fail(ErrorCode::invalid_argument, "fill_normal6",
         "stream " + std::to_string(stream) + " must be below 2^24 (the top byte selects the Philox block)");
  }
}

/// fill_normal6 for double (box_muller_bits) or float (box_muller_bits_f) values.
/// Planar = true: value c of index k at out[c * n + k] instead of out[6 k + c].
template <class Real, bool Planar>
void fill_normal6_impl(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step,
                       std::uint32_t stream, std::span<Real> out) {
  check_fill_normal6(index.size(), out.size(), stream);
  const std::size_t n = index.size();
  const Blocks blocks{{stream, stream + (1u << 24), stream + (2u << 24)}, 3};
  ChunkWords words;
  alignas(64) Real g0[3 * kChunk];
  alignas(64) Real g1[3 * kChunk];
  for (std::size_t start = 0; start < index.size(); start += kChunk) {
    const std::size_t m = std::min(kChunk, index.size() - start);
    draw_chunk<Mapping::bits>(index.data() + start, m, seed, step, blocks, words, g0, g1);
    if constexpr (Planar) {
      for (std::uint32_t b = 0; b < 3; ++b) {
        std::copy_n(&g0[b * kChunk], m, out.data() + (2 * b) * n + start);
        std::copy_n(&g1[b * kChunk], m, out.data() + (2 * b + 1) * n + start);
      }
    } else {
      Real* o = out.data() + 6 * start;
      for (std::size_t k = 0; k < m; ++k)
        for (std::uint32_t b = 0; b < 3; ++b) {
          o[6 * k + 2 * b] = g0[b * kChunk + k];
          o[6 * k + 2 * b + 1] = g1[b * kChunk + k];
        }
    }
  }
}

}  // namespace

void fill_normal6(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                  std::span<double> out) {
  fill_normal6_impl<double, false>(index, seed, step, stream, out);
}

void fill_normal6(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                  std::span<float> out) {
  fill_normal6_impl<float, false>(index, seed, step, stream, out);
}

namespace {

/// z[3 k + c] = normal3(seed, step, stream, index_of(k))[c] for k < n, in chunks of kChunk indices
/// (in parallel from 16384 indices: each chunk's values depend on its indices only).
template <class IndexOf>
void fill_normal3(std::size_t n, IndexOf index_of, std::span<double> z, std::uint64_t seed, std::uint64_t step,
                  std::uint32_t stream) {
  require(stream < 0x80000000u, ErrorCode::invalid_argument, "fill_normal",
          "stream " + std::to_string(stream) + " must be below 2^31 (the top bit selects the third component)");
  const Blocks blocks{{stream, stream ^ 0x80000000u, 0}, 2};
  const auto chunks = static_cast<std::int64_t>((n + kChunk - 1) / kChunk);
#pragma omp parallel if (n >= 16384)
  {
    ChunkWords words;
    alignas(64) double g0[3 * kChunk];
    alignas(64) double g1[3 * kChunk];
    alignas(64) std::uint64_t index[kChunk];
#pragma omp for schedule(static)
    for (std::int64_t c = 0; c < chunks; ++c) {
      const std::size_t start = static_cast<std::size_t>(c) * kChunk;
      const std::size_t m = std::min(kChunk, n - start);
      for (std::size_t k = 0; k < m; ++k) index[k] = index_of(start + k);
      draw_chunk<Mapping::r123>(index, m, seed, step, blocks, words, g0, g1);
      double* o = z.data() + 3 * start;
      for (std::size_t k = 0; k < m; ++k) {
        o[3 * k] = g0[k];
        o[3 * k + 1] = g1[k];
        o[3 * k + 2] = g0[kChunk + k];
      }
    }
  }
}

}  // namespace

void fill_normal(std::span<double> z, std::uint64_t seed, std::uint64_t step, std::uint32_t stream) {
  require(z.size() % 3 == 0, ErrorCode::invalid_input, "fill_normal",
          "noise length " + std::to_string(z.size()) + " is not a multiple of 3");
  fill_normal3(
      z.size() / 3, [](std::size_t k) { return static_cast<std::uint64_t>(k); }, z, seed, step, stream);
}

void fill_normal(std::span<const std::uint64_t> index, std::span<double> z, std::uint64_t seed, std::uint64_t step,
                 std::uint32_t stream) {
  require(z.size() == 3 * index.size(), ErrorCode::invalid_input, "fill_normal",
          "noise length " + std::to_string(z.size()) + " is not 3 x " + std::to_string(index.size()) + " indices");
  fill_normal3(
      index.size(), [index](std::size_t k) { return index[k]; }, z, seed, step, stream);
}

namespace random_detail {

void fill_normal6_planar(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step,
                         std::uint32_t stream, std::span<double> out) {
  fill_normal6_impl<double, true>(index, seed, step, stream, out);
}

void fill_normal6_planar(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step,
                         std::uint32_t stream, std::span<float> out) {
  fill_normal6_impl<float, true>(index, seed, step, stream, out);
}

}  // namespace random_detail

}  // namespace rpyfmm::rpy
