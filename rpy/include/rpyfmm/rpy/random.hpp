// rpyfmm — counter-based normal random numbers.
//
// A draw is a pure function of (seed, step, stream, particle): results do not
// depend on thread count or on the order of work, and normal3() / normal6() compile for
// CUDA (host and device) so that CPU and GPU noise agree (the same operations: equal up to
// fused multiply-adds).
// Philox4x32-10 (Salmon, Moraes, Dror & Shaw, SC'11; Random123) and Box-Muller transforms
// by polynomials (no libm call but sqrt), so that batches vectorize.
#pragma once

#include <Random123/philox.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <type_traits>

#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::rpy {

namespace random_detail {

/// The value of type To with the bits of `from` (same size; std::bit_cast is not yet usable
/// in device code): double <-> uint64 and float <-> uint32.
template <class To, class From>
RPYFMM_HOST_DEVICE inline To bit_copy(From from) {
  static_assert(sizeof(To) == sizeof(From), "bit_copy between types of one size");
#ifdef __CUDA_ARCH__
  if constexpr (std::is_same_v<To, double>) {
    return __longlong_as_double(static_cast<long long>(from));
  } else if constexpr (std::is_same_v<From, double>) {
    return static_cast<To>(__double_as_longlong(from));
  } else if constexpr (std::is_same_v<To, float>) {
    return __uint_as_float(from);
  } else {
    return __float_as_uint(from);
  }
#else
  To to;
  std::memcpy(&to, &from, sizeof to);
  return to;
#endif
}
RPYFMM_HOST_DEVICE inline double from_bits(std::uint64_t b) {
  return bit_copy<double>(b);
}
RPYFMM_HOST_DEVICE inline std::uint64_t to_bits(double d) {
  return bit_copy<std::uint64_t>(d);
}

// The functions below are branch-free, call no libm function but sqrt, and speculate no
// operation that can trap, so that a loop over them vectorizes (rpy/src/random_batch.cpp)
// and host and device evaluate the same operations.

/// sin(pi v), cos(pi v) from sr = sin(pi r), cp = cos(pi r), v = q/2 + r, q in {-2, ..., 2}:
/// q = 0 gives (sr, cp); q = +-1 swaps to (cp, -sr); q = -1, +-2 negate both.
template <class T>
RPYFMM_HOST_DEVICE inline void sincos_quadrant(T q, T sr, T cp, T& s, T& c) {
  const T aq = q < T(0) ? -q : q;
  const bool odd = aq == T(1);
  const bool negate = (q == T(-1)) | (aq == T(2));
  const T s0 = odd ? cp : sr;
  const T c0 = odd ? -sr : cp;
  s = negate ? -s0 : s0;
  c = negate ? -c0 : c0;
}

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
  sincos_quadrant(q, x * sp, cp, s, c);
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

/// Random123's Box-Muller (r123::boxmuller on two 64-bit words) with sincospi_poly and
/// log_poly in place of libm's functions, so that it vectorizes and host and device compute the
/// same operations: v = uneg11(u0) = int64(u0) 2^-63 + 2^-64 in [-1, 1], u = u01(u1) =
/// u1 2^-64 + 2^-65 in (0, 1] (Random123's uniform.hpp mappings); g0 = sin(pi v) r,
/// g1 = cos(pi v) r, r = sqrt(-2 log u). Equal to r123::boxmuller to a few ulps
/// (tests/sqrt/test_random.cpp).
RPYFMM_HOST_DEVICE inline void box_muller_r123(std::uint64_t u0, std::uint64_t u1, double& g0, double& g1) {
  const double v = static_cast<double>(static_cast<std::int64_t>(u0)) * 0x1p-63 + 0x1p-64;
  const double u = static_cast<double>(u1) * 0x1p-64 + 0x1p-65;
  double s, c;
  sincospi_poly(v, s, c);
  const double r = std::sqrt(-2.0 * log_poly(u));
  g0 = s * r;
  g1 = c * r;
}

/// sincospi_poly in single precision: the same quadrant reduction (q = round(2v) by the
/// 1.5 * 2^23 trick), Taylor polynomials to x^9 / x^10 on |x| <= pi/4 (truncation below 3e-9,
/// under float's unit round-off 6e-8).
RPYFMM_HOST_DEVICE inline void sincospi_polyf(float v, float& s, float& c) {
  const float round_magic = 12582912.0f;  // 1.5 * 2^23
  const float q = (2.0f * v + round_magic) - round_magic;
  const float r = v - 0.5f * q;
  const float x = 3.14159265358979f * r;
  const float x2 = x * x;
  const float sp = 1.0f + x2 * (-1.0f / 6.0f + x2 * (1.0f / 120.0f + x2 * (-1.0f / 5040.0f + x2 * (1.0f / 362880.0f))));
  const float cp =
      1.0f +
      x2 * (-0.5f + x2 * (1.0f / 24.0f + x2 * (-1.0f / 720.0f + x2 * (1.0f / 40320.0f + x2 * (-1.0f / 3628800.0f)))));
  sincos_quadrant(q, x * sp, cp, s, c);
}

/// log x in single precision for a positive normal float x, given also t = 1 - x to float's
/// relative precision: the reduction of log_poly, but with m - 1 = -t, m + 1 = 2 - t for
/// x > 3/4 (there x - 1 computed from a rounded x would keep few bits); the atanh series to
/// s^9 (|s| <= 0.1716: truncation below 2e-9 relative).
RPYFMM_HOST_DEVICE inline float log_polyf(float x, float t) {
  const std::uint32_t b = bit_copy<std::uint32_t>(x);
  float e = static_cast<float>(static_cast<std::int32_t>(b >> 23) - 127);
  float m = bit_copy<float>((b & 0x007FFFFFu) | 0x3F800000u);  // [1, 2)
  const bool big = m > 1.41421356f;
  m *= big ? 0.5f : 1.0f;
  e += big ? 1.0f : 0.0f;
  const bool near_one = t < 0.25f;  // x in (3/4, 1]: e = 0, m = x
  const float num = near_one ? -t : m - 1.0f;
  const float den = near_one ? 2.0f - t : m + 1.0f;
  e = near_one ? 0.0f : e;
  const float s = num / den;
  const float s2 = s * s;
  const float p = 1.0f + s2 * (1.0f / 3.0f + s2 * (1.0f / 5.0f + s2 * (1.0f / 7.0f + s2 * (1.0f / 9.0f))));
  return e * 0.693147180559945f + 2.0f * s * p;
}

/// box_muller_bits in single precision, from the same four 32-bit words (u0 = w0:w1,
/// u1 = w2:w3; w1 only moves v below float's resolution): v, u = 1 - t and t are box_muller_bits's
/// v and u rounded to float (within 2 ulps; u = (~w2 + 1 - w3' / 2^20) / 2^32 and
/// t = (w2 + w3' / 2^20) / 2^32 with w3' = w3 >> 12, each a sum of two positive terms, keep their
/// relative precision at both ends: |g| <= 6.7 at u = 2^-32, and the small radii at u near 1), so
/// g0, g1 equal box_muller_bits's values to a few float ulps. For single-precision PSE wave grids,
/// whose spectrum is float anyway.
RPYFMM_HOST_DEVICE inline void box_muller_bits_f(std::uint32_t w0, std::uint32_t w2, std::uint32_t w3, float& g0,
                                                 float& g1) {
  const float v = static_cast<float>(static_cast<std::int32_t>(w0 ^ 0x80000000u)) * 4.656612873077393e-10f;  // 2^-31
  const float low = static_cast<float>(static_cast<std::int32_t>(w3 >> 12)) * 9.5367431640625e-07f;          // [0, 1)
  const float u = (static_cast<float>(~w2) + (1.0f - low)) * 2.3283064365386963e-10f;                        // (0, 1]
  const float t = (static_cast<float>(w2) + low) * 2.3283064365386963e-10f;                                  // [0, 1)
  float s, c;
  sincospi_polyf(v, s, c);
  const float rad = std::sqrt(-2.0f * log_polyf(u, t));
  g0 = rad * s;
  g1 = rad * c;
}

/// Philox4x32-10 counter (index_lo, c1, step_lo, step_hi) of one block: c1 = stream + 2^24 b for
/// block b of normal6, stream and stream ^ 2^31 for normal3's two blocks.
RPYFMM_HOST_DEVICE inline r123::Philox4x32::ctr_type philox_counter(std::uint64_t index, std::uint32_t c1,
                                                                    std::uint64_t step) {
  return {{static_cast<std::uint32_t>(index), c1, static_cast<std::uint32_t>(step),
           static_cast<std::uint32_t>(step >> 32)}};
}
/// Philox4x32-10 key (seed_lo ^ index_hi, seed_hi) of normal3 and normal6: the index's high word
/// goes into the key, so that more than 2^32 indices stay distinct.
RPYFMM_HOST_DEVICE inline r123::Philox4x32::key_type normal6_key(std::uint64_t seed, std::uint64_t index) {
  return {{static_cast<std::uint32_t>(seed) ^ static_cast<std::uint32_t>(index >> 32),
           static_cast<std::uint32_t>(seed >> 32)}};
}

/// Box-Muller on one Philox block's words (u0 = w0:w1, u1 = w2:w3): box_muller_bits for double
/// values, box_muller_bits_f for float ones.
RPYFMM_HOST_DEVICE inline void box_muller_words(std::uint32_t w0, std::uint32_t w1, std::uint32_t w2, std::uint32_t w3,
                                                double& g0, double& g1) {
  box_muller_bits((static_cast<std::uint64_t>(w0) << 32) | w1, (static_cast<std::uint64_t>(w2) << 32) | w3, g0, g1);
}
RPYFMM_HOST_DEVICE inline void box_muller_words(std::uint32_t w0, std::uint32_t /*w1*/, std::uint32_t w2,
                                                std::uint32_t w3, float& g0, float& g1) {
  box_muller_bits_f(w0, w2, w3, g0, g1);
}

/// normal6 (Real = double) and normal6f (Real = float).
template <class Real>
RPYFMM_HOST_DEVICE inline void normal6_as(std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                                          std::uint64_t index, Real out[6]) {
  const r123::Philox4x32 rng;
  const auto key = normal6_key(seed, index);
  for (std::uint32_t b = 0; b < 3; ++b) {
    const auto r = rng(philox_counter(index, stream + (b << 24), step), key);
    box_muller_words(r.v[0], r.v[1], r.v[2], r.v[3], out[2 * b], out[2 * b + 1]);
  }
}

}  // namespace random_detail

