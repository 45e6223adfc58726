// rpyfmm::bd::device — the dynamic rebuild test of Tran et al. (2015)
// (Algorithm 1, lines 15-16): the Verlet lists must be rebuilt once some particle has moved
// more than skin/2 since the last build, for only then can a pair have come from beyond the list
// radius r_c + skin to within r_c unseen. The arithmetic of NeighbourList::update (unwrapped
// positions, no minimum image), so both engines rebuild at the same steps.
#pragma once

#include <cstdint>

#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::bd::device {

/// True when particle i at x has moved more than sqrt(limit2) = skin/2 from `reference`
/// (positions at the last build, 3 per particle).
RPYFMM_HOST_DEVICE inline bool moved_beyond_half_skin(std::uint64_t i, const double* x, const double* reference,
                                                      double limit2) {
  double d2 = 0.0;
  for (int c = 0; c < 3; ++c) {
    const double d = x[3 * i + c] - reference[3 * i + c];
    d2 += d * d;
  }
  return d2 > limit2;
}

}  // namespace rpyfmm::bd::device
