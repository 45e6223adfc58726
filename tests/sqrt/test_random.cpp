// The counter-based generator (rpy/random.hpp, Philox4x32-10 + Box-Muller):
// distribution (KS test, moments), independence of streams and keys, and
// independence of the thread count.
#include <gtest/gtest.h>
#include <omp.h>

#include <Random123/boxmuller.hpp>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "simd_levels.hpp"
#include "sqrt_test_util.hpp"

using namespace rpyfmm::rpy;

namespace {

// KS critical value at significance 1e-3 is 1.95 / sqrt(n) (asymptotic).
double ks_critical(std::size_t n) {
  return 1.95 / std::sqrt(static_cast<double>(n));
}

TEST(Random, StandardNormalKsAndMoments) {
  std::vector<double> z(3 * 100000);
  fill_normal(z, 2024u, 0u);
  EXPECT_LT(sqrt_test::ks_statistic_normal(z), ks_critical(z.size()));
  // Each component separately (the third comes from a second Philox block).
  for (int c = 0; c < 3; ++c) {
    std::vector<double> comp;
    for (std::size_t i = c; i < z.size(); i += 3) comp.push_back(z[i]);
    EXPECT_LT(sqrt_test::ks_statistic_normal(comp), ks_critical(comp.size())) << "component " << c;
  }
  double m1 = 0, m2 = 0, m4 = 0;
  for (double v : z) {
    m1 += v;
    m2 += v * v;
    m4 += v * v * v * v;
  }
  const double n = static_cast<double>(z.size());
  m1 /= n;
  m2 /= n;
  m4 /= n;
  // Standard errors: mean 1/sqrt(n), variance sqrt(2/n), 4th moment sqrt(96/n); 5 sigma.
  EXPECT_LT(std::abs(m1), 5 / std::sqrt(n));
  EXPECT_LT(std::abs(m2 - 1), 5 * std::sqrt(2 / n));
  EXPECT_LT(std::abs(m4 - 3), 5 * std::sqrt(96 / n));
}

// Components of one particle and neighbouring particles are uncorrelated.
TEST(Random, ComponentsUncorrelated) {
  std::vector<double> z(3 * 100000);
  fill_normal(z, 7u, 3u);
  const std::size_t N = z.size() / 3;
  for (auto [p, q] : {std::pair{0, 1}, {0, 2}, {1, 2}}) {
    double s = 0;
    for (std::size_t i = 0; i < N; ++i) s += z[3 * i + p] * z[3 * i + q];
    EXPECT_LT(std::abs(s / N), 5 / std::sqrt(double(N))) << p << "," << q;
  }
  double s = 0;
  for (std::size_t i = 0; i + 1 < N; ++i) s += z[3 * i] * z[3 * (i + 1)];
  EXPECT_LT(std::abs(s / N), 5 / std::sqrt(double(N)));
}

// Different seeds, steps and streams give different (uncorrelated) streams;
// the same key reproduces the same numbers.
TEST(Random, DifferentKeysDifferentStreams) {
  const std::size_t n = 3 * 50000;
  std::vector<double> base(n), again(n);
  fill_normal(base, 1u, 10u, 0u);
  fill_normal(again, 1u, 10u, 0u);
  EXPECT_EQ(base, again);
  struct Key {
    std::uint64_t seed, step;
    std::uint32_t stream;
  };
  for (Key k : {Key{2u, 10u, 0u}, Key{1u, 11u, 0u}, Key{1u, 10u, 1u}, Key{1ull << 32, 10u, 0u},
                Key{1u, 10ull + (1ull << 32), 0u}}) {
    std::vector<double> other(n);
    fill_normal(other, k.seed, k.step, k.stream);
    double corr = 0;
    std::size_t equal = 0;
    for (std::size_t i = 0; i < n; ++i) {
      corr += base[i] * other[i];
      equal += base[i] == other[i];
    }
    EXPECT_LT(std::abs(corr / n), 5 / std::sqrt(double(n))) << k.seed << " " << k.step << " " << k.stream;
    EXPECT_EQ(equal, 0u);
  }
  // Particles beyond 2^32 are distinct from their low-word twins.
  double a[3], b[3];
  normal3(5u, 0u, 0u, 17u, a);
  normal3(5u, 0u, 0u, 17u + (1ull << 32), b);
  EXPECT_NE(a[0], b[0]);
}

// A draw is a pure function of (seed, step, stream, particle): fill_normal
// gives the same array for 1 and 2 threads, and its entries are normal3's.
TEST(Random, IndependentOfThreadCount) {
  const std::size_t n = 3 * 40000;
  std::vector<double> z1(n), z2(n);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  fill_normal(z1, 99u, 5u, 2u);
  omp_set_num_threads(2);
  fill_normal(z2, 99u, 5u, 2u);
  omp_set_num_threads(saved);
  EXPECT_EQ(z1, z2);
  double g[3];
  normal3(99u, 5u, 2u, 12345u, g);
  // normal3 here and fill_normal's vectors evaluate the same operations: equal up to fused
  // multiply-adds on builds that contract (bit for bit on the portable presets).
  EXPECT_NEAR(g[0], z1[3 * 12345], 1e-14 * std::max(1.0, std::abs(g[0])));
  EXPECT_NEAR(g[2], z1[3 * 12345 + 2], 1e-14 * std::max(1.0, std::abs(g[2])));
}

// sincospi_poly (the angle of the wave-space Box-Muller) against libm on a dense grid and
// at the quadrant boundaries. 1e-15 absolute is ~4 ulps of 1: the reference sin(pi * v) itself
// carries the rounding of pi * v (up to 1 ulp of the argument) and libm's own half ulp.
TEST(Random, SincospiPolyMatchesLibm) {
  const double pi = 3.14159265358979323846;
  double worst = 0.0;
  auto check = [&](double v) {
    double s, c;
    random_detail::sincospi_poly(v, s, c);
    worst = std::max({worst, std::abs(s - std::sin(pi * v)), std::abs(c - std::cos(pi * v))});
  };
  for (int i = -200000; i <= 200000; ++i) check(i / 200000.0 + 1.3e-7);
  for (double v : {-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0, 0.25000000001, -0.7499999999}) check(v);
  EXPECT_LT(worst, 1e-15);
}

// log_poly (the radius of that Box-Muller) against libm from 2^-52 to 1 and beyond.
TEST(Random, LogPolyMatchesLibm) {
  double worst = 0.0;
  for (int i = 1; i <= 400000; ++i) {
    const double x = std::ldexp(1.0 + (i % 1000) / 1000.0, -(i % 53)) * (1.0 + 1e-9 * i);
    const double ref = std::log(x);
    worst = std::max(worst, std::abs(random_detail::log_poly(x) - ref) / std::max(1.0, std::abs(ref)));
  }
  EXPECT_EQ(random_detail::log_poly(1.0), 0.0);
  EXPECT_LT(worst, 1e-15);  // a few ulps; the Box-Muller radius needs far less
}

// fill_normal6 (vectorized) gives normal6's values for arbitrary, unordered indices above
// 2^32 and any length (chunk tails, groups of 16 / 8 lanes with spare lanes); bit for bit on
// builds without FMA contraction. At every instruction-set level the machine has.
TEST(Random, FillNormal6EqualsNormal6) {
  std::vector<std::uint64_t> index;
  for (std::uint64_t i = 0; i < 1003; ++i)
    index.push_back((i * 2654435761ull) % 100000 + (i % 7 == 0 ? (5ull << 32) : 0));
  for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
    const rpyfmm::ScopedSimdLevel scope(level);
    for (const std::size_t n : {std::size_t{1003}, std::size_t{5}, std::size_t{17}, std::size_t{64}}) {
      const std::span<const std::uint64_t> idx(index.data(), n);
      std::vector<double> out(6 * n);
      fill_normal6(idx, 0x1234567890ull, 77u, 2u, out);
      double worst = 0.0;
      for (std::size_t k = 0; k < n; ++k) {
        double ref[6];
        normal6(0x1234567890ull, 77u, 2u, idx[k], ref);
        for (int c = 0; c < 6; ++c)
          worst = std::max(worst, std::abs(out[6 * k + c] - ref[c]) / std::max(1.0, std::abs(ref[c])));
      }
      EXPECT_LT(worst, 1e-14) << "n " << n << " at " << rpyfmm::simd_level_name(level);
    }
  }
  std::vector<double> bad(5);
  EXPECT_THROW(fill_normal6(std::span<const std::uint64_t>(index.data(), 1), 1u, 1u, 2u, bad), rpyfmm::Error);
  std::vector<double> six(6);
  EXPECT_THROW(fill_normal6(std::span<const std::uint64_t>(index.data(), 1), 1u, 1u, 1u << 24, six), rpyfmm::Error);
}

