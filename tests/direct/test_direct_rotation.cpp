// DirectRpy's grand mobility with rotation, [U; W] = M [F; T], against independent references:
// - the closed forms written out here (far field: the stokeslet's half vorticity, the rotlet and
//   its half vorticity; equal overlapping spheres: Wajnryb, Mizerski, Zuk & Szymczak 2013);
// - the definition itself: the Oseen tensor averaged over both spheres' surfaces with the
//   rigid-motion weights (docs/theory/rpy.md, "Rotation"), by quadrature, in every regime (far,
//   touching, partial overlap with equal and different radii, one sphere inside the other);
// - dense linear algebra: the 6N x 6N matrix is symmetric and positive definite.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"
#include "translation_only_operator.hpp"

using rpyfmm::Error;
using rpyfmm::ErrorCode;
using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::Geometry;

namespace {

constexpr double pi = std::numbers::pi;
using Vec = std::array<double, 3>;
using Block = Eigen::Matrix<double, 6, 6>;

Vec cross(const Vec& a, const Vec& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

/// The 6x6 block (U_0, W_0) from (F_1, T_1) of two spheres, column by column through the operator.
Block operator_block(const Vec& x0, const Vec& x1, double a0, double a1, double eta = 1.0) {
  DirectRpy op(Geometry::open(), eta);
  op.set_positions(std::vector<double>{x0[0], x0[1], x0[2], x1[0], x1[1], x1[2]}, std::vector<double>{a0, a1});
  Block b;
  for (int col = 0; col < 6; ++col) {
    std::vector<double> f(6, 0.0), t(6, 0.0), u(6), w(6);
    (col < 3 ? f : t)[3 + col % 3] = 1.0;
    op.apply(f, t, u, w);
    for (int c = 0; c < 3; ++c) b(c, col) = u[c], b(3 + c, col) = w[c];
  }
  return b;
}

/// Points of the Fibonacci lattice on the unit sphere (equal areas), rotated by `twist`.
std::vector<Vec> fibonacci_sphere(int m, double twist) {
  std::vector<Vec> p(m);
  const double golden = pi * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < m; ++k) {
    const double z = 1.0 - 2.0 * (k + 0.5) / m, s = std::sqrt(1.0 - z * z), phi = golden * (k + 0.5) + twist;
    p[k] = {s * std::cos(phi), s * std::sin(phi), z};
  }
  return p;
}

/// The generalized RPY block by its definition (viscosity 1): the source sphere 1 carries the force
/// density F / (4 pi a1^2) or, for a torque, (3 / (8 pi a1^3)) T x n; its Oseen flow u is averaged over
/// sphere 0: U_0 = <u>, W_0 = (3 / (2 a0)) <n x u>. Midpoint quadrature on m lattice points each.
Block quadrature_block(const Vec& x0, const Vec& x1, double a0, double a1, int m) {
  const auto n0 = fibonacci_sphere(m, 0.3), n1 = fibonacci_sphere(m, 1.1);
  Block b = Block::Zero();
  for (int col = 0; col < 6; ++col) {
    Vec load{};
    load[col % 3] = 1.0;
    std::vector<Vec> f(m);  // point forces of the source's density, weight 1/m each
    for (int q = 0; q < m; ++q) {
      const Vec tn = cross(load, n1[q]);
      for (int c = 0; c < 3; ++c) f[q][c] = (col < 3 ? load[c] : 1.5 / a1 * tn[c]) / m;
    }
    Vec u_mean{}, w_mean{};
    for (int p = 0; p < m; ++p) {
      Vec u{};
      for (int q = 0; q < m; ++q) {
        Vec d;
        for (int c = 0; c < 3; ++c) d[c] = (x0[c] + a0 * n0[p][c]) - (x1[c] + a1 * n1[q][c]);
        const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2], inv_r = 1.0 / std::sqrt(r2);
        const double df = (d[0] * f[q][0] + d[1] * f[q][1] + d[2] * f[q][2]) * inv_r * inv_r;
        for (int c = 0; c < 3; ++c) u[c] += inv_r * (f[q][c] + df * d[c]);
      }
      for (int c = 0; c < 3; ++c) u[c] /= 8.0 * pi;
      const Vec nu = cross(n0[p], u);
      for (int c = 0; c < 3; ++c) u_mean[c] += u[c] / m, w_mean[c] += 1.5 / a0 * nu[c] / m;
    }
    for (int c = 0; c < 3; ++c) b(c, col) = u_mean[c], b(3 + c, col) = w_mean[c];
  }
  return b;
}

