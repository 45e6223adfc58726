// PSE real-space kernel: closed forms of [PSE] App. A against an independent
// Fourier quadrature, regression values, continuity, limits, table and cutoff.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "ewald_reference.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/pse/real_space.hpp"

using namespace rpyfmm::rpy::pse;

TEST(PseRealSpace, ClosedFormMatchesFourierQuadrature) {
  // Quadrature of [PSE] eqs. 12-13 (no closed form involved). Its truncation at
  // k = 3000/a leaves oscillatory tails ~1e-9; the closed form is exact: tolerance 1e-7.
  const double a = 1.0;
  for (double xa : {0.3, 0.5, 1.0, 2.0}) {
    for (double r : {0.05, 0.5, 1.0, 1.9, 2.0, 2.1, 3.0, 4.5}) {
      const FG c = real_space_fg(r, xa / a, a);
      const auto q = pse_test::fourier_fg(r, xa / a, a);
      EXPECT_NEAR(c.f, q[0], 1e-7) << "xi a = " << xa << ", r = " << r;
      EXPECT_NEAR(c.g, q[1], 1e-7) << "xi a = " << xa << ", r = " << r;
    }
  }
}

TEST(PseRealSpace, RegressionValuesFromExtendedPrecision) {
  // [PSE] eqs. A1-A4 evaluated independently in 60-digit arithmetic, xi a = 0.5, a = 1.
  EXPECT_NEAR(real_space_self(0.5, 1.0), 0.33561712446901, 1e-13);
  const FG v1 = real_space_fg(1.0, 0.5, 1.0);
  EXPECT_NEAR(v1.f, 0.12319096951, 1e-10);
  EXPECT_NEAR(v1.g, 0.18340938010, 1e-10);
  const FG v2 = real_space_fg(2.1, 0.5, 1.0);
  EXPECT_NEAR(v2.f, -0.01476084264, 1e-10);
  EXPECT_NEAR(v2.g, 0.07431946232, 1e-10);
  const FG v3 = real_space_fg(3.0, 0.5, 1.0);
  EXPECT_NEAR(v3.f, -0.02918344398, 1e-10);
  EXPECT_NEAR(v3.g, 0.02130117477, 1e-10);
}

TEST(PseRealSpace, ContinuousWithContinuousSlopeAt2a) {
  // f0, g0 vanish at 2a with a double / triple zero (docs/theory/pse.md): F, G and F', G'
  // are continuous. Values: linear extrapolation from each side reaches F(2a) to O(h^2);
  // slopes: one-sided differences agree to O(h) (the second derivative jumps).
  for (double xa : {0.3, 0.5, 1.0, 2.0}) {
    const double h = 1e-5;
    auto f = [&](double r) { return real_space_fg(r, xa, 1.0); };
    const FG lo2 = f(2.0 - 2 * h), lo = f(2.0 - h), mid = f(2.0), hi = f(2.0 + h), hi2 = f(2.0 + 2 * h);
    EXPECT_NEAR(2 * lo.f - lo2.f, mid.f, 1e-8) << xa;
    EXPECT_NEAR(2 * hi.f - hi2.f, mid.f, 1e-8) << xa;
    EXPECT_NEAR(2 * lo.g - lo2.g, mid.g, 1e-8) << xa;
    EXPECT_NEAR(2 * hi.g - hi2.g, mid.g, 1e-8) << xa;
    EXPECT_NEAR((mid.f - lo.f) / h, (hi.f - mid.f) / h, 1e-4) << xa;
    EXPECT_NEAR((mid.g - lo.g) / h, (hi.g - mid.g) / h, 1e-4) << xa;
  }
}

