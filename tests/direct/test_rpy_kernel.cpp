// RPY pair formulas (rpy_kernel.hpp) against closed forms written here
// independently, and their structural properties (docs/theory/rpy.md).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"

using namespace rpyfmm::rpy;
constexpr double pi = std::numbers::pi;

namespace {
double rel(double a, double b) {
  return std::abs(a - b) / std::max(std::abs(b), 1e-300);
}
}  // namespace

// Rotne & Prager (1969) / Yamakawa (1970) in the textbook form, two spheres of
// radius a at distance r, in units of the Stokes mobility mu0 = 1/(6 pi eta a):
//   along the line of centres  r >= 2a: 3a/(2r) - a^3/r^3      r < 2a: 1 - 3r/(16a)
//   across it                  r >= 2a: 3a/(4r) + a^3/(2r^3)   r < 2a: 1 - 9r/(32a)
TEST(RpyKernel, TwoSpheresAlongAndAcrossTheLineOfCentres) {
  const double a = 0.7, eta = 1.3;
  const double mu0 = 1.0 / (6 * pi * eta * a);
  for (double r : {0.3, 1.0, 1.39, 1.4, 1.41, 2.5, 7.0, 40.0}) {
    const double along = r >= 2 * a ? 1.5 * a / r - std::pow(a / r, 3) : 1 - 3 * r / (16 * a);
    const double across = r >= 2 * a ? 0.75 * a / r + 0.5 * std::pow(a / r, 3) : 1 - 9 * r / (32 * a);
    const double d[3] = {r, 0, 0};  // along x
    double m[9];
    rpy_tensor(d, a, a, eta, m);
    // tolerance: a few ulps of the O(1) quantities compared
    EXPECT_NEAR(m[0] / mu0, along, 1e-14) << "r = " << r;
    EXPECT_NEAR(m[4] / mu0, across, 1e-14) << "r = " << r;
    EXPECT_NEAR(m[8] / mu0, across, 1e-14) << "r = " << r;
    EXPECT_EQ(m[1], 0.0);
    EXPECT_EQ(m[5], 0.0);
  }
}

TEST(RpyKernel, SelfTermAndCoincidentSpheres) {
  EXPECT_DOUBLE_EQ(rpy_self(2.0), 1.0 / (12 * pi));
  const auto s = rpy_scalars(0.0, 1.0, 1.0);
  EXPECT_DOUBLE_EQ(s.f, 1.0 / (6 * pi));
  EXPECT_EQ(s.g, 0.0);
  const auto e = rpy_scalars_equal(0.0, 1.0);
  EXPECT_DOUBLE_EQ(e.f, 1.0 / (6 * pi));
  EXPECT_EQ(e.g, 0.0);
  // one sphere inside the other: 1/(6 pi max(ai, aj)) (Zuk et al. 2014)
  const auto in = rpy_scalars(0.4, 1.0, 3.0);
  EXPECT_DOUBLE_EQ(in.f, 1.0 / (18 * pi));
  EXPECT_EQ(in.g, 0.0);
  // tiny but positive separation stays finite (no r^3 overflow)
  for (double r : {1e-300, 1e-200, 1e-160, 1e-100}) {
    const auto t = rpy_scalars(r, 1.0, 1.0);
    EXPECT_TRUE(std::isfinite(t.f) && std::isfinite(t.g)) << r;
    EXPECT_NEAR(t.f, 1.0 / (6 * pi), 1e-15);
  }
}

TEST(RpyKernel, DifferentRadiiReduceToEqualRadii) {
  for (double a : {0.1, 1.0, 3.0}) {
    for (double x = 0.0; x < 6.0; x += 0.0137) {
      const double r = x * a;
      const auto g = rpy_scalars(r, a, a);
      const auto e = rpy_scalars_equal(r, a);
      // same closed form rearranged: agreement to rounding (~1e-15 relative of f)
      EXPECT_NEAR(g.f, e.f, 1e-14 * std::abs(e.f)) << "a=" << a << " r=" << r;
      EXPECT_NEAR(g.g, e.g, 1e-14 * std::abs(e.f)) << "a=" << a << " r=" << r;
    }
  }
}

// Far-field and partial-overlap forms of Zuk et al. written here from the paper's
// full-r^3 expression (not the rearranged one of the header).
TEST(RpyKernel, DifferentRadiiClosedForms) {
  const double ai = 1.0, aj = 2.5;
  for (double r : {1.6, 2.0, 3.0, 3.5, 4.0, 9.0}) {
    const auto s = rpy_scalars(r, ai, aj);
    double f, g;
    if (r > ai + aj) {
      f = (1 + (ai * ai + aj * aj) / (3 * r * r)) / (8 * pi * r);
      g = (1 - (ai * ai + aj * aj) / (r * r)) / (8 * pi * r);
    } else {
      const double d2 = (ai - aj) * (ai - aj);
      f = (16 * r * r * r * (ai + aj) - std::pow(d2 + 3 * r * r, 2)) / (32 * r * r * r) / (6 * pi * ai * aj);
      g = 3 * std::pow(d2 - r * r, 2) / (32 * r * r * r) / (6 * pi * ai * aj);
    }
    EXPECT_LT(rel(s.f, f), 1e-13) << r;
    EXPECT_NEAR(s.g, g, 1e-13 * std::abs(f)) << r;
  }
}

