#include "host_copy.hpp"

#include <algorithm>
#include <cstring>

namespace rpyfmm::rpy::pse::detail {

void parallel_copy(double* dst, const double* src, std::size_t n) {
  constexpr std::size_t kChunk = std::size_t{1} << 17;  // 1 MiB of doubles per task
  const auto chunks = static_cast<long long>((n + kChunk - 1) / kChunk);
  if (chunks <= 1) {
    if (n > 0) std::memcpy(dst, src, n * sizeof(double));
    return;
  }
#pragma omp parallel for schedule(static)
  for (long long c = 0; c < chunks; ++c) {
    const std::size_t begin = static_cast<std::size_t>(c) * kChunk;
    const std::size_t count = std::min(kChunk, n - begin);
    std::memcpy(dst + begin, src + begin, count * sizeof(double));
  }
}

}  // namespace rpyfmm::rpy::pse::detail
