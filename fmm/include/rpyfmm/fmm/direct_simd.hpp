// rpyfmm — the hand-written AVX-512 pieces shared by the direct (O(N^2)) hot loops.
//
// The pairwise kernels are dominated by 1/sqrt, which runs several times faster per pair with
// AVX2/AVX-512. Two kinds of code serve them (core/include/rpyfmm/core/simd_dispatch.hpp):
//  - portable loops run through simd_dispatch, which compiles them for x86-64-v4, x86-64-v3 and
//    the baseline and runs the one simd_level() names;
//  - RPYFMM_DIRECT_AVX512 marks hand-vectorized AVX-512F kernels that compute 1/sqrt(r^2) as
//    rsqrt14 + two Newton steps (14 -> 28 -> ~53 bits; within a few ulp of 1/sqrt, versus sqrt
//    + division at 8-16x the latency), used where simd_level() is SimdLevel::avx512.
// Results of different levels differ by rounding only.
#pragma once

#include "rpyfmm/core/simd_dispatch.hpp"

#if defined(RPYFMM_HAVE_X86_KERNELS)
#define RPYFMM_HAVE_DIRECT_AVX512 1
#define RPYFMM_DIRECT_AVX512 __attribute__((target("avx512f,fma")))
#include <immintrin.h>
#endif

namespace rpyfmm::fmm::detail {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
/// 1/sqrt(r2) lane by lane where 0 < r2 < inf, else 0 (the r = 0 skip; the
/// r2 = inf limit is 0): rsqrt14 (relative error < 2^-14) and two Newton steps
/// y <- y + (y/2)(1 - r2 y^2), each squaring the error (14 -> 28 -> ~53 bits).
RPYFMM_DIRECT_AVX512 inline __m512d rsqrt_or_zero(__m512d r2) {
  const __mmask8 ok = _mm512_cmp_pd_mask(r2, _mm512_setzero_pd(), _CMP_GT_OQ) &
                      _mm512_cmp_pd_mask(r2, _mm512_set1_pd(__builtin_inf()), _CMP_LT_OQ);
  __m512d y = _mm512_maskz_rsqrt14_pd(ok, r2);
  const __m512d one = _mm512_set1_pd(1.0), half = _mm512_set1_pd(0.5);
  for (int it = 0; it < 2; ++it) {
    const __m512d h = _mm512_fnmadd_pd(_mm512_mul_pd(r2, y), y, one);
    y = _mm512_fmadd_pd(_mm512_mul_pd(half, y), h, y);
  }
  return _mm512_maskz_mov_pd(ok, y);  // re-mask: r2 = inf gives inf * 0 = NaN in the Newton step
}

/// The sum of the eight lanes as ((t0 + t1) + (t2 + t3)) + ((t4 + t5) + (t6 + t7)), in registers:
/// neighbouring lanes, then pairs, then halves (no store and scalar reloads). The maskz forms:
/// GCC 12's plain permutes start from an undefined register and trip -Wuninitialized.
RPYFMM_DIRECT_AVX512 inline double sum_lanes_pairwise(__m512d v) {
  const __m512d a = _mm512_add_pd(v, _mm512_maskz_permute_pd(0xFF, v, 0x55));  // t0 + t1 in lane 0
  const __m512d b = _mm512_add_pd(a, _mm512_maskz_shuffle_f64x2(0xFF, a, a, _MM_SHUFFLE(2, 3, 0, 1)));  // + t2 + t3
  const __m512d h = _mm512_add_pd(b, _mm512_maskz_shuffle_f64x2(0xFF, b, b, _MM_SHUFFLE(1, 0, 3, 2)));  // + upper half
  return _mm512_cvtsd_f64(h);
}
#endif
}  // namespace rpyfmm::fmm::detail
