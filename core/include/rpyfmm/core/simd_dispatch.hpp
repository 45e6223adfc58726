// rpyfmm — one loop body compiled for each instruction-set level and run at the level that
// simd_level() names (cpu_features.hpp).
//
// Usage: write the body as a lambda marked RPYFMM_SIMD_BODY and hand it to simd_dispatch:
//
//     simd_dispatch([=]() RPYFMM_SIMD_BODY { for (...) ... });
//
// Capture by value where the body is a whole function's: the closure is then passed by value,
// and after inlining its fields are plain scalars in registers, as the function's parameters
// were (captured references would be reloaded around stores that might alias them, which can
// keep a loop from vectorizing).
//
// The lambda is always inlined into three wrappers compiled with target("arch=x86-64-v4"),
// target("arch=x86-64-v3") and the build's baseline, so GCC vectorizes it for each; which one
// runs is decided at every call by simd_level(), i.e. the RPYFMM_SIMD override and
// set_simd_level() are obeyed (unlike GCC's target_clones, which choose by the CPU alone, once,
// at load time). Hand-written intrinsics kernels are marked RPYFMM_TARGET_AVX512 /
// RPYFMM_TARGET_AVX2 and chosen by comparing simd_level() with the level they need.
#pragma once

#include "rpyfmm/core/cpu_features.hpp"

#if defined(RPYFMM_HAVE_X86_KERNELS)
#define RPYFMM_TARGET_AVX512 __attribute__((target("arch=x86-64-v4")))
#define RPYFMM_TARGET_AVX2 __attribute__((target("arch=x86-64-v3")))
#endif
#define RPYFMM_SIMD_BODY __attribute__((always_inline))

namespace rpyfmm {

namespace simd_detail {
#if defined(RPYFMM_HAVE_X86_KERNELS)
template <class Body>
RPYFMM_TARGET_AVX512 __attribute__((noinline)) decltype(auto) run_avx512(Body body) {
  return body();
}
template <class Body>
RPYFMM_TARGET_AVX2 __attribute__((noinline)) decltype(auto) run_avx2(Body body) {
  return body();
}
#endif
template <class Body>
__attribute__((noinline)) decltype(auto) run_scalar(Body body) {
  return body();
}
}  // namespace simd_detail

/// body() compiled for the level in use (see the file comment).
template <class Body>
inline decltype(auto) simd_dispatch(Body body) {
#if defined(RPYFMM_HAVE_X86_KERNELS)
  switch (simd_level()) {
    case SimdLevel::avx512:
      return simd_detail::run_avx512(body);
    case SimdLevel::avx2:
      return simd_detail::run_avx2(body);
    case SimdLevel::scalar:
      break;
  }
#endif
  return simd_detail::run_scalar(body);
}

}  // namespace rpyfmm