/// Three independent N(0,1) values for (seed, step, stream, particle).
/// Counter = (particle, stream, step_lo, step_hi), key = (seed_lo ^ particle_hi, seed_hi); the
/// third value uses the counter with stream | 2^31, so `stream` must be below 2^31. Each Philox
/// block gives two normals by Random123's Box-Muller mapping (random_detail::box_muller_r123;
/// the third value's block gives one). fill_normal computes the same values for many particles
/// at once, vectorized.
RPYFMM_HOST_DEVICE inline void normal3(std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                                       std::uint64_t particle, double out[3]) {
  const r123::Philox4x32 rng;
  const auto key = random_detail::normal6_key(seed, particle);
  const auto r = rng(random_detail::philox_counter(particle, stream, step), key);
  random_detail::box_muller_r123((static_cast<std::uint64_t>(r.v[0]) << 32) | r.v[1],
                                 (static_cast<std::uint64_t>(r.v[2]) << 32) | r.v[3], out[0], out[1]);
  // The second block, for the third component.
  const auto t = rng(random_detail::philox_counter(particle, stream ^ 0x80000000u, step), key);
  double unused;
  random_detail::box_muller_r123((static_cast<std::uint64_t>(t.v[0]) << 32) | t.v[1],
                                 (static_cast<std::uint64_t>(t.v[2]) << 32) | t.v[3], out[2], unused);
}