// Continuity at r = ai + aj and r = |ai - aj|: the jump across r0 +- h must be
// O(h) (tolerance 1e-6 relative for h = 1e-9; a real jump would be O(1)).
TEST(RpyKernel, ContinuousAtContactAndInclusion) {
  const double h = 1e-9;
  for (auto [ai, aj] : {std::pair{1.0, 1.0}, std::pair{1.0, 2.0}, std::pair{0.3, 1.7}, std::pair{2.0, 0.5}}) {
    std::vector<double> r0 = {ai + aj};
    if (ai != aj) r0.push_back(std::abs(ai - aj));
    for (double r : r0) {
      const auto lo = rpy_scalars(r - h, ai, aj), at = rpy_scalars(r, ai, aj), hi = rpy_scalars(r + h, ai, aj);
      const double scale = std::abs(at.f);
      EXPECT_NEAR(lo.f, hi.f, 1e-6 * scale) << ai << " " << aj << " r=" << r;
      EXPECT_NEAR(lo.g, hi.g, 1e-6 * scale) << ai << " " << aj << " r=" << r;
      EXPECT_NEAR(at.f, hi.f, 1e-6 * scale);
      EXPECT_NEAR(at.g, hi.g, 1e-6 * scale);
    }
    if (ai == aj) {
      const auto lo = rpy_scalars_equal(2 * ai - h, ai), hi = rpy_scalars_equal(2 * ai + h, ai);
      EXPECT_NEAR(lo.f, hi.f, 1e-6 * std::abs(hi.f));
      EXPECT_NEAR(lo.g, hi.g, 1e-6 * std::abs(hi.f));
    }
  }
}

TEST(RpyKernel, TensorSymmetricAndPairAddConsistent) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-2.0, 2.0), ra(0.2, 1.5);
  for (int t = 0; t < 200; ++t) {
    const double d[3] = {u(rng), u(rng), u(rng)};
    const double md[3] = {-d[0], -d[1], -d[2]};
    const double ai = ra(rng), aj = ra(rng), eta = 0.8;
    double m[9], mt[9];
    rpy_tensor(d, ai, aj, eta, m);
    rpy_tensor(md, aj, ai, eta, mt);  // M_ji
    const double f[3] = {u(rng), u(rng), u(rng)};
    double uij[3] = {0, 0, 0}, ueq[3] = {0, 0, 0};
    rpy_pair_add(d, ai, aj, 1.0 / eta, f, uij);
    rpy_pair_add_equal(d, ai, 1.0 / eta, f, ueq);
    double ueq_ref[3] = {0, 0, 0};
    rpy_pair_add(d, ai, ai, 1.0 / eta, f, ueq_ref);
    for (int a = 0; a < 3; ++a) {
      double mf = 0;
      for (int b = 0; b < 3; ++b) {
        EXPECT_EQ(m[3 * a + b], m[3 * b + a]);                            // M_ij symmetric block
        EXPECT_NEAR(m[3 * a + b], mt[3 * b + a], 1e-15 * m[0] + 1e-300);  // M_ij = M_ji^T
        mf += m[3 * a + b] * f[b];
      }
      EXPECT_NEAR(uij[a], mf, 1e-14 * (std::abs(mf) + m[0]));
      EXPECT_NEAR(ueq[a], ueq_ref[a], 1e-14 * (std::abs(ueq_ref[a]) + m[0]));
    }
  }
}

// The whole 3N x 3N matrix is SPD for any configuration, overlapping and
// polydisperse included (Zuk et al. 2014). Dense eigenvalues with Eigen.
TEST(RpyKernel, DenseMatrixSpdForOverlappingPolydisperse) {
  for (unsigned seed : {1u, 2u, 3u}) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> box(0.0, 3.0), ra(0.3, 1.5);
    const std::size_t n = 40;  // packed densely: many overlaps, some inclusions
    std::vector<double> x(3 * n), a(n);
    for (auto& v : x) v = box(rng);
    for (auto& v : a) v = ra(rng);
    x[3] = x[0];  // coincident pair
    x[4] = x[1];
    x[5] = x[2];
    DirectRpy op;
    op.set_positions(x, a);
    const auto dense = op.assemble_dense();
    Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> m(dense.data(), 3 * n,
                                                                                               3 * n);
    EXPECT_LT((m - m.transpose()).cwiseAbs().maxCoeff(), 1e-15);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(m);
    const double lmin = es.eigenvalues().minCoeff();
    EXPECT_GT(lmin, 1e-8 * es.eigenvalues().maxCoeff()) << "seed " << seed;
  }
}