/// The closed-form block of equal spheres (radius a) at d = x0 - x1, written from the far-field
/// singularities and the overlap forms of Wajnryb et al. 2013 (independent of the kernel header).
Block closed_form_equal(const Vec& d, double a) {
  const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  const Eigen::Vector3d e(d[0] / r, d[1] / r, d[2] / r);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity(), E = e * e.transpose();
  Eigen::Matrix3d ex;  // [e x]: ex v = e x v
  ex << 0, -e.z(), e.y(), e.z(), 0, -e.x(), -e.y(), e.x(), 0;
  Block b;
  if (r > 2 * a) {
    const double s = 2 * a * a / (r * r);
    b.topLeftCorner<3, 3>() = ((1 + s / 3) * I + (1 - s) * E) / (8 * pi * r);
    b.topRightCorner<3, 3>() = -ex / (8 * pi * r * r);    // U = (T x e) / (8 pi r^2): the rotlet
    b.bottomLeftCorner<3, 3>() = -ex / (8 * pi * r * r);  // W = (F x e) / (8 pi r^2): half the vorticity
    b.bottomRightCorner<3, 3>() = -(I - 3 * E) / (16 * pi * r * r * r);
  } else {
    const double s = r / a;
    b.topLeftCorner<3, 3>() = ((1 - 9 * s / 32) * I + (3 * s / 32) * E) / (6 * pi * a);
    b.topRightCorner<3, 3>() = -(s * (1 - 3 * s / 8) / (16 * pi * a * a)) * ex;
    b.bottomLeftCorner<3, 3>() = b.topRightCorner<3, 3>();
    b.bottomRightCorner<3, 3>() =
        ((1 - 27 * s / 32 + 5 * s * s * s / 64) * I + (9 * s / 32 - 3 * s * s * s / 64) * E) / (8 * pi * a * a * a);
  }
  return b;
}

double max_abs(const Block& b) {
  return b.cwiseAbs().maxCoeff();
}

}  // namespace

// Equal spheres, term by term against the closed forms: far apart, touching, overlapping, and
// nearly coincident; viscosity 2 divides every block.
TEST(DirectRotation, EqualSpheresMatchTheClosedForms) {
  const Vec x1{0.3, -0.2, 0.5};
  const Vec dir{0.48, -0.6, 0.64};  // unit
  for (double r : {50.0, 4.5, 2.0, 1.3, 0.4, 1e-6}) {
    const Vec x0{x1[0] + r * dir[0], x1[1] + r * dir[1], x1[2] + r * dir[2]};
    const Block got = operator_block(x0, x1, 1.0, 1.0, 2.0);
    const Block want = closed_form_equal({r * dir[0], r * dir[1], r * dir[2]}, 1.0) / 2.0;
    EXPECT_LE(max_abs(got - want), 1e-14 * max_abs(want)) << "r = " << r;
  }
}

// Every regime against the definition by quadrature (3000 lattice points per sphere). Its error,
// measured against the closed forms, stays below 7e-5 of the block's largest entry on these
// configurations (the integrand is near-singular where the two surfaces meet); 2e-4 bounds it.
TEST(DirectRotation, EveryRegimeMatchesTheSurfaceAverageDefinition) {
  struct Pair {
    double a0, a1, r;
    const char* regime;
  };
  for (const Pair& p : {Pair{1.0, 2.0, 3.3, "far, different radii"}, Pair{1.0, 1.0, 2.0, "touching"},
                        Pair{1.0, 1.0, 1.5, "overlapping, equal"}, Pair{1.0, 2.0, 2.0, "overlapping, different"},
                        Pair{1.5, 0.7, 1.2, "overlapping, larger target"}, Pair{0.5, 2.0, 1.0, "target inside source"},
                        Pair{2.0, 0.5, 1.0, "source inside target"}}) {
    const Vec x0{0.1, 0.2, 0.3}, dir{0.3 / 0.98995, -0.5 / 0.98995, 0.8 / 0.98995};
    const Vec x1{x0[0] - p.r * dir[0], x0[1] - p.r * dir[1], x0[2] - p.r * dir[2]};
    const Block got = operator_block(x0, x1, p.a0, p.a1);
    const Block want = quadrature_block(x0, x1, p.a0, p.a1, 3000);
    EXPECT_LE(max_abs(got - want), 2e-4 * max_abs(want)) << p.regime;
  }
}