/// Six independent N(0,1) values for (seed, step, stream, index): three Philox4x32-10 blocks
/// (counter (index_lo, stream + 2^24 b, step_lo, step_hi), b = 0, 1, 2; key (seed_lo ^ index_hi,
/// seed_hi)), each giving two normals by Box-Muller (random_detail::box_muller_bits).
/// `stream` must be below 2^24. One call per PSE Fourier mode (the wave-space noise);
/// fill_normal6 computes the same values for many indices at once, vectorized.
RPYFMM_HOST_DEVICE inline void normal6(std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                                       std::uint64_t index, double out[6]) {
  random_detail::normal6_as(seed, step, stream, index, out);
}

/// normal6's six values computed in single precision (random_detail::box_muller_bits_f on the
/// same Philox words): equal to normal6's to a few float ulps (|difference| below 1e-6 max(1, |g|)).
/// The wave-space noise of single-precision PSE grids, on CPU and GPU alike.
RPYFMM_HOST_DEVICE inline void normal6f(std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                                        std::uint64_t index, float out[6]) {
  random_detail::normal6_as(seed, step, stream, index, out);
}

/// out[6 k + c] = normal6(seed, step, stream, index[k])[c] for every k (vectorized with AVX2 /
/// AVX-512 where the CPU has them; the values equal normal6's to a few ulps, contraction of
/// a * b + c into fused multiply-adds aside). out.size() must be 6 index.size(), stream < 2^24.
void fill_normal6(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                  std::span<double> out);

/// out[6 k + c] = normal6f(seed, step, stream, index[k])[c] for every k (vectorized as
/// fill_normal6; equal to normal6f's values to a few float ulps).
void fill_normal6(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step, std::uint32_t stream,
                  std::span<float> out);

namespace random_detail {
/// fill_normal6 with the values in planes: value c of index k at out[c * n + k], n = index.size()
/// (the layout the PSE wave-space line loop vectorizes over).
void fill_normal6_planar(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step,
                         std::uint32_t stream, std::span<double> out);
void fill_normal6_planar(std::span<const std::uint64_t> index, std::uint64_t seed, std::uint64_t step,
                         std::uint32_t stream, std::span<float> out);
}  // namespace random_detail

/// Fills z[3*i + c] (i = 0..N-1, c = 0..2) with normal3(seed, step, stream, i), vectorized
/// (AVX2 / AVX-512 where the CPU has them) and in parallel (OpenMP): the values equal normal3's
/// to a few ulps (bit for bit on builds without FMA contraction), whatever the thread count.
/// z.size() must be a multiple of 3 and stream < 2^31 (throws rpyfmm::Error otherwise).
void fill_normal(std::span<double> z, std::uint64_t seed, std::uint64_t step, std::uint32_t stream = 0);

/// z[3 k + c] = normal3(seed, step, stream, index[k])[c] for every k: fill_normal's values for any
/// particle indices (a rank's particles under MPI, rpyfmm/mpi/brownian_dynamics.hpp), computed as
/// fill_normal computes them. z.size() must be 3 index.size() and stream < 2^31.
void fill_normal(std::span<const std::uint64_t> index, std::span<double> z, std::uint64_t seed, std::uint64_t step,
                 std::uint32_t stream = 0);

}  // namespace rpyfmm::rpy
