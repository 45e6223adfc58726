// DirectRpy against a plain double loop written here from docs/theory/rpy.md, plus
// block products, thread-count independence and input validation.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "simd_levels.hpp"

using rpyfmm::Error;
using rpyfmm::ErrorCode;
using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::Geometry;
constexpr double pi = std::numbers::pi;

namespace {

// Reference: U_i = sum_j M_ij F_j, branches exactly as in docs/theory/rpy.md.
std::vector<double> reference(const std::vector<double>& x, const std::vector<double>& a, double eta,
                              const std::vector<double>& F) {
  const std::size_t n = a.size();
  std::vector<double> U(3 * n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j) {
      const double ai = a[i], aj = a[j];
      double d[3] = {x[3 * i] - x[3 * j], x[3 * i + 1] - x[3 * j + 1], x[3 * i + 2] - x[3 * j + 2]};
      const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      double cI, cR;  // M = cI I + cR rhat rhat
      if (i == j) {
        cI = 1 / (6 * pi * eta * ai);
        cR = 0;
      } else if (r > ai + aj) {
        const double s2 = ai * ai + aj * aj;
        cI = (1 + s2 / (3 * r * r)) / (8 * pi * eta * r);
        cR = (1 - s2 / (r * r)) / (8 * pi * eta * r);
      } else if (r > std::abs(ai - aj)) {
        const double d2 = (ai - aj) * (ai - aj);
        cI = (16 * r * r * r * (ai + aj) - std::pow(d2 + 3 * r * r, 2)) / (32 * r * r * r) / (6 * pi * eta * ai * aj);
        cR = 3 * std::pow(d2 - r * r, 2) / (32 * r * r * r) / (6 * pi * eta * ai * aj);
      } else {
        cI = 1 / (6 * pi * eta * std::max(ai, aj));
        cR = 0;
      }
      double rh[3] = {0, 0, 0};
      if (r > 0)
        for (int c = 0; c < 3; ++c) rh[c] = d[c] / r;
      const double rf = rh[0] * F[3 * j] + rh[1] * F[3 * j + 1] + rh[2] * F[3 * j + 2];
      for (int c = 0; c < 3; ++c) U[3 * i + c] += cI * F[3 * j + c] + cR * rh[c] * rf;
    }
  }
  return U;
}

struct Config {
  std::vector<double> x, a, F;
};

Config random_config(std::size_t n, double box, double amin, double amax, unsigned seed, std::size_t nrhs = 1) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(0.0, box), ua(amin, amax), uf(-1.0, 1.0);
  Config c;
  c.x.resize(3 * n);
  c.a.resize(n);
  c.F.resize(3 * n * nrhs);
  for (auto& v : c.x) v = ux(rng);
  for (auto& v : c.a) v = ua(rng);
  for (auto& v : c.F) v = uf(rng);
  return c;
}

double max_rel_error(const std::vector<double>& u, const std::vector<double>& ref) {
  double num = 0, den = 0;
  for (std::size_t i = 0; i < u.size(); ++i) {
    num = std::max(num, std::abs(u[i] - ref[i]));
    den = std::max(den, std::abs(ref[i]));
  }
  return num / den;
}

}  // namespace

// Tolerance 1e-13 relative to max |U|: same formulas, different summation order
// and rearranged overlap expressions (rounding only).
// Every instruction-set level the machine has (scalar, AVX2, AVX-512).
class DirectRpyPaths : public rpyfmm::test::SimdLevelTest {};
INSTANTIATE_TEST_SUITE_P(Kernels, DirectRpyPaths, ::testing::ValuesIn(rpyfmm::test::all_simd_levels()),
                         rpyfmm::test::simd_level_param_name);

TEST_P(DirectRpyPaths, MatchesPlainLoopEqualRadii) {
  for (double box : {4.0, 30.0}) {  // dense (many overlaps) and dilute
    auto c = random_config(150, box, 0.5, 0.5, 11);
    std::fill(c.a.begin(), c.a.end(), 0.5);
    DirectRpy op(Geometry::open(), 1.7);
    op.set_positions(c.x, 0.5);
    EXPECT_TRUE(op.equal_radii());
    std::vector<double> u(c.F.size());
    op.apply(c.F, u);
    EXPECT_LT(max_rel_error(u, reference(c.x, c.a, 1.7, c.F)), 1e-13) << "box " << box;
  }
}

