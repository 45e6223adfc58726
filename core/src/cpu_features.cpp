// rpyfmm — instruction-set level: detection, the RPYFMM_SIMD override, names (cpu_features.hpp).
#include "rpyfmm/core/cpu_features.hpp"

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "rpyfmm/core/error.hpp"

namespace rpyfmm {

namespace {

SimdLevel detect() noexcept {
#if defined(RPYFMM_HAVE_X86_KERNELS)
  __builtin_cpu_init();
  // The same feature sets as the targets the kernels are compiled for (simd_dispatch.hpp);
  // libgcc also checks that the OS saves the wide registers.
  if (__builtin_cpu_supports("x86-64-v4")) return SimdLevel::avx512;
  if (__builtin_cpu_supports("x86-64-v3")) return SimdLevel::avx2;
#endif
  return SimdLevel::scalar;
}

/// The level requested by RPYFMM_SIMD, the detected one where it is unset or invalid (warned
/// about once on stderr).
SimdLevel from_environment(SimdLevel detected) noexcept {
  const char* value = std::getenv("RPYFMM_SIMD");
  if (value == nullptr || *value == '\0') return detected;
  const auto level = parse_simd_level(value);
  if (!level) {
    std::fprintf(stderr, "rpyfmm: ignoring RPYFMM_SIMD=%s (expected scalar, avx2 or avx512)\n", value);
    return detected;
  }
  return std::min(*level, detected);
}

std::atomic<int>& level_in_use() noexcept {
  static std::atomic<int> level{static_cast<int>(from_environment(detected_simd_level()))};
  return level;
}

}  // namespace

SimdLevel detected_simd_level() noexcept {
  static const SimdLevel level = detect();
  return level;
}

SimdLevel simd_level() noexcept {
  return static_cast<SimdLevel>(level_in_use().load(std::memory_order_relaxed));
}

bool x86_kernels_compiled() noexcept {
#if defined(RPYFMM_HAVE_X86_KERNELS)
  return true;
#else
  return false;
#endif
}

const char* simd_level_name(SimdLevel level) noexcept {
  switch (level) {
    case SimdLevel::avx512:
      return "avx512";
    case SimdLevel::avx2:
      return "avx2";
    case SimdLevel::scalar:
      break;
  }
  return "scalar";
}

std::optional<SimdLevel> parse_simd_level(std::string_view name) noexcept {
  for (const SimdLevel level : {SimdLevel::scalar, SimdLevel::avx2, SimdLevel::avx512})
    if (name == simd_level_name(level)) return level;
  return std::nullopt;
}

SimdLevel set_simd_level(SimdLevel level) noexcept {
  const SimdLevel capped = std::min(level, detected_simd_level());
  return static_cast<SimdLevel>(level_in_use().exchange(static_cast<int>(capped), std::memory_order_relaxed));
}

void require_valid_simd_environment() {
  const char* value = std::getenv("RPYFMM_SIMD");
  if (value == nullptr || *value == '\0' || parse_simd_level(value)) return;
  throw Error(ErrorCode::invalid_argument,
              "RPYFMM_SIMD: must be scalar, avx2 or avx512, got '" + std::string(value) + "'");
}

}  // namespace rpyfmm
