// Langevin (inertial) dynamics by the GJF step with half-step velocities (bd/langevin.hpp):
// equipartition, the velocity autocorrelation exp(-gamma t / m), the long-time diffusion
// coefficient kT / gamma and the Boltzmann distribution in a harmonic well, each for
// gamma dt / m from 0.01 to 10, to sampling error (bounds: 5 standard errors of the estimate,
// estimated from the number of independent samples stated at each test). Fixed seeds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "rpyfmm/bd/langevin.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/random.hpp"

using namespace rpyfmm::bd;

namespace {

struct Ensemble {
  std::vector<LangevinParticle> particles;
  std::vector<std::uint64_t> index;
  std::vector<double> x, v, f;
  explicit Ensemble(std::size_t n, LangevinParticle p) : particles(n, p), index(n), x(3 * n, 0.0), v(3 * n), f(3 * n) {
    std::iota(index.begin(), index.end(), std::uint64_t{0});
  }
  /// Forces of the harmonic well -kappa x (kappa = 0: free particles).
  void well(double kappa) {
    for (std::size_t k = 0; k < x.size(); ++k) f[k] = -kappa * x[k];
  }
};

double mean_square(const std::vector<double>& v) {
  double s = 0.0;
  for (double e : v) s += e * e;
  return s / static_cast<double>(v.size());
}

}  // namespace

TEST(Langevin, EquipartitionAndBoltzmannInAHarmonicWell) {
  // m = 1, kT = 1, kappa chosen so that omega dt = sqrt(kappa) dt <= 0.32; start in equilibrium
  // (Maxwell velocities, Gaussian positions), run 5 relaxation times, average the second half.
  // Per component: <m v^2> = kT and <kappa x^2> = kT. Samples: 1000 particles x 3 components x
  // (half the run / the slower relaxation time) >= 7500 independent values per moment.
  const double dt = 0.1, kT = 1.0;
  for (const double gamma_dt : {0.01, 0.1, 1.0, 10.0}) {
    const double gamma = gamma_dt / dt;
    const double kappa = gamma_dt >= 10.0 ? 10.0 : 1.0;
    // Slowest relaxation: velocities m / gamma, positions gamma / kappa (overdamped) or 1 / omega.
    const double relax = std::max({1.0 / gamma, gamma / kappa, 1.0 / std::sqrt(kappa)});
    const auto steps = static_cast<std::uint64_t>(std::ceil(5.0 * relax / dt)) + 200;
    Ensemble e(1000, {1.0, gamma});
    maxwell_velocities(kT, 7, e.particles, e.index, e.v);
    rpyfmm::rpy::fill_normal(e.x, 7, 1, 9);
    for (double& x : e.x) x *= std::sqrt(kT / kappa);
    double kinetic = 0.0, potential = 0.0;
    std::size_t samples = 0;
    for (std::uint64_t n = 0; n < steps; ++n) {
      e.well(kappa);
      langevin_step({dt, kT, 11, n}, e.particles, e.index, e.f, e.x, e.v);
      if (n >= steps / 2) {
        kinetic += mean_square(e.v);
        potential += kappa * mean_square(e.x);
        ++samples;
      }
    }
    kinetic /= static_cast<double>(samples);
    potential /= static_cast<double>(samples);
    const double bound = 5.0 * std::sqrt(2.0 / 7500.0);
    EXPECT_NEAR(kinetic, kT, bound * kT) << "gamma dt / m = " << gamma_dt;
    EXPECT_NEAR(potential, kT, bound * kT) << "gamma dt / m = " << gamma_dt;
  }
}

TEST(Langevin, FreeParticlesDiffuseWithKTOverGamma) {
  // D from the mean-square displacement between t1 = 20 m/gamma and t2 = 60 m/gamma (the ballistic
  // transient then contributes the same offset 6 D m/gamma to both): 4000 particles, relative
  // standard error of each MSD sqrt(2 / (3 * 4000)) = 1.3%, of the slope about 2%.
  const double kT = 1.0, m = 1.0;
  for (const double gamma_dt : {0.1, 1.0, 10.0}) {
    const double gamma = 2.0, dt = gamma_dt * m / gamma;
    const auto s1 = static_cast<std::uint64_t>(std::llround(20.0 / gamma_dt)),
               s2 = static_cast<std::uint64_t>(std::llround(60.0 / gamma_dt));
    Ensemble e(4000, {m, gamma});
    maxwell_velocities(kT, 3, e.particles, e.index, e.v);
    double msd1 = 0.0;
    for (std::uint64_t n = 0; n < s2; ++n) {
      langevin_step({dt, kT, 5, n}, e.particles, e.index, e.f, e.x, e.v);
      if (n + 1 == s1) msd1 = 3.0 * mean_square(e.x);
    }
    const double msd2 = 3.0 * mean_square(e.x);
    const double D = (msd2 - msd1) / (6.0 * static_cast<double>(s2 - s1) * dt);
    EXPECT_NEAR(D, kT / gamma, 0.1 * kT / gamma) << "gamma dt / m = " << gamma_dt;
  }
}