// normal6 (one call per PSE Fourier mode): standard normal per slot (KS, moments),
// slots of one index uncorrelated, a pure function of its key, distinct keys differ.
TEST(Random, Normal6StandardAndIndependent) {
  const std::size_t n = 60000;
  std::vector<double> z(6 * n);
  for (std::size_t i = 0; i < n; ++i) normal6(31u, 4u, 2u, i, &z[6 * i]);
  for (int c = 0; c < 6; ++c) {
    std::vector<double> comp;
    double m2 = 0;
    for (std::size_t i = c; i < z.size(); i += 6) {
      comp.push_back(z[i]);
      m2 += z[i] * z[i];
    }
    EXPECT_LT(sqrt_test::ks_statistic_normal(comp), ks_critical(comp.size())) << "slot " << c;
    EXPECT_LT(std::abs(m2 / n - 1), 5 * std::sqrt(2.0 / n)) << "slot " << c;
    for (int d = c + 1; d < 6; ++d) {
      double s = 0;
      for (std::size_t i = 0; i < n; ++i) s += z[6 * i + c] * z[6 * i + d];
      EXPECT_LT(std::abs(s / n), 5 / std::sqrt(double(n))) << c << "," << d;
    }
  }
  double a[6], b[6], c6[6], d6[6];
  normal6(31u, 4u, 2u, 777u, a);
  normal6(31u, 4u, 2u, 777u, b);
  normal6(31u, 5u, 2u, 777u, c6);
  normal6(31u, 4u, 2u, 777u + (1ull << 32), d6);
  for (int k = 0; k < 6; ++k) {
    EXPECT_EQ(a[k], b[k]);
    EXPECT_NE(a[k], c6[k]);
    EXPECT_NE(a[k], d6[k]);
    EXPECT_EQ(a[k], z[6 * 777 + k]);
  }
}

