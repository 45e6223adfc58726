// rpyfmm — the one place that decides which instruction-set level the kernels use.
//
// Three levels: `scalar` (portable C++ compiled for the baseline target, x86-64 SSE2 or the
// architecture's own), `avx2` (x86-64-v3: AVX2 + FMA) and `avx512` (x86-64-v4: AVX-512F/BW/CD/
// DQ/VL). The level in use is the widest that both the build and the CPU support, lowered by
// the environment variable RPYFMM_SIMD=scalar|avx2|avx512 (read once, at the first query) or by
// set_simd_level(). A level above the detected one is capped at the detected one.
//
// Every kernel choice and every algorithmic parameter chosen per level (FMM leaf capacity,
// direct limits, PSE pair caches and list layouts, batch sizes, crossovers) asks simd_level(),
// so forcing a level reproduces on any machine what a CPU of that level computes. Results of
// different levels differ by rounding only; every level meets the same accuracy contracts
// (docs/reproducibility.md).
#pragma once

#include <optional>
#include <string_view>

// The x86 SIMD kernels are compiled with GCC on x86-64 Linux (target attributes, <immintrin.h>),
// unless the build defines RPYFMM_NO_X86_KERNELS (CMake -DRPYFMM_X86_KERNELS=OFF: the portable
// code alone, as on a machine without x86 intrinsics). Never in CUDA translation units.
#if !defined(RPYFMM_NO_X86_KERNELS) && !defined(__CUDACC__) && defined(__x86_64__) && defined(__GNUC__) && \
    !defined(__clang__) && defined(__linux__)
#define RPYFMM_HAVE_X86_KERNELS 1
#endif

namespace rpyfmm {

enum class SimdLevel : int { scalar = 0, avx2 = 1, avx512 = 2 };

/// The level the kernels run at now.
[[nodiscard]] SimdLevel simd_level() noexcept;
/// The widest level this build and this CPU support, ignoring RPYFMM_SIMD and set_simd_level.
[[nodiscard]] SimdLevel detected_simd_level() noexcept;
/// True when the x86 SIMD kernels are compiled in (GCC on x86-64 Linux, unless the build was
/// configured with -DRPYFMM_X86_KERNELS=OFF). Without them the only level is `scalar`.
[[nodiscard]] bool x86_kernels_compiled() noexcept;
/// "scalar", "avx2" or "avx512".
[[nodiscard]] const char* simd_level_name(SimdLevel level) noexcept;
/// The level named by `name` (as simd_level_name writes it), or nothing.
[[nodiscard]] std::optional<SimdLevel> parse_simd_level(std::string_view name) noexcept;
/// Runs the kernels at min(level, detected_simd_level()) from now on and returns the level in
/// use before. For tests and benchmarks; do not call while a kernel runs on another thread.
SimdLevel set_simd_level(SimdLevel level) noexcept;
/// Throws rpyfmm::Error (invalid_argument) when RPYFMM_SIMD is set to something other than a
/// level name. The library itself only warns once on stderr and ignores such a value; the CLI
/// calls this at start-up so that a typo is one clear error.
void require_valid_simd_environment();

/// Sets a level for the lifetime of the object and restores the previous one (tests).
class ScopedSimdLevel {
 public:
  explicit ScopedSimdLevel(SimdLevel level) noexcept : previous_(set_simd_level(level)) {}
  ~ScopedSimdLevel() { set_simd_level(previous_); }
  ScopedSimdLevel(const ScopedSimdLevel&) = delete;
  ScopedSimdLevel& operator=(const ScopedSimdLevel&) = delete;

 private:
  SimdLevel previous_;
};

}  // namespace rpyfmm
