// rpyfmm::bd::device — the two atomic updates the BD stages need, one spelling for both sides:
// CUDA's atomicAdd / atomicMin in device code, std::atomic_ref on the host (the host launcher
// may run a stage's particles on several threads).
#pragma once

#include <atomic>
#include <cstdint>

#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::bd::device {

/// *counter += 1; returns the value before (the particle's rank within its cell when binning).
RPYFMM_HOST_DEVICE inline std::uint32_t fetch_increment(std::uint32_t* counter) {
#ifdef __CUDA_ARCH__
  return atomicAdd(counter, 1u);
#else
  return std::atomic_ref<std::uint32_t>(*counter).fetch_add(1u, std::memory_order_relaxed);
#endif
}

/// *slot = min(*slot, value): the lowest particle (or bond) index that failed a check, so that
/// the error names the same one whatever the order of the threads (as ForceField::compute does).
RPYFMM_HOST_DEVICE inline void store_min(std::uint64_t* slot, std::uint64_t value) {
#ifdef __CUDA_ARCH__
  atomicMin(reinterpret_cast<unsigned long long*>(slot), static_cast<unsigned long long>(value));
#else
  std::atomic_ref<std::uint64_t> ref(*slot);
  std::uint64_t current = ref.load(std::memory_order_relaxed);
  while (value < current && !ref.compare_exchange_weak(current, value, std::memory_order_relaxed)) {
  }
#endif
}

/// The "nothing failed" value of a store_min slot.
inline constexpr std::uint64_t kNone = ~std::uint64_t{0};

}  // namespace rpyfmm::bd::device
