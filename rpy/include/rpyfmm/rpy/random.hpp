// rpyfmm — counter-based normal random numbers.
//
// A draw is a pure function of (seed, step, stream, particle): results do not
// depend on thread count or on the order of work, and normal3() compiles for
// CUDA (host and device) so that CPU and GPU noise agree bit for bit.
// Philox4x32-10 (Salmon, Moraes, Dror & Shaw, SC'11; Random123) and the
// Box-Muller transform of Random123's boxmuller.hpp.
#pragma once

#include <Random123/philox.h>

#include <Random123/boxmuller.hpp>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
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

namespace random_detail {

/// The double with bit pattern b and back (std::bit_cast is not yet usable in device code).
RPYFMM_HOST_DEVICE inline double from_bits(std::uint64_t b) {
#ifdef __CUDA_ARCH__
  return __longlong_as_double(static_cast<long long>(b));
#else
  double d;
  std::memcpy(&d, &b, sizeof d);
  return d;
#endif
}
RPYFMM_HOST_DEVICE inline std::uint64_t to_bits(double d) {
#ifdef __CUDA_ARCH__
  return static_cast<std::uint64_t>(__double_as_longlong(d));
#else
  std::uint64_t b;
  std::memcpy(&b, &d, sizeof b);
  return b;
#endif
}

// The functions below are branch-free, call no libm function but sqrt, and speculate no
// operation that can trap, so that a loop over them vectorizes (rpy/src/random_batch.cpp)
// and host and device evaluate the same operations.

/// sin(pi v) and cos(pi v) for |v| <= 1: v = q/2 + r with q = round(2v) (exact, |r| <= 1/4),
/// Taylor polynomials on |pi r| <= pi/4 (truncation below 1e-16 relative), then the quadrant.
RPYFMM_HOST_DEVICE inline void sincospi_poly(double v, double& s, double& c) {
  const double round_magic = 6755399441055744.0;  // 1.5 * 2^52: (y + M) - M rounds y to an integer
  const double q = (2.0 * v + round_magic) - round_magic;
  const double r = v - 0.5 * q;
  const double x = 3.14159265358979323846 * r;
  const double x2 = x * x;
  // sin x = x (1 - x^2/3! + ... - x^14/15!), cos x = 1 - x^2/2! + ... + x^16/16!
  const double sp =
      1.0 +
      x2 * (-1.0 / 6.0 +
            x2 * (1.0 / 120.0 +
                  x2 * (-1.0 / 5040.0 +
                        x2 * (1.0 / 362880.0 +
                              x2 * (-1.0 / 39916800.0 + x2 * (1.0 / 6227020800.0 + x2 * (-1.0 / 1307674368000.0)))))));
  const double cp =
      1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 +
                               x2 * (-1.0 / 720.0 +
                                     x2 * (1.0 / 40320.0 +
                                           x2 * (-1.0 / 3628800.0 +
                                                 x2 * (1.0 / 479001600.0 + x2 * (-1.0 / 87178291200.0 +
                                                                                 x2 * (1.0 / 20922789888000.0))))))));
  const double sr = x * sp;
  // q = 0: (sin, cos) = (sr, cp); q = +-1 swaps to (cp, -sr); q = -1, +-2 negate both.
  const double aq = q < 0.0 ? -q : q;
  const bool odd = aq == 1.0;
  const bool negate = (q == -1.0) | (aq == 2.0);
  const double s0 = odd ? cp : sr;
  const double c0 = odd ? -sr : cp;
  s = negate ? -s0 : s0;
  c = negate ? -c0 : c0;
}

