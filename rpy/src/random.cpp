#include "rpyfmm/rpy/random.hpp"

#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy {

void fill_normal(std::span<double> z, std::uint64_t seed, std::uint64_t step, std::uint32_t stream) {
  require(z.size() % 3 == 0, ErrorCode::invalid_input, "fill_normal",
          "noise length " + std::to_string(z.size()) + " is not a multiple of 3");
  require(stream < 0x80000000u, ErrorCode::invalid_argument, "fill_normal",
          "stream " + std::to_string(stream) + " must be below 2^31 (the top bit selects the third component)");
  const auto n = static_cast<std::int64_t>(z.size() / 3);
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (std::int64_t i = 0; i < n; ++i) normal3(seed, step, stream, static_cast<std::uint64_t>(i), &z[3 * i]);
}

}  // namespace rpyfmm::rpy
