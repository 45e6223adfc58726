// rpyfmm::bd::device — pair separations with the minimum image in a periodic box: the arithmetic
// of NeighbourList::separation (bd/include/rpyfmm/bd/neighbour_list.hpp), operation for
// operation, so that forces summed from it agree with the CPU engine's bit for bit where neither
// side contracts multiply-adds (docs/gpu-bd.md, bounds).
#pragma once

#include <math.h>  // ::nearbyint, a CUDA builtin in device code too

#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::bd::device {

struct MinimumImage {
  bool periodic = false;
  double box[3] = {0.0, 0.0, 0.0};
  double inv_box[3] = {0.0, 0.0, 0.0};

  /// d = x_i - x_j, shifted by the nearest box vector in a periodic box (positions unwrapped).
  RPYFMM_HOST_DEVICE void separation(const double* xi, const double* xj, double d[3]) const {
    for (int c = 0; c < 3; ++c) {
      d[c] = xi[c] - xj[c];
      if (periodic) d[c] -= box[c] * ::nearbyint(d[c] * inv_box[c]);
    }
  }
};

RPYFMM_HOST_DEVICE inline double squared_norm(const double d[3]) {
  return d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
}

}  // namespace rpyfmm::bd::device