// The single-precision transform (normal6f, the noise of float PSE wave grids): its polynomials
// against libm to a few float ulps, and its values against normal6's (the same Philox words)
// to 1e-6 max(1, |g|): float's unit round-off 6e-8 times the conditioning of sqrt(-2 log u) and
// of the angle. Checked on random words and on crafted ones at both ends of u (u = 2^-32:
// |g| = 6.66; u -> 1: radii ~1e-5, where 1 - u must not be formed from a rounded u).
TEST(Random, SinglePrecisionBoxMullerFollowsDouble) {
  const double pi = 3.14159265358979323846;
  double worst_trig = 0.0;
  for (int i = -100000; i <= 100000; ++i) {
    const float v = static_cast<float>(i / 100000.0 + 1.3e-7);
    float s, c;
    random_detail::sincospi_polyf(v, s, c);
    worst_trig = std::max({worst_trig, std::abs(s - std::sin(pi * v)), std::abs(c - std::cos(pi * v))});
  }
  EXPECT_LT(worst_trig, 4e-7);  // a few ulps of 1
  double worst_log = 0.0;
  for (int i = 1; i <= 100000; ++i) {
    const double x = std::ldexp(1.0 + (i % 1000) / 1000.0, -(i % 33)) * (1.0 + 1e-9 * i);
    const float xf = static_cast<float>(std::min(x, 1.0));
    const double ref = std::log(static_cast<double>(xf));
    const float t = static_cast<float>(1.0 - static_cast<double>(xf));
    worst_log = std::max(worst_log, std::abs(random_detail::log_polyf(xf, t) - ref) / std::max(1e-30, std::abs(ref)));
  }
  EXPECT_LT(worst_log, 1e-6);  // relative, also near x = 1 thanks to t
  EXPECT_EQ(random_detail::log_polyf(1.0f, 0.0f), 0.0f);

  auto compare = [](std::uint32_t w0, std::uint32_t w1, std::uint32_t w2, std::uint32_t w3) {
    double g0, g1;
    float f0, f1;
    random_detail::box_muller_bits((std::uint64_t{w0} << 32) | w1, (std::uint64_t{w2} << 32) | w3, g0, g1);
    random_detail::box_muller_bits_f(w0, w2, w3, f0, f1);
    return std::max(std::abs(f0 - g0) / std::max(1.0, std::abs(g0)), std::abs(f1 - g1) / std::max(1.0, std::abs(g1)));
  };
  double worst = 0.0;
  std::mt19937 rng(3);
  for (int i = 0; i < 200000; ++i) worst = std::max(worst, compare(rng(), rng(), rng(), rng()));
  for (std::uint32_t w2 : {0u, 1u, 7u, 0xFFFFu, 0x7FFFFFFFu, 0xFFFFFF00u, 0xFFFFFFFEu, 0xFFFFFFFFu})
    for (std::uint32_t w3 : {0u, 0x1000u, 0x80000000u, 0xFFFFFFFFu})
      for (std::uint32_t w0 : {0u, 0x40000000u, 0x80000000u, 0xC0000001u, 0xFFFFFFFFu})
        worst = std::max(worst, compare(w0, 12345u, w2, w3));
  EXPECT_LT(worst, 1e-6);

  // normal6f against normal6, and the vectorized fill (interleaved and planar) against normal6f:
  // bit for bit without FMA contraction, a few ulps with it.
  std::vector<std::uint64_t> index;
  for (std::uint64_t i = 0; i < 1003; ++i)
    index.push_back(i * 2654435761ull % 100000 + (i % 5 == 0 ? (3ull << 32) : 0));
  for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
    const rpyfmm::ScopedSimdLevel scope(level);
    std::vector<float> out(6 * index.size()), planar(6 * index.size());
    std::vector<double> planar_d(6 * index.size());
    fill_normal6(index, 99u, 4u, 2u, std::span<float>(out));
    random_detail::fill_normal6_planar(index, 99u, 4u, 2u, std::span<float>(planar));
    random_detail::fill_normal6_planar(index, 99u, 4u, 2u, std::span<double>(planar_d));
    double worst_fill = 0.0, worst_vs_double = 0.0;
    for (std::size_t k = 0; k < index.size(); ++k) {
      float ref[6];
      double refd[6];
      normal6f(99u, 4u, 2u, index[k], ref);
      normal6(99u, 4u, 2u, index[k], refd);
      for (std::size_t c = 0; c < 6; ++c) {
        const double scale = std::max(1.0, std::abs(static_cast<double>(ref[c])));
        worst_fill = std::max(worst_fill, std::abs(static_cast<double>(out[6 * k + c] - ref[c])) / scale);
        worst_fill = std::max(worst_fill, std::abs(static_cast<double>(planar[c * index.size() + k] - ref[c])) / scale);
        worst_vs_double = std::max(worst_vs_double, std::abs(ref[c] - refd[c]) / std::max(1.0, std::abs(refd[c])));
        EXPECT_NEAR(planar_d[c * index.size() + k], refd[c], 1e-14 * std::max(1.0, std::abs(refd[c])));
      }
    }
    EXPECT_LT(worst_fill, 1e-6) << rpyfmm::simd_level_name(level);
    EXPECT_LT(worst_vs_double, 1e-6);
  }
  std::vector<float> bad(5);
  EXPECT_THROW(fill_normal6(std::span<const std::uint64_t>(index.data(), 1), 1u, 1u, 2u, std::span<float>(bad)),
               rpyfmm::Error);
}

