// PSE: positions any number of box lengths outside the box wrap exactly into [0, L).
// The naive wrap v - L floor(v / L) fails there: the rounded quotient's floor can be one too
// large, and L floor(v / L) is then rounded too, so that at ~1e16 box lengths a position lands on
// the wrong point of the box (below: 8 -> 4), and far beyond it on garbage (|U| ~ 1e68) or NaN.
// The references are exact integer arithmetic: for L = 12 = 3 * 4, a double x = m 2^q (m an
// integer, q >= 2) has x mod 12 = 4 ((m 2^(q-2)) mod 3), with 2^j mod 3 = 1 (j even) or 2 (j odd).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <span>
#include <vector>

#include "rpyfmm/rpy/pse/pse_rpy.hpp"

using namespace rpyfmm;
using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

namespace {

constexpr double kL = 12.0;  // not a power of two: v / L is rounded

// x mod 12 in [0, 12) for a double x that is a multiple of 4, by integer arithmetic.
double exact_mod12(double x) {
  int q = 0;
  const double frac = std::frexp(std::abs(x), &q);                  // |x| = frac 2^q, frac in [0.5, 1)
  const auto m = static_cast<std::uint64_t>(std::ldexp(frac, 53));  // |x| = m 2^(q - 53)
  const int j = q - 53 - 2;                                         // |x| = 4 m 2^j
  std::uint64_t r3 = 0;
  if (j >= 0) {
    r3 = (m % 3) * (j % 2 == 0 ? 1 : 2) % 3;
  } else {
    r3 = (m >> -j) % 3;  // |x| a multiple of 4: the low -j bits of m are zero
  }
  double r = 4.0 * double(r3);
  if (x < 0 && r != 0.0) r = kL - r;
  return r;
}

bool bitwise_equal(std::span<const double> a, std::span<const double> b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

std::vector<double> product(const PseRpy& op, const std::vector<double>& f) {
  std::vector<double> u(f.size());
  op.apply(f, u);
  return u;
}

PseRpy make_pse() {
  PseOptions o;
  o.tolerance = 1e-4;
  return PseRpy(Geometry::periodic(kL), 1.0, o);
}

}  // namespace

// Positions r in {0, 8}^3 plus k L with k = +-2^52: r + k L = 3 2^54 + r is exact (ulp 8), its
// remainder is r, and the products must be those of r bit for bit. 2^52 is where the old wrap
// first failed (8 -> 4); 2^50 and 2^51 check that smaller multiples stay exact too.
TEST(PseFarPositions, MultiplesOfTheBoxWrapToTheSamePoint) {
  std::vector<double> r;
  for (int i = 0; i < 8; ++i)
    for (int c = 0; c < 3; ++c) r.push_back((i >> c) & 1 ? 8.0 : 0.0);
  std::mt19937_64 rng(9);
  std::normal_distribution<double> g;
  std::vector<double> f(r.size());
  for (double& v : f) v = g(rng);
  PseRpy inside = make_pse();
  inside.set_positions(r, 1.0);
  const auto u_ref = product(inside, f);

  for (double k : {std::ldexp(1.0, 50), std::ldexp(1.0, 51), std::ldexp(1.0, 52), -std::ldexp(1.0, 52)}) {
    std::vector<double> x(r.size());
    for (std::size_t j = 0; j < r.size(); ++j) {
      x[j] = r[j] + k * kL;
      ASSERT_EQ(x[j] - k * kL, r[j]) << "the shifted position is not exact";
    }
    PseRpy far = make_pse();
    far.set_positions(x, 1.0);
    EXPECT_TRUE(bitwise_equal(far.positions(), r)) << "k = " << k;
    EXPECT_TRUE(bitwise_equal(product(far, f), u_ref)) << "k = " << k;
  }
}

// Positions up to 1e300 and down to -1e300 box lengths: stored exactly at their remainder.
TEST(PseFarPositions, HugePositionsStoreTheirExactRemainder) {
  std::mt19937_64 rng(4);
  std::uniform_int_distribution<std::uint64_t> mant(std::uint64_t(1) << 52, (std::uint64_t(1) << 53) - 1);
  std::uniform_int_distribution<int> expo(3, 950);
  const std::size_t n = 200;
  std::vector<double> x(3 * n);
  for (std::size_t j = 0; j < x.size(); ++j) {
    x[j] = std::ldexp(double(mant(rng)), expo(rng));  // >= 2^55: a multiple of 8
    if (j % 2) x[j] = -x[j];
  }
  x[0] = std::ldexp(1.0, 1023);  // the largest powers of two and a value near DBL_MAX
  x[1] = -std::numeric_limits<double>::max();
  PseRpy far = make_pse();
  far.set_positions(x, 1.0);  // remainders in {0, 4, 8}^3: many coincide, as overlapping spheres may
  const auto stored = far.positions();
  for (std::size_t j = 0; j < x.size(); ++j) {
    EXPECT_GE(stored[j], 0.0) << "x = " << x[j];
    EXPECT_LT(stored[j], kL) << "x = " << x[j];
    EXPECT_EQ(stored[j], exact_mod12(x[j])) << "x = " << x[j];
  }
  std::vector<double> f(x.size(), 1.0);
  for (double v : product(far, f)) EXPECT_TRUE(std::isfinite(v));
}