TEST_P(DirectRpyPaths, MatchesPlainLoopPolydisperse) {
  for (double box : {3.0, 25.0}) {
    auto c = random_config(150, box, 0.1, 1.2, 12);
    c.x[6] = c.x[0];  // particle 2 coincides with particle 0
    c.x[7] = c.x[1];
    c.x[8] = c.x[2];
    DirectRpy op(Geometry::open(), 0.3);
    op.set_positions(c.x, c.a);
    EXPECT_FALSE(op.equal_radii());
    std::vector<double> u(c.F.size());
    op.apply(c.F, u);
    EXPECT_LT(max_rel_error(u, reference(c.x, c.a, 0.3, c.F)), 1e-13) << "box " << box;
  }
}

TEST_P(DirectRpyPaths, BlockEqualsSeparateApplies) {
  const std::size_t n = 300, nrhs = 3;  // n > internal block size
  auto c = random_config(n, 10.0, 0.2, 0.6, 13, nrhs);
  DirectRpy op;
  op.set_positions(c.x, c.a);
  std::vector<double> ub(3 * n * nrhs);
  op.apply_block(c.F, ub, nrhs);
  for (std::size_t k = 0; k < nrhs; ++k) {
    std::vector<double> f(c.F.begin() + 3 * n * k, c.F.begin() + 3 * n * (k + 1)), u(3 * n);
    op.apply(f, u);
    for (std::size_t i = 0; i < 3 * n; ++i) EXPECT_EQ(u[i], ub[3 * n * k + i]);
  }
}

// apply_rows (what rpyfmm::mpi splits between ranks): any range of rows equals those rows of
// apply() bit for bit, at every kernel level, with equal and different radii, and with forces
// large enough to take the load scaling; out-of-range rows and wrong sizes are refused.
TEST_P(DirectRpyPaths, RowsEqualTheFullProductsRows) {
  const std::size_t n = 300;
  for (const double radius_spread : {0.0, 0.4}) {
    auto c = random_config(n, 10.0, 0.5, 0.5 + radius_spread, 17, 1);
    for (const double scale : {1.0, 1e300}) {
      std::vector<double> f = c.F;
      for (double& v : f) v *= scale;
      DirectRpy op;
      op.set_positions(c.x, c.a);
      std::vector<double> full(3 * n);
      op.apply(f, full);
      for (const auto& [first, count] :
           {std::pair<std::size_t, std::size_t>{0, n}, {0, 1}, {37, 260}, {299, 1}, {n, 0}, {128, 128}}) {
        std::vector<double> rows(3 * count);
        op.apply_rows(first, count, f, rows);
        for (std::size_t q = 0; q < 3 * count; ++q) ASSERT_EQ(rows[q], full[3 * first + q]) << first << " " << q;
      }
      std::vector<double> rows(3);
      EXPECT_THROW(op.apply_rows(n, 1, f, rows), Error);
      EXPECT_THROW(op.apply_rows(0, 2, f, rows), Error);  // 3 velocities for 2 rows
    }
  }
}

TEST(DirectRpy, ResultIndependentOfThreadCount) {
  auto c = random_config(500, 12.0, 0.3, 0.3, 14);
  DirectRpy op;
  op.set_positions(c.x, 0.3);
  std::vector<double> u1(c.F.size()), u2(c.F.size());
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  op.apply(c.F, u1);
  omp_set_num_threads(3);
  op.apply(c.F, u2);
  omp_set_num_threads(saved);
  EXPECT_EQ(u1, u2);  // bitwise: each velocity is summed by one thread in a fixed order
}

TEST(DirectRpy, SingleParticleAndViscosityScaling) {
  DirectRpy op(Geometry::open(), 2.0);
  op.set_positions(std::vector<double>{1, 2, 3}, 0.5);
  std::vector<double> f = {1, -2, 3}, u(3);
  op.apply(f, u);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(u[c], f[c] / (6 * pi * 2.0 * 0.5), 1e-15);
  EXPECT_EQ(op.name(), "direct");
}

