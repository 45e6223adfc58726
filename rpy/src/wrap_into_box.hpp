// rpyfmm — a coordinate wrapped into [0, L), as MobilityOperator::set_positions stores positions of
// a periodic geometry. Private; shared with the MPI layer, whose distributed PSE must place every
// particle on the serial operator's grid points bit for bit, and with PseRpyCuda, whose device
// positions (set_positions_device) wrap as the host's do.
#pragma once

#include <cmath>

#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::rpy::detail {

/// v wrapped into [0, L): v itself where it lies there already (bitwise), else fmod, which is exact
/// (the remainder of two doubles is a double), so a position any number of box lengths away wraps
/// to the same point; v - L floor(v / L) lost all bits of v past ~1e16 box lengths (floor of a
/// rounded quotient, then a cancelling difference).
RPYFMM_HOST_DEVICE inline double wrap_into_box(double v, double L) {
  if (v >= 0.0 && v < L) return v;
  v = std::fmod(v, L);              // in (-L, L), sign of v, exact
  if (v < 0.0) v += L;              // -tiny wraps to L - tiny (or to L: then below)
  if (v >= L || v == 0.0) v = 0.0;  // guards results that round to L exactly; -0 to +0
  return v;
}

}  // namespace rpyfmm::rpy::detail
