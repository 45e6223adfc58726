// rpyfmm — counter-based normal random numbers.
//
// A draw is a pure function of (seed, step, stream, particle): results do not
// depend on thread count or on the order of work, and normal3() compiles for
// CUDA (host and device) so that CPU and GPU noise agree bit for bit.
// Philox4x32-10 (Salmon, Moraes, Dror & Shaw, SC'11; Random123) and the
// Box-Muller transform of Random123's boxmuller.hpp.
#pragma once

#include <Random123/boxmuller.hpp>
#include <Random123/philox.h>

#include <cstddef>
#include <cstdint>
#include <span>

#ifdef __CUDACC__
#define RPYFMM_HOST_DEVICE __host__ __device__
#else
#define RPYFMM_HOST_DEVICE
#endif

namespace rpyfmm::rpy {

/// Three independent N(0,1) values for (seed, step, stream, particle).
/// Counter = (particle, stream, step_lo, step_hi), key = seed; the third value uses
/// the counter with stream | 2^31, so `stream` must be below 2^31.
RPYFMM_HOST_DEVICE inline void normal3(std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                                       std::uint64_t particle, double out[3]) {
  using Philox = r123::Philox4x32;
  Philox rng;
  Philox::ctr_type ctr = {{static_cast<std::uint32_t>(particle), stream, static_cast<std::uint32_t>(step),
                           static_cast<std::uint32_t>(step >> 32)}};
  // The particle's high word goes into the key so that > 2^32 particles stay distinct.
  Philox::key_type key = {{static_cast<std::uint32_t>(seed) ^ static_cast<std::uint32_t>(particle >> 32),
                           static_cast<std::uint32_t>(seed >> 32)}};
  const Philox::ctr_type r = rng(ctr, key);
  const auto u0 = (static_cast<std::uint64_t>(r.v[0]) << 32) | r.v[1];
  const auto u1 = (static_cast<std::uint64_t>(r.v[2]) << 32) | r.v[3];
  const r123::double2 g01 = r123::boxmuller(u0, u1);
  ctr.v[1] = stream ^ 0x80000000u;  // second block for the third component
  const Philox::ctr_type s = rng(ctr, key);
  const auto u2 = (static_cast<std::uint64_t>(s.v[0]) << 32) | s.v[1];
  const auto u3 = (static_cast<std::uint64_t>(s.v[2]) << 32) | s.v[3];
  const r123::double2 g23 = r123::boxmuller(u2, u3);
  out[0] = g01.x;
  out[1] = g01.y;
  out[2] = g23.x;
}

/// Fills z[3*i + c] (i = 0..N-1, c = 0..2) with normal3(seed, step, stream, i).
/// z.size() must be a multiple of 3 and stream < 2^31 (throws rpyfmm::Error otherwise).
void fill_normal(std::span<double> z, std::uint64_t seed, std::uint64_t step, std::uint32_t stream = 0);

}  // namespace rpyfmm::rpy
