// rpyfmm — instruction-set dispatch for the direct (O(N^2)) hot loops.
//
// The default build is portable x86-64 (SSE2: two doubles per vector). The
// pairwise kernels are dominated by 1/sqrt, which runs several times faster
// per pair with AVX2/AVX-512, so on x86-64 GCC builds:
//  - RPYFMM_DIRECT_CLONES compiles a loop for x86-64-v4, x86-64-v3 and the
//    default target, and the loader picks the widest the CPU offers (ifunc);
//  - RPYFMM_DIRECT_AVX512 marks hand-vectorized AVX-512F kernels that compute
//    1/sqrt(r^2) as rsqrt14 + two Newton steps (14 -> 28 -> ~53 bits; within
//    a few ulp of 1/sqrt, versus sqrt + division at 8-16x the latency), used
//    when rpyfmm::fmm::detail::avx512_kernels_active() says so.
// With -DRPYFMM_NATIVE=ON the clones are unnecessary and disabled (the
// AVX-512 kernels stay: they are chosen at run time). Define
// RPYFMM_NO_TARGET_CLONES to turn both off. Results of different paths differ
// by rounding only.
#pragma once

#if !defined(RPYFMM_NO_TARGET_CLONES) && !defined(__CUDACC__) && defined(__x86_64__) && defined(__GNUC__) && \
    !defined(__clang__) && defined(__linux__)
#define RPYFMM_HAVE_DIRECT_AVX512 1
#define RPYFMM_DIRECT_AVX512 __attribute__((target("avx512f,fma")))
#if !defined(__AVX2__)
#define RPYFMM_DIRECT_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#endif
#endif

#ifndef RPYFMM_DIRECT_CLONES
#define RPYFMM_DIRECT_CLONES
#endif

namespace rpyfmm::fmm::detail {
/// True when the AVX-512 kernels are compiled in, the running CPU supports
/// AVX-512F, and they have not been disabled with use_avx512_kernels(false).
bool avx512_kernels_active() noexcept;
/// Enables (default) or disables the AVX-512 kernels, e.g. so that tests can
/// check the portable kernels on an AVX-512 machine. Do not call while a
/// direct sum runs on another thread.
void use_avx512_kernels(bool enabled) noexcept;
}  // namespace rpyfmm::fmm::detail