TEST(PseRealSpace, SeriesJoinsClosedFormAndSelfTerm) {
  for (double xa : {0.3, 0.5, 1.0, 2.0}) {
    const double rs = std::clamp(0.01 / xa, 0.004, 0.2);
    const FG below = real_space_fg(rs * (1 - 1e-9), xa, 1.0), above = real_space_fg(rs * (1 + 1e-9), xa, 1.0);
    // Both sides carry <= ~5e-10 error there (docs/theory/pse.md): the jump is <= 2e-9.
    EXPECT_NEAR(below.f, above.f, 2e-9) << xa;
    EXPECT_NEAR(below.g, above.g, 2e-9) << xa;
    const FG zero = real_space_fg(0.0, xa, 1.0);
    EXPECT_DOUBLE_EQ(zero.f, real_space_self(xa, 1.0));
    EXPECT_DOUBLE_EQ(zero.g, real_space_self(xa, 1.0));
  }
}

TEST(PseRealSpace, SmallXiTendsToRpy) {
  // xi -> 0: M_r -> RPY; the wave part removed is O(xi a) (M_w,free(0) ~ xi a * const).
  const double xa = 0.02;
  for (double r : {0.5, 1.5, 3.0, 6.0}) {
    const FG v = real_space_fg(r, xa, 1.0);
    const double f = r > 2 ? 0.75 / r + 0.5 / (r * r * r) : 1 - 9 * r / 32;
    const double g = r > 2 ? 1.5 / r - 1.0 / (r * r * r) : 1 - 3 * r / 16;
    EXPECT_NEAR(v.f, f, 3 * xa) << r;
    EXPECT_NEAR(v.g, g, 3 * xa) << r;
  }
}

TEST(PseRealSpace, CutoffBoundsTheEnvelope) {
  for (double xa : {0.5, 1.0, 2.0}) {
    for (double eps : {1e-3, 1e-6}) {
      const double rc = real_space_cutoff(eps, xa, 1.0);
      double worst = 0.0;
      for (double r = rc; r < rc + 10.0 / xa; r += 0.001 / xa) {
        const FG v = real_space_fg(r, xa, 1.0);
        worst = std::max({worst, std::abs(v.f), std::abs(v.g)});
      }
      EXPECT_LE(worst, eps * 1.001) << "xi a = " << xa << ", eps = " << eps;
      // and it is not wastefully large: something just inside exceeds eps (within 0.05/xi)
      double inside = 0.0;
      for (double r = rc - 0.05 / xa; r < rc; r += 0.001 / xa) {
        const FG v = real_space_fg(r, xa, 1.0);
        inside = std::max({inside, std::abs(v.f), std::abs(v.g)});
      }
      EXPECT_GT(inside, 0.5 * eps);
    }
  }
}

TEST(PseRealSpace, TableMeetsItsTolerance) {
  for (double xa : {0.5, 1.0}) {
    for (double eps_t : {1e-4, 1e-7}) {
      const double rc = real_space_cutoff(eps_t, xa, 1.0);
      const PseRealSpaceTable t(xa, 1.0, rc, eps_t);
      double worst = 0.0;
      for (double r = 0.0; r < rc; r += 0.0007) {
        const FG e = real_space_fg(r, xa, 1.0), v = t(r);
        worst = std::max({worst, std::abs(e.f - v.f), std::abs(e.g - v.g)});
      }
      EXPECT_LE(worst, 1.5 * eps_t) << xa << " " << eps_t;  // midpoint check + curvature between samples
    }
  }
}

// A huge xi (xi a = 1e300, e.g. PseRpy(box, xi=1e300)) made the cutoff's sampling step 0.01 / xi
// vanish next to r, and the loop never ended: it is refused, naming xi; xi a of order 1 is not.
TEST(PseRealSpace, HugeXiIsRefusedNotLoopedOn) {
  EXPECT_THROW((void)real_space_cutoff(1e-4, 1e300, 1.0), rpyfmm::Error);
  EXPECT_THROW((void)real_space_cutoff(1e-4, 1e5, 1.0), rpyfmm::Error);
  try {
    (void)real_space_cutoff(1e-4, 1e300, 0.5);
  } catch (const rpyfmm::Error& e) {
    EXPECT_NE(std::string(e.what()).find("xi = 1e+300 (xi a = 5e+299) is too large"), std::string::npos) << e.what();
  }
  EXPECT_GT(real_space_cutoff(1e-4, 8.0, 1.0), 0.0);
}
