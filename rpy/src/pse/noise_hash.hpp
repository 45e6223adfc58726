// rpyfmm — the pieces of pse::noise_hash (pse_rpy.hpp): a splitmix64 chain over the bit patterns of
// z, started from its length, so that the MPI layer's distributed split sampler continues the chain
// over the ranks' shares in rank order and keys the wave-space noise as the serial one. Private.
#pragma once

#include <cstdint>
#include <cstring>
#include <span>

namespace rpyfmm::rpy::pse::detail {

/// The splitmix64 finaliser.
inline std::uint64_t noise_hash_mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

/// The chain's start for a vector of `size` entries.
inline std::uint64_t noise_hash_start(std::size_t size) {
  return noise_hash_mix(size);
}

/// The chain continued over the entries of z.
inline std::uint64_t noise_hash_extend(std::uint64_t h, std::span<const double> z) {
  for (const double v : z) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, sizeof bits);
    h = noise_hash_mix(h ^ bits);
  }
  return h;
}

}  // namespace rpyfmm::rpy::pse::detail
