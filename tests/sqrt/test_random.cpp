// The counter-based generator (rpy/random.hpp, Philox4x32-10 + Box-Muller):
// distribution (KS test, moments), independence of streams and keys, and
// independence of the thread count.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "sqrt_test_util.hpp"

using namespace rpyfmm::rpy;

namespace {

// KS critical value at significance 1e-3 is 1.95 / sqrt(n) (asymptotic).
double ks_critical(std::size_t n) { return 1.95 / std::sqrt(static_cast<double>(n)); }

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
// gives the same array for 1 and 2 threads, and a sub-range equals normal3.
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
  EXPECT_EQ(g[0], z1[3 * 12345]);
  EXPECT_EQ(g[2], z1[3 * 12345 + 2]);
}

TEST(Random, BadSize) {
  std::vector<double> z(10);
  try {
    fill_normal(z, 1u, 1u);
    FAIL();
  } catch (const rpyfmm::Error& e) {
    EXPECT_NE(std::string(e.what()).find("not a multiple of 3"), std::string::npos);
  }
}

}  // namespace