// Each coefficient is continuous where the regimes meet (r = ai + aj and r = |ai - aj|), and equal
// radii are the limit of different ones.
TEST(DirectRotation, RegimesJoinContinuously) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> radius(0.2, 3.0);
  for (int k = 0; k < 200; ++k) {
    const double ai = radius(rng), aj = radius(rng);
    const double scale = rpyfmm::rpy::rpy_rotation_self(std::min(ai, aj)) * std::min(ai, aj);  // 1/(8 pi a^2)
    for (double rb : {ai + aj, std::abs(ai - aj)}) {
      const auto lo = rpyfmm::rpy::rpy_rotation_scalars(rb * (1 - 1e-12), ai, aj);
      const auto hi = rpyfmm::rpy::rpy_rotation_scalars(rb * (1 + 1e-12), ai, aj);
      EXPECT_NEAR(lo.ut, hi.ut, 1e-9 * scale) << ai << " " << aj << " " << rb;
      EXPECT_NEAR(lo.wf, hi.wf, 1e-9 * scale) << ai << " " << aj << " " << rb;
      EXPECT_NEAR(lo.h, hi.h, 1e-9 * scale / std::min(ai, aj)) << ai << " " << aj << " " << rb;
      EXPECT_NEAR(lo.k, hi.k, 1e-9 * scale / std::min(ai, aj)) << ai << " " << aj << " " << rb;
    }
  }
}

// The 6N x 6N matrix on dense, heavily overlapping suspensions of mixed radii (some spheres
// inside others): exactly symmetric up to rounding, and positive definite.
TEST(DirectRotation, GrandMatrixIsSymmetricPositiveDefinite) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> pos(0.0, 3.0), radius(0.2, 1.5);
  for (int trial = 0; trial < 10; ++trial) {
    const int n = 20;
    std::vector<double> x(3 * n), a(n);
    for (double& v : x) v = pos(rng);
    for (double& v : a) v = radius(rng);
    DirectRpy op;
    op.set_positions(x, a);
    Eigen::MatrixXd M(6 * n, 6 * n);
    for (int col = 0; col < 6 * n; ++col) {
      std::vector<double> f(3 * n, 0.0), t(3 * n, 0.0), u(3 * n), w(3 * n);
      (col % 6 < 3 ? f : t)[3 * (col / 6) + col % 3] = 1.0;
      op.apply(f, t, u, w);
      for (int i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) M(6 * i + c, col) = u[3 * i + c], M(6 * i + 3 + c, col) = w[3 * i + c];
    }
    EXPECT_LE((M - M.transpose()).cwiseAbs().maxCoeff(), 1e-15 * M.cwiseAbs().maxCoeff()) << trial;
    const double smallest = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (M + M.transpose())).eigenvalues()(0);
    EXPECT_GT(smallest, 0.0) << trial;
  }
}

// Without torques, U is the translational product (the rotation path evaluates the same pair
// formulas in branching form: equal to rounding); results do not depend on the thread count.
TEST(DirectRotation, ForcesAloneGiveTheTranslationalProductOnAnyThreadCount) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> pos(0.0, 12.0), radius(0.3, 1.2), load(-1.0, 1.0);
  const int n = 300;
  std::vector<double> x(3 * n), a(n), f(3 * n), t(3 * n);
  for (double& v : x) v = pos(rng);
  for (double& v : a) v = radius(rng);
  for (double& v : f) v = load(rng);
  for (double& v : t) v = load(rng);
  DirectRpy op;
  op.set_positions(x, a);
  std::vector<double> u0(3 * n), u(3 * n), w(3 * n), zero(3 * n, 0.0);
  op.apply(f, u0);
  op.apply(f, zero, u, w);
  // Both sum the same 300 pair terms, each below 1/(6 pi 0.3) ~ 0.18 per unit force, in other
  // associations (vectorized blocks against one loop): rounding <= 300 x 2^-52 x 0.18 ~ 1.2e-14.
  for (int i = 0; i < 3 * n; ++i) EXPECT_NEAR(u[i], u0[i], 2e-14) << i;
  const int threads = omp_get_max_threads();
  std::vector<double> u1(3 * n), w1(3 * n), u2(3 * n), w2(3 * n);
  omp_set_num_threads(1);
  op.apply(f, t, u1, w1);
  omp_set_num_threads(2);
  op.apply(f, t, u2, w2);
  omp_set_num_threads(threads);
  EXPECT_EQ(u1, u2);
  EXPECT_EQ(w1, w2);
}

