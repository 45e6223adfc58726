// BD with rotation (docs/theory/bd.md Sec. 7): rotational diffusion of free spheres, dipoles in a
// field against the Boltzmann distribution, the hydrodynamic coupling of translation and rotation
// against closed forms, and the translational noise unchanged by turning rotation on. Fixed
// seeds; each statistical tolerance is stated in standard errors of its estimator.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <span>
#include <vector>

#include "one_thread.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/quaternion.hpp"
#include "rpyfmm/bd/torque_field.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/free_draining.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "translation_only_operator.hpp"

using namespace rpyfmm::bd;
using rpyfmm::Error;
constexpr double pi = std::numbers::pi;

namespace {

std::unique_ptr<rpyfmm::rpy::MobilityOperator> free_draining() {
  return std::make_unique<rpyfmm::rpy::FreeDrainingMobility>();
}

// n particles on a line, far enough apart for any pair potential to be irrelevant (none is set).
std::vector<double> line(std::size_t n) {
  std::vector<double> x(3 * n, 0.0);
  for (std::size_t i = 0; i < n; ++i) x[3 * i] = 10.0 * static_cast<double>(i);
  return x;
}

std::array<double, 3> axis(std::span<const double> q, std::size_t i) {
  return quaternion::body_axis(std::span<const double, 4>(q.data() + 4 * i, 4));
}

double dot(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

std::array<double, 3> cross(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// Expects the sample covariance of `samples` (rows of length m, mean zero by construction) to
// equal `expected` (m x m, row-major) entry by entry to k standard errors: for Gaussian samples
// the estimate of C_ab from n rows has variance (C_aa C_bb + C_ab^2) / n.
void expect_covariance(const std::vector<std::vector<double>>& samples, const std::vector<double>& expected, double k) {
  const std::size_t m = samples.front().size();
  const auto n = static_cast<double>(samples.size());
  for (std::size_t a = 0; a < m; ++a)
    for (std::size_t b = a; b < m; ++b) {
      double c = 0.0;
      for (const auto& row : samples) c += row[a] * row[b] / n;
      const double ea = expected[a * m + a], eb = expected[b * m + b], eab = expected[a * m + b];
      EXPECT_NEAR(c, eab, k * std::sqrt((ea * eb + eab * eab) / n)) << "entry (" << a << ", " << b << ")";
    }
}

// One type of radius a, with the given torque entry, and the field on its dipoles.
ForceField rotating_field(double a, TypeTorque type, std::array<double, 3> field) {
  ForceField ff({ParticleType{.name = "A", .radius = a}});
  ff.set_torque_field(TorqueField({type}, {0, 0, 0}, field));
  return ff;
}

}  // namespace

// The dipole torque and energy of a sphere turned by alpha about x (u = (0, -sin a, cos a)) in
// E = E e_z: mu u x E = (-mu E sin alpha, 0, 0), energy -mu E cos alpha; the constant torques add.
TEST(BdRotationTorques, DipoleInAFieldAndConstantTorques) {
  const double alpha = 0.7, mu = 1.5, e = 2.0;
  const std::vector<double> q{std::cos(alpha / 2), std::sin(alpha / 2), 0, 0};
  const TorqueField field({TypeTorque{.torque = {0.1, 0.2, 0.3}, .dipole = mu}}, {1, 0, 0}, {0, 0, e});
  std::vector<double> t(3);
  const double energy = field.compute(q, std::vector<std::uint32_t>{0}, t);
  EXPECT_NEAR(energy, -mu * e * std::cos(alpha), 1e-15);
  EXPECT_NEAR(t[0], 1.1 - mu * e * std::sin(alpha), 1e-15);
  EXPECT_NEAR(t[1], 0.2, 1e-15);
  EXPECT_NEAR(t[2], 0.3, 1e-15);
  EXPECT_FALSE(TorqueField({TypeTorque{.dipole = mu}}, {0, 0, 0}, {0, 0, 0}).active());  // no field: no torque
  EXPECT_THROW(TorqueField({TypeTorque{.dipole = -1.0}}, {0, 0, 0}, {0, 0, 1}), Error);
  EXPECT_THROW(TorqueField({}, {std::nan(""), 0, 0}, {0, 0, 0}), Error);
}

// Free spheres (free draining, kT = 1, a = eta = 1): D_r = kT / (8 pi eta a^3). The scheme turns
// each sphere by independent isotropic Gaussian rotation vectors of variance 2 D_r dt per
// component, so their sum has |sum phi|^2 / (2 D_r t) ~ chi^2_3 at every t: mean 6 D_r t, relative
// standard error sqrt(2/3) / sqrt(N) = 1.3% for N = 4000; tolerance 5% (4 SE). The body axis
// decorrelates as <u(t) . u(0)> = E[R(phi)]^k = exp(-2 D_r t (1 + O(D_r dt))) (the bias of the
// exponent, 2 D_r dt / 12 = 3e-4, is far below the sampling error), with variance
// (1 + 2 exp(-6 D_r t)) / 3 - exp(-4 D_r t) per sphere (<P_2(u . u0)> = exp(-6 D_r t)); tolerance
// 4 standard errors, at a short time (10 steps, 2(1 - <u . u0>) = 4 D_r t to 2%) and at
// 2 D_r t = 0.7. After one step the translation and rotation of each sphere are independent, of
// covariance 2 kT dt diag(I / (6 pi eta a), I / (8 pi eta a^3)) (5 standard errors per entry).
TEST(BdRotation, FreeSpheresDiffuseWithTheStokesRotationalCoefficient) {
  const bdtest::OneThread one;
  const std::size_t n = 4000;
  const double kT = 1.0, dt = 0.05, dr = kT / (8 * pi);
  const auto x0 = line(n);
  Integrator bd(free_draining(), ForceField(), {.dt = dt, .kT = kT, .seed = 5, .rotation = true}, x0,
                std::vector<std::uint32_t>(n, 0));
  const std::vector<double> q0(bd.orientations().begin(), bd.orientations().end());
  std::vector<double> sum(3 * n, 0.0);
  const auto check = [&](std::uint64_t steps) {
    const double t = static_cast<double>(steps) * dt;
    double msd = 0.0, corr = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      corr += dot(axis(bd.orientations(), i), axis(q0, i));
      for (int c = 0; c < 3; ++c) msd += sum[3 * i + c] * sum[3 * i + c];
    }
    msd /= static_cast<double>(n);
    corr /= static_cast<double>(n);
    EXPECT_NEAR(msd / (6 * dr * t), 1.0, 0.05) << "t = " << t;
    const double expected = std::exp(-2 * dr * t);
    const double variance = (1 + 2 * std::exp(-6 * dr * t)) / 3 - expected * expected;
    EXPECT_NEAR(corr, expected, 4 * std::sqrt(variance / static_cast<double>(n))) << "t = " << t;
  };
  for (std::uint64_t s = 1; s <= 175; ++s) {
    bd.step();
    if (s == 1) {  // one step's (dx, phi) per sphere: covariance 2 kT dt diag(I / (6 pi), I / (8 pi)), 5 SE
      std::vector<std::vector<double>> samples;
      for (std::size_t i = 0; i < n; ++i) {
        std::vector<double> row(6);
        for (int c = 0; c < 3; ++c) {
          row[c] = bd.positions()[3 * i + c] - x0[3 * i + c];
          row[3 + c] = bd.last_rotations()[3 * i + c];
        }
        samples.push_back(row);
      }
      std::vector<double> expected(36, 0.0);
      for (int c = 0; c < 3; ++c) {
        expected[7 * c] = 2 * kT * dt / (6 * pi);
        expected[7 * (3 + c)] = 2 * kT * dt / (8 * pi);
      }
      expect_covariance(samples, expected, 5.0);
    }
    for (std::size_t k = 0; k < 3 * n; ++k) sum[k] += bd.last_rotations()[k];
    if (s == 10 || s == 175) check(s);
  }
  for (std::size_t i = 0; i < n; ++i) {  // orientations stay unit quaternions
    double norm = 0.0;
    for (int c = 0; c < 4; ++c) norm += bd.orientations()[4 * i + c] * bd.orientations()[4 * i + c];
    ASSERT_NEAR(norm, 1.0, 1e-14);
  }
}

// Dipoles mu u in a field E e_z sample the Boltzmann distribution exp(b cos theta), b = mu E / kT:
// <cos theta> = coth(b) - 1/b (Langevin). b = 2, a = 0.5 (D_r = 1/pi), dt = 0.01: from u = e_z,
// 6 relaxation times (1 / (2 D_r) = 1.6) of equilibration, then 1000 steps sampled every 10. The
// particles are independent, so the standard error is that of the N per-particle time averages;
// tolerance 4 SE plus 0.006 for the O(dt) bias of Euler-Maruyama (measured with N = 20000 over
// twice as many samples: -0.0037 +- 0.0013 at dt = 0.02 and 0.01, -0.0009 +- 0.0013 at dt = 0.005).
TEST(BdRotation, DipolesInAFieldFollowTheLangevinFunction) {
  const bdtest::OneThread one;
  const std::size_t n = 1000;
  const double a = 0.5, mu = 2.0, e = 1.0, kT = 1.0, b = mu * e / kT;
  Integrator bd(free_draining(), rotating_field(a, {.dipole = mu}, {0, 0, e}),
                {.dt = 0.01, .kT = kT, .seed = 17, .rotation = true}, line(n), std::vector<std::uint32_t>(n, 0));
  bd.run(1000);
  std::vector<double> mean(n, 0.0);
  const int samples = 100;
  for (int s = 0; s < samples; ++s) {
    bd.run(10);
    for (std::size_t i = 0; i < n; ++i) mean[i] += axis(bd.orientations(), i)[2] / samples;
  }
  double m = 0.0, m2 = 0.0;
  for (double v : mean) m += v / static_cast<double>(n);
  for (double v : mean) m2 += (v - m) * (v - m) / static_cast<double>(n - 1);
  const double langevin = 1.0 / std::tanh(b) - 1.0 / b;
  EXPECT_NEAR(m, langevin, 4 * std::sqrt(m2 / static_cast<double>(n)) + 0.006);
}

// kT = 0, two spheres (a = 1, eta = 1) at r = 2.69 > 2a with RPY (DirectRpy): a torque T on
// sphere 0 and a force F on sphere 1. Closed forms (docs/theory/rpy.md Sec. 7, far field; e =
// (x_1 - x_0) / r): dx_0 = dt M^tt_01 F; dx_1 = dt [F / (6 pi) + (T x e) / (8 pi r^2)] (rotlet);
// phi_0 = dt [T / (8 pi) - (F x e) / (8 pi r^2)] (half the stokeslet's vorticity);
// phi_1 = dt [3 (T . e) e - T] / (16 pi r^3) (half the rotlet's vorticity). Tolerance 1e-13
// relative to the largest entry (round-off).
TEST(BdRotation, HydrodynamicCouplingMatchesTheRotletAndStokeslet) {
  const double dt = 0.01;
  const std::array<double, 3> torque{0.3, -0.2, 0.5}, force{-0.4, 0.1, 0.25};
  ForceField ff({ParticleType{.name = "T"}, ParticleType{.name = "F", .external_force = force}});
  ff.set_torque_field(TorqueField({TypeTorque{.torque = torque}, TypeTorque{}}, {0, 0, 0}, {0, 0, 0}));
  const std::vector<double> x{0, 0, 0, 2.0, 1.5, 1.0};
  Integrator bd(std::make_unique<rpyfmm::rpy::DirectRpy>(), ff,
                {.dt = dt, .kT = 0.0, .keep_split_displacements = true, .rotation = true}, x, {0, 1});
  bd.step();
  const std::array<double, 3> d{2.0, 1.5, 1.0};
  const double r = std::sqrt(dot(d, d));
  const std::array<double, 3> unit{d[0] / r, d[1] / r, d[2] / r};
  const auto t_x_e = cross(torque, unit), f_x_e = cross(force, unit);
  const double te = dot(torque, unit), fe = dot(force, unit);
  std::array<double, 12> expected{};
  for (int c = 0; c < 3; ++c) {
    // RPY far field M_01 F = [(1 + 2/(3 r^2)) F + (1 - 2/r^2) (F . e) e] / (8 pi r) (a = 1).
    expected[c] = dt * ((1 + 2 / (3 * r * r)) * force[c] + (1 - 2 / (r * r)) * fe * unit[c]) / (8 * pi * r);
    expected[3 + c] = dt * (force[c] / (6 * pi) + t_x_e[c] / (8 * pi * r * r));
    expected[6 + c] = dt * (torque[c] / (8 * pi) - f_x_e[c] / (8 * pi * r * r));
    expected[9 + c] = dt * (3 * te * unit[c] - torque[c]) / (16 * pi * r * r * r);
  }
  double scale = 0.0;
  for (double v : expected) scale = std::max(scale, std::abs(v));
  for (int k = 0; k < 6; ++k) {
    EXPECT_NEAR(bd.deterministic_displacement()[k], expected[k], 1e-13 * scale) << "displacement entry " << k;
    EXPECT_NEAR(bd.last_rotations()[k], expected[6 + k], 1e-13 * scale) << "rotation entry " << k;
  }
}

// kT = 0, 400 dipolar spheres with constant torques in a field, scattered over a box where many
// pairs are far-field pairs of the FMM's tree (24-point leaves): one step with FmmRpy at tolerance
// 1e-9 gives the deterministic displacements and rotations of DirectRpy to that tolerance (relative
// l2, the operator's contract; 1e-8 leaves room for the sum of two products).
TEST(BdRotation, FmmStepMatchesDirect) {
  const std::size_t n = 400;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> coordinate(0.0, 60.0);
  std::vector<double> x(3 * n);
  for (double& v : x) v = coordinate(rng);
  const ForceField ff = rotating_field(1.0, TypeTorque{.torque = {0.3, -0.2, 0.5}, .dipole = 2.0}, {0.5, 0, 1});
  const std::vector<std::uint32_t> types(n, 0);
  const IntegratorOptions options{.dt = 0.01, .kT = 0.0, .keep_split_displacements = true, .rotation = true};
  Integrator direct(std::make_unique<rpyfmm::rpy::DirectRpy>(), ff, options, x, types);
  Integrator fmm(
      std::make_unique<rpyfmm::rpy::FmmRpy>(rpyfmm::rpy::Geometry::open(), 1.0,
                                            rpyfmm::rpy::FmmRpyOptions{.tolerance = 1e-9, .leaf_capacity = 24}),
      ff, options, x, types);
  direct.step();
  fmm.step();
  const auto relative = [](std::span<const double> a, std::span<const double> b) {
    double num = 0.0, den = 0.0;
    for (std::size_t k = 0; k < a.size(); ++k) num += (a[k] - b[k]) * (a[k] - b[k]), den += b[k] * b[k];
    return std::sqrt(num / den);
  };
  EXPECT_LE(relative(fmm.deterministic_displacement(), direct.deterministic_displacement()), 1e-8);
  EXPECT_LE(relative(fmm.last_rotations(), direct.last_rotations()), 1e-8);
}

// PSE with rotation in a periodic box: one step without noise moves and turns the spheres by
// dt [U; W] of the operator's own grand-mobility product (torques alone), to a few ulps.
TEST(BdRotation, PseStepAppliesThePeriodicGrandMobility) {
  const std::size_t n = 60;
  const double L = 16.0;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> coordinate(0.0, L);
  std::vector<double> x(3 * n);
  for (double& v : x) v = coordinate(rng);
  const ForceField ff = rotating_field(1.0, TypeTorque{.torque = {0.3, -0.2, 0.5}}, {0, 0, 0});
  const std::vector<std::uint32_t> types(n, 0);
  const double dt = 0.01;
  const auto geometry = rpyfmm::rpy::Geometry::periodic(L, L, L);
  Integrator bd(std::make_unique<rpyfmm::rpy::pse::PseRpy>(geometry, 1.0), ff,
                {.dt = dt, .kT = 0.0, .keep_split_displacements = true, .rotation = true}, x, types);
  bd.step();
  rpyfmm::rpy::pse::PseRpy op(geometry, 1.0);
  op.set_positions(x, 1.0);
  std::vector<double> f(3 * n, 0.0), t(3 * n), u(3 * n), w(3 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) t[3 * i + c] = std::array{0.3, -0.2, 0.5}[c];
  op.apply(f, t, u, w);
  for (std::size_t k = 0; k < 3 * n; ++k) {
    EXPECT_DOUBLE_EQ(bd.deterministic_displacement()[k], dt * u[k]) << k;
    EXPECT_DOUBLE_EQ(bd.last_rotations()[k], dt * w[k]) << k;
  }
}

// One step's 12 displacements [dx_0, dx_1, phi_0, phi_1] of two spheres (a = 1, eta = 1, kT = 1,
// r = 2.5, RPY by DirectRpy) have covariance 2 kT dt M, M the grand mobility assembled here from
// docs/theory/rpy.md Sec. 7's far-field closed forms: self blocks I / (6 pi), I / (8 pi); pair
// blocks M^tt (RPY), M^rr = h I + k e e^T, and the coupling M^tr_ij = M^rt_ij = -c [e_ij]_x
// (U_i = c T_j x e_ij, W_i = c F_j x e_ij, e_ij = (x_i - x_j) / r, c = 1 / (8 pi r^2)), whose
// correlation coefficient 0.14 is 20 standard errors from zero. n = 20000 steps from the same
// state (noise keyed by the step number); tolerance 5 standard errors per entry (78 entries).
TEST(BdRotation, PairDisplacementsHaveTheGrandMobilityCovariance) {
  const bdtest::OneThread one;
  const double dt = 0.01, kT = 1.0;
  const std::vector<double> x{0, 0, 0, 1.5, 1.2, 1.6};
  const std::array<double, 3> e{0.6, 0.48, 0.64};  // (x_1 - x_0) / r, r = 2.5
  const double r = 2.5, c = 1 / (8 * pi * r * r), h = -1 / (16 * pi * r * r * r), k = 3 / (16 * pi * r * r * r);
  std::vector<double> m(144, 0.0);  // rows and columns [t_0, t_1, r_0, r_1], 3 each
  const auto set = [&](int bi, int bj, int a, int b, double v) { m[(3 * bi + a) * 12 + 3 * bj + b] = v; };
  for (int a = 0; a < 3; ++a)
    for (int b = 0; b < 3; ++b) {
      const double id = a == b ? 1.0 : 0.0, ee = e[a] * e[b];
      const double tt = ((1 + 2 / (3 * r * r)) * id + (1 - 2 / (r * r)) * ee) / (8 * pi * r);
      int third = 3 - a - b;  // [e]_x entry (a, b): eps_{a third b} e_third
      const double ex = a == b ? 0.0 : ((b - a + 3) % 3 == 1 ? -e[third] : e[third]);
      for (int i = 0; i < 2; ++i) {
        set(i, i, a, b, id / (6 * pi));
        set(2 + i, 2 + i, a, b, id / (8 * pi));
        set(i, 1 - i, a, b, tt);
        set(2 + i, 3 - i, a, b, h * id + k * ee);
        const double sign = i == 1 ? 1.0 : -1.0;  // e_10 = e, e_01 = -e
        set(i, 3 - i, a, b, -c * sign * ex);      // U_i from T_j
        set(2 + i, 1 - i, a, b, -c * sign * ex);  // W_i from F_j
      }
    }
  for (double& v : m) v *= 2 * kT * dt;
  std::vector<std::vector<double>> samples;
  for (std::uint64_t s = 0; s < 20000; ++s) {
    Integrator bd(std::make_unique<rpyfmm::rpy::DirectRpy>(), ForceField(),
                  {.dt = dt, .kT = kT, .seed = 31, .rotation = true}, x, {0, 0}, {}, s);
    bd.step();
    std::vector<double> row(12);
    for (int j = 0; j < 6; ++j) {
      row[j] = bd.positions()[j] - x[j];
      row[6 + j] = bd.last_rotations()[j];
    }
    samples.push_back(row);
  }
  expect_covariance(samples, m, 5.0);
}

// Free draining: with rotation on, the translational noise is drawn from the same stream and the
// rotational one from its own, so positions stay bitwise those of the same run without rotation
// (here with a torque and dipoles in a field, which turn the spheres but cannot move them).
TEST(BdRotation, TurningRotationOnLeavesFreeDrainingTranslationBitwise) {
  const std::size_t n = 200;
  ForceField ff({ParticleType{.name = "A", .radius = 1.0, .external_force = {0.1, 0, -0.5}}});
  ff.set_pair(0, 0, {.kind = PairKind::wca, .epsilon = 1.0});
  ForceField turning = ff;
  turning.set_torque_field(TorqueField({TypeTorque{.torque = {0, 0.3, 0}, .dipole = 2.0}}, {0, 0, 0}, {1, 0, 0}));
  std::vector<double> x(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    x[3 * i] = 2.2 * static_cast<double>(i % 10);
    x[3 * i + 1] = 2.2 * static_cast<double>(i / 10);
  }
  Integrator off(free_draining(), ff, {.dt = 1e-3, .kT = 1.0, .seed = 9}, x, std::vector<std::uint32_t>(n, 0));
  Integrator on(free_draining(), turning, {.dt = 1e-3, .kT = 1.0, .seed = 9, .rotation = true}, x,
                std::vector<std::uint32_t>(n, 0));
  off.run(50);
  on.run(50);
  EXPECT_EQ(std::vector<double>(on.positions().begin(), on.positions().end()),
            std::vector<double>(off.positions().begin(), off.positions().end()));
  EXPECT_TRUE(off.orientations().empty());
  EXPECT_NE(on.orientations()[0], 1.0);  // and the spheres did turn
}

using rpyfmm::testing::TranslationOnly;

// Rotation needs an operator with torques: one without is refused, the error naming it and the key.
TEST(BdRotation, OperatorWithoutRotationIsRefusedByName) {
  try {
    Integrator bd(std::make_unique<TranslationOnly>(), ForceField(), {.dt = 0.01, .rotation = true}, line(2), {0, 0});
    FAIL() << "rotation with an operator without it not refused";
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("'translation-only'"), std::string::npos) << err.what();
    EXPECT_NE(std::string(err.what()).find("system.rotation"), std::string::npos) << err.what();
  }
  EXPECT_THROW(Integrator(free_draining(), ForceField(), {.dt = 0.01}, line(1), {0}, {}, 0, {1, 0, 0, 0}), Error);
  EXPECT_THROW(
      Integrator(free_draining(), ForceField(), {.dt = 0.01, .rotation = true}, line(1), {0}, {}, 0, {0, 0, 0, 0}),
      Error);  // a zero quaternion
}

// The blow-up guard bounds the rotation angle too: a torque that would turn a sphere by more than
// max_displacement radians in one step stops the step, naming the angle, with the state kept.
TEST(BdRotation, BlowUpGuardBoundsTheRotationAngle) {
  ForceField ff({ParticleType{.name = "A"}});
  ff.set_torque_field(TorqueField({}, {0, 0, 100.0}, {0, 0, 0}));  // W = 100 / (8 pi) = 4 rad per unit time
  Integrator bd(free_draining(), ff, {.dt = 0.2, .kT = 0.0, .max_displacement = 0.5, .rotation = true}, line(1), {0});
  try {
    bd.step();
    FAIL() << "no blow-up";
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("particle 0 would turn by"), std::string::npos) << err.what();
  }
  EXPECT_EQ(bd.step_count(), 0u);
  EXPECT_EQ(bd.orientations()[0], 1.0);
}