/// Natural logarithm of a positive normal double: x = 2^e m with m in [sqrt(1/2), sqrt(2)),
/// log x = e ln 2 + 2 atanh(s), s = (m - 1)/(m + 1), |s| <= 0.1716, by its series to s^25
/// (truncation below 1e-17). Relative error a few ulps (tests/sqrt/test_random.cpp).
RPYFMM_HOST_DEVICE inline double log_poly(double x) {
  const std::uint64_t b = to_bits(x);
  // Exponent as a double without an int64 conversion: 2^52 + biased exponent, minus 2^52 + 1023.
  double e = from_bits((b >> 52) | 0x4330000000000000ull) - 4503599627371519.0;
  double m = from_bits((b & 0x000FFFFFFFFFFFFFull) | 0x3FF0000000000000ull);  // [1, 2)
  const bool big = m > 1.41421356237309504880;
  m *= big ? 0.5 : 1.0;
  e += big ? 1.0 : 0.0;
  const double s = (m - 1.0) / (m + 1.0);
  const double s2 = s * s;
  double p = 1.0 / 25.0;
  p = 1.0 / 23.0 + s2 * p;
  p = 1.0 / 21.0 + s2 * p;
  p = 1.0 / 19.0 + s2 * p;
  p = 1.0 / 17.0 + s2 * p;
  p = 1.0 / 15.0 + s2 * p;
  p = 1.0 / 13.0 + s2 * p;
  p = 1.0 / 11.0 + s2 * p;
  p = 1.0 / 9.0 + s2 * p;
  p = 1.0 / 7.0 + s2 * p;
  p = 1.0 / 5.0 + s2 * p;
  p = 1.0 / 3.0 + s2 * p;
  p = 1.0 + s2 * p;
  return e * 0.69314718055994530942 + 2.0 * s * p;
}

/// Box-Muller on two 64-bit uniforms: the angle from v = uneg11(u0) in [-1, 1), the radius
/// from u = u01(u1) in (0, 1] (52 bits each, by bit patterns; u > 0, so |g| <= 8.6).
RPYFMM_HOST_DEVICE inline void box_muller_bits(std::uint64_t u0, std::uint64_t u1, double& g0, double& g1) {
  const double v = from_bits((u0 >> 12) | 0x4000000000000000ull) - 3.0;  // [2, 4) - 3
  const double u = 2.0 - from_bits((u1 >> 12) | 0x3FF0000000000000ull);  // 2 - [1, 2)
  double s, c;
  sincospi_poly(v, s, c);
  const double rad = std::sqrt(-2.0 * log_poly(u));
  g0 = rad * s;
  g1 = rad * c;
}

/// Philox4x32-10 counter for block b of normal6.
RPYFMM_HOST_DEVICE inline r123::Philox4x32::ctr_type normal6_counter(std::uint64_t step, std::uint32_t stream,
                                                                     std::uint64_t index, std::uint32_t b) {
  return {{static_cast<std::uint32_t>(index), stream + (b << 24), static_cast<std::uint32_t>(step),
           static_cast<std::uint32_t>(step >> 32)}};
}
RPYFMM_HOST_DEVICE inline r123::Philox4x32::key_type normal6_key(std::uint64_t seed, std::uint64_t index) {
  return {{static_cast<std::uint32_t>(seed) ^ static_cast<std::uint32_t>(index >> 32),
           static_cast<std::uint32_t>(seed >> 32)}};
}

}  // namespace random_detail

/// Six independent N(0,1) values for (seed, step, stream, index): three Philox4x32-10 blocks
/// (counter (index_lo, stream + 2^24 b, step_lo, step_hi), b = 0, 1, 2; key (seed_lo ^ index_hi,
/// seed_hi)), each giving two normals by Box-Muller (random_detail::box_muller_bits).
/// `stream` must be below 2^24. One call per PSE Fourier mode (the wave-space noise);
/// fill_normal6 computes the same values for many indices at once, vectorized.
RPYFMM_HOST_DEVICE inline void normal6(std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                                       std::uint64_t index, double out[6]) {
  const r123::Philox4x32 rng;
  const auto key = random_detail::normal6_key(seed, index);
  for (std::uint32_t b = 0; b < 3; ++b) {
    const auto r = rng(random_detail::normal6_counter(step, stream, index, b), key);
    const auto u0 = (static_cast<std::uint64_t>(r.v[0]) << 32) | r.v[1];
    const auto u1 = (static_cast<std::uint64_t>(r.v[2]) << 32) | r.v[3];
    random_detail::box_muller_bits(u0, u1, out[2 * b], out[2 * b + 1]);
  }
}

/// out[6 k + c] = normal6(seed, step, stream, index[k])[c] for every k (vectorized with AVX2 /
/// AVX-512 where the CPU has them; the values equal normal6's to a few ulps, contraction of
/// a * b + c into fused multiply-adds aside). out.size() must be 6 index.size(), stream < 2^24.
void fill_normal6(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                  std::span<double> out);

/// Fills z[3*i + c] (i = 0..N-1, c = 0..2) with normal3(seed, step, stream, i).
/// z.size() must be a multiple of 3 and stream < 2^31 (throws rpyfmm::Error otherwise).
void fill_normal(std::span<double> z, std::uint64_t seed, std::uint64_t step, std::uint32_t stream = 0);

}  // namespace rpyfmm::rpy
