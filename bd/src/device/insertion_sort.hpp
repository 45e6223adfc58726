// rpyfmm::bd::device — insertion sort of a short array of indices in place (a cell's slots, a
// Verlet row: tens of entries), one thread per array: no scratch, no recursion.
#pragma once

#include <cstdint>

#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::bd::device {

RPYFMM_HOST_DEVICE inline void insertion_sort(std::uint32_t* a, std::uint64_t n) {
  for (std::uint64_t k = 1; k < n; ++k) {
    const std::uint32_t v = a[k];
    std::uint64_t m = k;
    for (; m > 0 && a[m - 1] > v; --m) a[m] = a[m - 1];
    a[m] = v;
  }
}

}  // namespace rpyfmm::bd::device