// Suspensions at extreme length scales (units of their size, length_units.hpp): the blocks scale as
// 1/L (UF), 1/L^2 (UT, WF) and 1/L^3 (WT), exactly for powers of two.
TEST(DirectRotation, ExtremeScalesGiveTheScaledBlocks) {
  const Vec x0{0.25, 0.5, -0.75}, x1{1.5, -0.25, 0.5};
  const Block plain = operator_block(x0, x1, 0.5, 0.75);
  for (int e : {300, -300}) {
    const double s = std::ldexp(1.0, e);
    const Block scaled =
        operator_block({s * x0[0], s * x0[1], s * x0[2]}, {s * x1[0], s * x1[1], s * x1[2]}, s * 0.5, s * 0.75);
    for (int row = 0; row < 6; ++row)
      for (int col = 0; col < 6; ++col) {
        const int power = 1 + (row >= 3) + (col >= 3);
        EXPECT_EQ(std::ldexp(scaled(row, col), power * e), plain(row, col)) << e << " " << row << " " << col;
      }
  }
}

// Loads near 1e308 (e . F and e . T of such entries overflowed) give the plain product scaled
// exactly: forces and torques are applied in units of a common power of two.
TEST(DirectRotation, HugeLoadsGiveTheScaledProduct) {
  DirectRpy op;
  // Particle 1 lies along (1, 1, 1) from particle 0, which carries F = T = 1.875 (1, 1, 1) x 2^1023: the
  // pair's e . F and e . T are 3.2 x 2^1023, beyond double precision, although M [F; T] is not.
  op.set_positions(std::vector<double>{0, 0, 0, 0.8, 0.8, 0.8, -1, 2, 0.25}, std::vector<double>{1.0, 0.5, 0.75});
  const std::vector<double> f = {1.875, 1.875, 1.875, -0.5, 1, 0.25, 0.75, -1, 1},
                            t = {1.875, 1.875, 1.875, 1, 1, -1, 0.25, 0.5, 1};
  std::vector<double> u(9), w(9), u_big(9), w_big(9), f_big(9), t_big(9);
  op.apply(f, t, u, w);
  for (int i = 0; i < 9; ++i) f_big[i] = std::ldexp(f[i], 1023), t_big[i] = std::ldexp(t[i], 1023);
  op.apply(f_big, t_big, u_big, w_big);
  for (int i = 0; i < 9; ++i) {
    EXPECT_EQ(std::ldexp(u_big[i], -1023), u[i]) << i;
    EXPECT_EQ(std::ldexp(w_big[i], -1023), w[i]) << i;
  }
}

// Operators without the rotational blocks refuse clearly; wrong sizes and non-finite torques too.
using rpyfmm::testing::TranslationOnly;

TEST(DirectRotation, BadInputAndUnsupportedOperators) {
  const std::vector<double> x = {0, 0, 0, 3, 0, 0};
  std::vector<double> f(6, 1.0), t(6, 1.0), u(6), w(6), short_t(5, 1.0);
  TranslationOnly plain;
  plain.set_positions(x, 1.0);
  EXPECT_FALSE(plain.supports_rotation());
  try {
    plain.apply(f, t, u, w);
    ADD_FAILURE() << "an operator without rotation accepted torques";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::not_supported);
    EXPECT_NE(std::string(e.what()).find("has no rotational mobility"), std::string::npos) << e.what();
  }
  DirectRpy op;
  EXPECT_THROW(op.apply(f, t, u, w), Error);  // no positions yet
  op.set_positions(x, 1.0);
  EXPECT_TRUE(op.supports_rotation());
  EXPECT_THROW(op.apply(f, short_t, u, w), Error);
  t[4] = NAN;
  try {
    op.apply(f, t, u, w);
    ADD_FAILURE() << "accepted a NaN torque";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("torques entry (1, 1) is NaN"), std::string::npos) << e.what();
  }
}