// normal3's Box-Muller (random_detail::box_muller_r123: polynomials instead of libm) against
// Random123's own r123::boxmuller on the same words: a few ulps (1e-14 relative to max(1, |g|)),
// on random words and at the ends of both uniforms. And fill_normal (vectorized, in chunks of
// 64 particles, in parallel above 16384) against normal3 for sizes with chunk tails, at every
// instruction-set level: bit for bit on builds without FMA contraction, 1e-14 here.
TEST(Random, Normal3FollowsRandom123BoxMuller) {
  double worst = 0.0;
  auto compare = [&](std::uint64_t u0, std::uint64_t u1) {
    const r123::double2 ref = r123::boxmuller(u0, u1);
    double g0, g1;
    random_detail::box_muller_r123(u0, u1, g0, g1);
    worst = std::max({worst, std::abs(g0 - ref.x) / std::max(1.0, std::abs(ref.x)),
                      std::abs(g1 - ref.y) / std::max(1.0, std::abs(ref.y))});
  };
  std::mt19937_64 rng(9);
  for (int i = 0; i < 200000; ++i) compare(rng(), rng());
  for (std::uint64_t u0 : {0ull, 1ull, 0x7FFFFFFFFFFFFFFFull, 0x8000000000000000ull, ~0ull, 0x4000000000000000ull})
    for (std::uint64_t u1 : {0ull, 1ull, 0x8000000000000000ull, ~0ull - 1, ~0ull}) compare(u0, u1);
  EXPECT_LT(worst, 1e-14);

  for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
    const rpyfmm::ScopedSimdLevel scope(level);
    for (const std::size_t n :
         {std::size_t{1}, std::size_t{63}, std::size_t{64}, std::size_t{1001}, std::size_t{20011}}) {
      std::vector<double> z(3 * n);
      fill_normal(z, 0x9876543210ull, 12u, 1u);
      double worst_fill = 0.0;
      for (std::size_t i = 0; i < n; i += (n > 2000 ? 7 : 1)) {
        double ref[3];
        normal3(0x9876543210ull, 12u, 1u, i, ref);
        for (std::size_t c = 0; c < 3; ++c)
          worst_fill = std::max(worst_fill, std::abs(z[3 * i + c] - ref[c]) / std::max(1.0, std::abs(ref[c])));
      }
      EXPECT_LT(worst_fill, 1e-14) << "n " << n << " at " << rpyfmm::simd_level_name(level);
    }
  }
}

