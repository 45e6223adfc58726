// rpyfmm — the one rule for user-requested thread counts (CLI --threads, Python
// set_num_threads, PSE fft_threads): at least 1 (0 where "default" is meant), at most
// max_threads(). More threads than that only oversubscribe the cores, and counts in the tens of
// thousands exhaust the OS and crash inside the OpenMP runtime.
#pragma once

#include <algorithm>
#include <string>
#include <string_view>
#include <thread>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm {

/// The hard ceiling on any thread count, whatever the machine.
inline constexpr int kThreadCeiling = 1024;

/// The largest thread count accepted: 4 x the hardware threads, at most kThreadCeiling (and at
/// least 4 where the hardware count is unknown).
[[nodiscard]] inline int max_threads() noexcept {
  const unsigned hw = std::thread::hardware_concurrency();
  const long long four = 4LL * static_cast<long long>(hw == 0 ? 1 : hw);
  return static_cast<int>(std::min<long long>(four, kThreadCeiling));
}

/// Throws rpyfmm::Error (invalid_argument) unless `count` is in [allow_zero ? 0 : 1, max_threads()];
/// the message names `where` and the valid range.
inline void require_thread_count(long long count, std::string_view where, bool allow_zero) {
  const long long lo = allow_zero ? 0 : 1;
  if (count < lo || count > max_threads()) {
    fail(ErrorCode::invalid_argument, where,
         "thread count must lie in [" + std::to_string(lo) + ", " + std::to_string(max_threads()) +
             "] (at most 4 x the " + std::to_string(std::thread::hardware_concurrency()) +
             " hardware threads, and at most " + std::to_string(kThreadCeiling) + "), got " + std::to_string(count));
  }
}

}  // namespace rpyfmm