TEST(DirectRpy, RejectsBadInput) {
  // periodic geometry: not supported, with a message that says so
  try {
    DirectRpy p(Geometry::periodic(10.0));
    FAIL() << "periodic accepted";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::not_supported);
    EXPECT_NE(std::string(e.what()).find("periodic"), std::string::npos);
  }
  EXPECT_THROW(DirectRpy(Geometry::open(), 0.0), Error);
  EXPECT_THROW(DirectRpy(Geometry::open(), -1.0), Error);
  EXPECT_THROW(DirectRpy(Geometry::open(), NAN), Error);
  DirectRpy op;
  std::vector<double> f(6, 1.0), u(6);
  EXPECT_THROW(op.apply(f, u), Error);  // no positions
  EXPECT_THROW(op.set_positions(std::vector<double>{}, 1.0), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1}, 1.0), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1, NAN, 0}, 1.0), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1, INFINITY, 0}, 1.0), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1, 0, 0}, 0.0), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1, 0, 0}, std::vector<double>{1.0, -1.0}), Error);
  EXPECT_THROW(op.set_positions(std::vector<double>{0, 0, 0, 1, 0, 0}, std::vector<double>{1.0}), Error);
  op.set_positions(std::vector<double>{0, 0, 0, 3, 0, 0}, 1.0);
  EXPECT_THROW(op.apply(std::vector<double>(5, 1.0), u), Error);
  std::vector<double> u5(5);
  EXPECT_THROW(op.apply(f, u5), Error);
  f[4] = NAN;
  EXPECT_THROW(op.apply(f, u), Error);
  f[4] = 1.0;
  EXPECT_THROW(op.apply_block(f, u, 0), Error);
  EXPECT_NO_THROW(op.apply(f, u));
}

// Extreme separations: tiny ones stay finite; large ones are evaluated in units of the
// suspension's size (no r^2 overflow), up to the limit of 2^300 (~2e90) on the ratio of size to
// radius shared with FmmRpy, beyond which they are refused naming the particle. Both code paths.
TEST_P(DirectRpyPaths, ExtremeSeparationsStayFiniteOrAreRefused) {
  for (double d : {1e-170, 1e-150, 1e40, 1e80, 1e150, 1e300}) {
    const std::vector<double> x = {0, 0, 0, d, 0, 0, 0, 2 * d, 0};
    for (bool poly : {false, true}) {
      DirectRpy op;
      const std::vector<double> a = poly ? std::vector<double>{1.0, 2.0, 0.5} : std::vector<double>(3, 1.0);
      if (d > 1e90) {
        try {
          op.set_positions(x, a);
          ADD_FAILURE() << "accepted radius 1 at separation " << d;
        } catch (const Error& e) {
          EXPECT_NE(std::string(e.what()).find("DirectRpy::set_positions: radius of particle"), std::string::npos)
              << e.what();
        }
        continue;
      }
      op.set_positions(x, a);
      std::vector<double> f = {1, 0, 0, 0, 1, 0, 0, 0, 1}, u(9);
      op.apply(f, u);
      for (double v : u) EXPECT_TRUE(std::isfinite(v)) << d;
      if (d >= 1e40) {  // far apart: the self term dominates (others < 1e-40)
        const double a0 = 1.0;
        EXPECT_NEAR(u[0], 1 / (6 * pi * a0), 1e-15);
      }
    }
  }
}

// Forces near 1e308 on spheres of radius 1 give velocities near 5e306: their pair terms
// d (d . F) overflowed and U was Inf or NaN; forces are now applied in units of their size. Where
// M F itself overflows (radius 1e-3), the product is refused with numerical_failure naming the entry,
// never returned as Inf or NaN.
TEST(DirectRpy, HugeForcesGiveTheScaledProductOrAreRefused) {
  DirectRpy op;
  op.set_positions(std::vector<double>{0, 0, 0, 3, 0, 0}, 1.0);
  std::vector<double> u(6), u1(6);
  op.apply(std::vector<double>{1, 0.5, 0, 1, 0, -0.25}, u1);
  // Powers of two: the products are the plain one's exactly.
  for (int e : {1020, 700, -700, -1000}) {
    const double s = std::ldexp(1.0, e);
    op.apply(std::vector<double>{s, 0.5 * s, 0, s, 0, -0.25 * s}, u);
    for (int i = 0; i < 6; ++i) EXPECT_EQ(std::ldexp(u[i], -e), u1[i]) << e << " " << i;
  }
  op.set_positions(std::vector<double>{0, 0, 0, 3, 0, 0}, 1e-3);
  try {
    op.apply(std::vector<double>{1e308, 0, 0, 1e308, 0, 0}, u);
    ADD_FAILURE() << "returned " << u[0];
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::numerical_failure);
    EXPECT_NE(std::string(e.what()).find("DirectRpy::apply: velocities entry (0, 0) is infinite"), std::string::npos)
        << e.what();
  }
}