// fill_normal at a list of particle indices (a rank's particles under MPI) gives, bit for bit, the
// values fill_normal gives those particles in the whole set: the same chunked Philox and Box-Muller
// on the same counters, at every instruction-set level.
TEST(Random, FillNormalAtIndicesEqualsTheWholeSetsValues) {
  const std::size_t n = 20011;
  std::vector<std::uint64_t> index;
  for (std::size_t i = n - 1; i < n; i -= 3) index.push_back(i);  // descending, every third
  for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
    const rpyfmm::ScopedSimdLevel scope(level);
    std::vector<double> whole(3 * n), part(3 * index.size());
    fill_normal(whole, 77u, 5u, 2u);
    fill_normal(index, part, 77u, 5u, 2u);
    std::size_t differ = 0;
    for (std::size_t k = 0; k < index.size(); ++k)
      for (std::size_t c = 0; c < 3; ++c) differ += part[3 * k + c] != whole[3 * index[k] + c] ? 1 : 0;
    EXPECT_EQ(differ, 0u) << rpyfmm::simd_level_name(level);
  }
  std::vector<double> wrong(5);
  EXPECT_THROW(fill_normal(std::vector<std::uint64_t>{1, 2}, wrong, 1u, 1u), rpyfmm::Error);
}

TEST(Random, BadSize) {
  std::vector<double> z(10);
  try {
    fill_normal(z, 1u, 1u);
    FAIL();
  } catch (const rpyfmm::Error& e) {
    EXPECT_NE(std::string(e.what()).find("not a multiple of 3"), std::string::npos);
  }
  // The top bit of the stream word selects normal3's second block: streams from 2^31 on refused.
  std::vector<double> six(6);
  try {
    fill_normal(six, 1u, 1u, 0x80000000u);
    FAIL();
  } catch (const rpyfmm::Error& e) {
    EXPECT_NE(std::string(e.what()).find("must be below 2^31"), std::string::npos);
  }
  EXPECT_NO_THROW(fill_normal(six, 1u, 1u, 0x7FFFFFFFu));
}

}  // namespace
