// rpyfmm::bd::device — the Brownian noise of one particle: three N(0, 1) values from the
// counter-based Philox4x32-10 stream keyed by (seed, step, particle) (Salmon, Moraes, Dror &
// Shaw, SC'11), the values rpy::fill_normal gives the CPU engine for z (stream 0). No state:
// a thread draws its particle's values from the counter alone, and host and device evaluate
// the same operations (rpyfmm/rpy/random.hpp), so the draws agree bit for bit where neither side
// contracts multiply-adds.
#pragma once

#include <cstdint>

#include "rpyfmm/core/host_device.hpp"
#include "rpyfmm/rpy/random.hpp"

namespace rpyfmm::bd::device {

/// The stream of the translational noise z of a BD step (Integrator: fill_normal's default).
inline constexpr std::uint32_t kTranslationNoiseStream = 0;

RPYFMM_HOST_DEVICE inline void brownian_normals(std::uint64_t seed, std::uint64_t step, std::uint64_t particle,
                                                double z[3]) {
  rpy::normal3(seed, step, kTranslationNoiseStream, particle, z);
}

}  // namespace rpyfmm::bd::device
