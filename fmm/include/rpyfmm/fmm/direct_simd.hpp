// rpyfmm — function multiversioning for the direct (O(N^2)) hot loops.
//
// The default build is portable x86-64 (SSE2: two doubles per vector). The
// pairwise kernels are dominated by sqrt and division, which run 2-4x faster
// per pair with AVX2/AVX-512, so on x86-64 GCC/Clang builds each hot loop is
// compiled several times and the loader picks the widest one the CPU offers
// (ifunc). With -DRPYFMM_NATIVE=ON the whole build already targets the build
// machine and the clones are disabled. Define RPYFMM_NO_TARGET_CLONES to turn
// them off by hand. Results differ between clones only by rounding (FMA).
#pragma once

#if !defined(RPYFMM_NO_TARGET_CLONES) && !defined(__CUDACC__) && defined(__x86_64__) && defined(__GNUC__) && \
    !defined(__clang__) && !defined(__AVX2__) && defined(__linux__)
#define RPYFMM_DIRECT_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define RPYFMM_DIRECT_CLONES
#endif