TEST(Langevin, VelocityAutocorrelationDecaysAsExpMinusGammaTOverM) {
  // gamma dt / m = 0.01: C(t) / C(0) at t = 0.5, 1 and 2 m / gamma against exp(-gamma t / m).
  // 4000 particles x 3 components, one time origin: standard error 1 / sqrt(12000) = 0.9%.
  const double kT = 1.0, m = 1.0, gamma = 1.0, dt = 0.01;
  Ensemble e(4000, {m, gamma});
  maxwell_velocities(kT, 13, e.particles, e.index, e.v);
  for (std::uint64_t n = 0; n < 300; ++n) langevin_step({dt, kT, 17, n}, e.particles, e.index, e.f, e.x, e.v);
  const std::vector<double> v0 = e.v;
  const double c0 = mean_square(v0);
  std::uint64_t n = 300;
  for (const double t : {0.5, 1.0, 2.0}) {
    while (static_cast<double>(n - 300) * dt < t - 1e-9) {
      langevin_step({dt, kT, 17, n}, e.particles, e.index, e.f, e.x, e.v);
      ++n;
    }
    double c = 0.0;
    for (std::size_t k = 0; k < v0.size(); ++k) c += v0[k] * e.v[k];
    c /= static_cast<double>(v0.size());
    EXPECT_NEAR(c / c0, std::exp(-gamma * t / m), 5.0 / std::sqrt(12000.0)) << "t = " << t;
  }
}

TEST(Langevin, RestartsFromPositionsVelocitiesAndStepBitForBit) {
  Ensemble a(50, {2.0, 3.0});
  maxwell_velocities(1.0, 1, a.particles, a.index, a.v);
  Ensemble b = a;
  for (std::uint64_t n = 0; n < 20; ++n) {
    a.well(0.5);
    langevin_step({0.05, 1.0, 9, n}, a.particles, a.index, a.f, a.x, a.v);
  }
  for (std::uint64_t n = 0; n < 10; ++n) {
    b.well(0.5);
    langevin_step({0.05, 1.0, 9, n}, b.particles, b.index, b.f, b.x, b.v);
  }
  Ensemble c = b;  // the state a checkpoint keeps: x, v_{n-1/2} and the step
  for (std::uint64_t n = 10; n < 20; ++n) {
    c.well(0.5);
    langevin_step({0.05, 1.0, 9, n}, c.particles, c.index, c.f, c.x, c.v);
  }
  EXPECT_EQ(a.x, c.x);
  EXPECT_EQ(a.v, c.v);
}

TEST(Langevin, BadInputIsRefusedByName) {
  Ensemble e(2, {1.0, 1.0});
  EXPECT_THROW(langevin_step({0.0, 1.0, 1, 0}, e.particles, e.index, e.f, e.x, e.v), rpyfmm::Error);
  EXPECT_THROW(langevin_step({0.1, -1.0, 1, 0}, e.particles, e.index, e.f, e.x, e.v), rpyfmm::Error);
  e.particles[1].mass = 0.0;
  try {
    langevin_step({0.1, 1.0, 1, 0}, e.particles, e.index, e.f, e.x, e.v);
    FAIL() << "zero mass accepted";
  } catch (const rpyfmm::Error& err) {
    EXPECT_NE(std::string(err.what()).find("particle 1"), std::string::npos) << err.what();
  }
  e.particles[1].mass = 1.0;
  std::vector<double> short_f(3);
  EXPECT_THROW(langevin_step({0.1, 1.0, 1, 0}, e.particles, e.index, short_f, e.x, e.v), rpyfmm::Error);
  EXPECT_THROW(sphere_mass(-1.0, 1.0), rpyfmm::Error);
  EXPECT_DOUBLE_EQ(sphere_mass(2.0, 3.0), 4.0 / 3.0 * M_PI * 8.0 * 3.0);
}
