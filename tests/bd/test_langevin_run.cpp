// BD runs with Langevin (inertial) types beside Brownian ones (docs/theory/bd.md Sec. 8): both
// kinds reach the same temperature in one harmonic trap, the Brownian particles move as in a run
// without Langevin ones, restarts continue bit for bit (velocities included), the log's
// langevin_kT column, and the config errors naming their key. Fixed seeds.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "config_helpers.hpp"
#include "one_thread.hpp"
#include "restart_pair.hpp"
#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "run_files_fixture.hpp"
#include "text_edit.hpp"

using namespace rpyfmm::bd;
using rpyfmm::Error;

namespace {

using bdtest::expect_refused;
using bdtest::make_integrator;
using bdtest::replace;

// Brownian "S" (radius 1, gamma = 6 pi) and Langevin "L" (radius 2, gamma = 12 pi, m = 7.5:
// gamma dt / m = 0.1) spheres, free draining, in the trap kappa = 10 at the origin, from a dense
// lattice (the trap's force on the outermost particles moves them < 0.5 a per step).
const std::string kMixed = R"(
[system]
kT = 1.0
[[types]]
name = "S"
radius = 1.0
[[types]]
name = "L"
radius = 2.0
dynamics = "langevin"
mass = 7.5
[particles]
source = "lattice"
count = 64
volume_fraction = 0.25
types = ["S", "L"]
[external]
trap_stiffness = 10.0
[mobility]
method = "none"
[integrator]
dt = 0.02
steps = 40
seed = 5
[output]
trajectory_every = 5
log_every = 5
checkpoint_every = 10
)";

/// Means over the particles of one kind, per component and step.
struct Moments {
  double potential = 0.0, kinetic = 0.0;
  std::size_t samples = 0;
};

class LangevinRun : public bdtest::RunFiles {};

}  // namespace

TEST(LangevinRunStatistics, BrownianAndLangevinParticlesReachTheSameTemperatureInOneTrap) {
  // 600 particles of each kind start from the trap's (kappa = 40) Boltzmann distribution
  // (Langevin ones with Maxwell velocities), 100 steps of burn-in, then 1000 steps (20 time
  // units) are averaged. Per component: <kappa x^2> and <m v^2> (Langevin) are kT exactly for the
  // GJF step (langevin.hpp); the Euler-Maruyama step of the Brownian ones keeps the variance
  // kT / kappa / (1 - c / 2), c = kappa dt / gamma = 0.042 (x <- (1 - c) x + noise).
  // Slowest relaxation time: Langevin positions 0.65 (the overdamped mode of gamma / m = 5,
  // omega^2 = kappa / m), Brownian gamma / kappa = 0.47; x^2 decorrelates in half of it, so each
  // moment averages >= 1800 x 20 / 0.65 = 55000 independent values: relative standard error
  // sqrt(2 / 55000) = 0.6%. Bound: 5 standard errors, 3%.
  const bdtest::OneThread one;
  RunConfig c = parse_config(replace(kMixed, "trap_stiffness = 10.0", "trap_stiffness = 40.0"), "mixed");
  const std::size_t half = 600, n = 2 * half;
  const double kT = 1.0, kappa = 40.0, dt = c.integrator.dt;
  std::vector<std::uint32_t> types(n);
  for (std::size_t i = 0; i < n; ++i) types[i] = static_cast<std::uint32_t>(i % 2);  // S, L alternating
  std::vector<double> x(3 * n);
  rpyfmm::rpy::fill_normal(x, 3, 0, 9);
  for (double& v : x) v *= std::sqrt(kT / kappa);
  Integrator bd = make_integrator(c, std::move(x), types);
  bd.run(100);
  Moments brownian, langevin;
  const double mass = 7.5;
  for (int s = 0; s < 1000; ++s) {
    bd.step();
    const auto pos = bd.positions();
    const auto vel = bd.inertial().velocities();
    for (std::size_t i = 0; i < n; ++i) {
      Moments& m = types[i] == 0 ? brownian : langevin;
      for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
        m.potential += kappa * pos[k] * pos[k];
        m.kinetic += mass * vel[k] * vel[k];
      }
      m.samples += 3;
    }
  }
  const double gamma_s = 6.0 * std::numbers::pi, c_s = kappa * dt / gamma_s;
  const double bound = 0.03;
  EXPECT_NEAR(brownian.potential / static_cast<double>(brownian.samples), kT / (1.0 - 0.5 * c_s), bound * kT);
  EXPECT_NEAR(langevin.potential / static_cast<double>(langevin.samples), kT, bound * kT);
  EXPECT_NEAR(langevin.kinetic / static_cast<double>(langevin.samples), kT, bound * kT);
  EXPECT_EQ(brownian.kinetic, 0.0);                                 // Brownian particles carry no velocity
  EXPECT_NEAR(bd.inertial().kinetic_temperature(), kT, 0.25 * kT);  // one step's mean over 600
}

TEST(LangevinRunStatistics, BrownianParticlesMoveAsWithoutLangevinOnes) {
  // Free draining, no pair forces: a Brownian particle feels neither the Langevin ones nor their
  // noise (stream 4), so its path is bit for bit that of the run where every type is Brownian.
  RunConfig mixed = parse_config(kMixed, "mixed");
  RunConfig brownian =
      parse_config(replace(replace(kMixed, "dynamics = \"langevin\"\n", ""), "mass = 7.5\n", ""), "brownian");
  std::vector<double> x(3 * 40);
  rpyfmm::rpy::fill_normal(x, 4, 0, 9);
  std::vector<std::uint32_t> types(40);
  for (std::size_t i = 0; i < types.size(); ++i) types[i] = static_cast<std::uint32_t>(i % 2);
  Integrator a = make_integrator(mixed, x, types), b = make_integrator(brownian, x, types);
  a.run(30);
  b.run(30);
  for (std::size_t i = 0; i < types.size(); i += 2)
    for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) EXPECT_EQ(a.positions()[k], b.positions()[k]) << "particle " << i;
  EXPECT_NE(a.positions()[3], b.positions()[3]);  // particle 1 is Langevin in `a`
}

TEST_F(LangevinRun, RestartContinuesBitForBitWithVelocities) {
  // Interrupted at step 20 and restarted to 40: positions, velocities, the trajectory and the
  // log's langevin_kT column (its last; wall times differ between the runs) equal those of the
  // uninterrupted run, bitwise.
  const bdtest::OneThread one;
  const RunConfig c = parse_config(kMixed, "mixed");
  EXPECT_EQ(bdtest::run_whole_and_restarted(c, dir_ / "whole", dir_ / "split", 20).last_step, 40u);
  const Checkpoint a = read_checkpoint(dir_ / "whole" / "checkpoint.bin");
  const Checkpoint b = read_checkpoint(dir_ / "split" / "checkpoint.bin");
  EXPECT_TRUE(a.positions == b.positions);
  EXPECT_TRUE(a.velocities == b.velocities);
  EXPECT_TRUE(slurp(dir_ / "whole" / "trajectory.xyz") == slurp(dir_ / "split" / "trajectory.xyz"));
  const auto last_column = [](const std::string& log) {
    std::vector<std::string> out;
    for (std::size_t start = 0, end; (end = log.find('\n', start)) != std::string::npos; start = end + 1)
      out.push_back(log.substr(log.rfind(',', end) + 1, end - log.rfind(',', end) - 1));
    return out;
  };
  const auto kt_a = last_column(slurp(dir_ / "whole" / "log.csv"));
  EXPECT_EQ(kt_a, last_column(slurp(dir_ / "split" / "log.csv")));
  ASSERT_EQ(kt_a.size(), 10u);  // header + steps 0, 5, ..., 40
  EXPECT_EQ(kt_a.front(), "langevin_kT");
  ASSERT_EQ(a.velocities.size(), 3 * a.types.size());
  for (std::size_t i = 0; i < a.types.size(); ++i) {  // S: no velocity; L: some
    const double* v = a.velocities.data() + 3 * i;
    const double v2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    if (a.types[i] == 0)
      EXPECT_EQ(v2, 0.0) << i;
    else
      EXPECT_GT(v2, 0.0) << i;
  }
}

TEST_F(LangevinRun, BrownianOnlyRunsKeepCheckpointVersion2AndNoLogColumn) {
  const RunConfig c = parse_config(replace(replace(kMixed, "dynamics = \"langevin\"\n", ""), "mass = 7.5\n", ""), "b");
  run(c, dir_ / "out", 10);
  const std::string bytes = slurp(dir_ / "out" / "checkpoint.bin");
  ASSERT_GT(bytes.size(), 12u);
  EXPECT_EQ(static_cast<unsigned char>(bytes[8]), 2u);
  EXPECT_TRUE(read_checkpoint(dir_ / "out" / "checkpoint.bin").velocities.empty());
  EXPECT_EQ(slurp(dir_ / "out" / "log.csv").find("langevin_kT"), std::string::npos);
}

TEST(LangevinConfig, MassFromDensityAndFrictionFromViscosity) {
  const RunConfig c = parse_config(
      replace(replace(kMixed, "mass = 7.5", "density = 0.5"), "kT = 1.0", "kT = 1.0\nviscosity = 2.0"), "density");
  ASSERT_EQ(c.integrator.inertia.size(), 2u);
  EXPECT_FALSE(c.integrator.inertia[0].has_value());
  ASSERT_TRUE(c.integrator.inertia[1].has_value());
  EXPECT_DOUBLE_EQ(c.integrator.inertia[1]->mass, sphere_mass(2.0, 0.5));
  EXPECT_DOUBLE_EQ(c.integrator.inertia[1]->friction, 6.0 * std::numbers::pi * 2.0 * 2.0);
  EXPECT_EQ(c.trap_stiffness, 10.0);
}

TEST(LangevinConfig, BadCombinationsAreRefusedNamingTheKey) {
  expect_refused(replace(kMixed, "\"langevin\"", "\"inertial\""), "types[1].dynamics",
                 "must be \"brownian\" or \"langevin\"");
  expect_refused(replace(kMixed, "mass = 7.5\n", ""), "types[1].dynamics", "needs mass or density");
  expect_refused(replace(kMixed, "mass = 7.5", "mass = 7.5\ndensity = 1.0"), "types[1].density",
                 "cannot be given with mass");
  expect_refused(replace(kMixed, "mass = 7.5", "mass = -1.0"), "types[1].mass", "must be > 0");
  expect_refused(replace(kMixed, "mass = 7.5", "density = 0.0"), "types[1].density", "must be > 0");
  expect_refused(replace(kMixed, "radius = 1.0", "radius = 1.0\nmass = 1.0"), "types[0].mass",
                 "only used with dynamics");
  expect_refused(replace(kMixed, "radius = 1.0", "radius = 1.0\ndensity = 1.0"), "types[0].density", "only used with");
  expect_refused(replace(kMixed, "method = \"none\"", "method = \"direct\""), "types[1].dynamics",
                 "hydrodynamic interactions with inertia are not supported");
  expect_refused(replace(kMixed, "method = \"none\"\n", ""), "types[1].dynamics", "method = \"none\"");
  expect_refused(replace(kMixed, "kT = 1.0", "kT = 1.0\nrotation = true"), "types[1].dynamics", "system.rotation");
  expect_refused(replace(kMixed, "seed = 5", "seed = 5\nsplit_displacements = true"), "types[1].dynamics",
                 "split_displacements");
  expect_refused(replace(kMixed, "trap_stiffness = 10.0", "trap_stiffness = -1.0"), "external.trap_stiffness", ">= 0");
  expect_refused(replace(replace(kMixed, "kT = 1.0", "kT = 1.0\ngeometry = \"periodic\"\nbox = [20.0, 20.0, 20.0]"),
                         "volume_fraction = 0.25\n", ""),
                 "external.trap_stiffness", "geometry = \"open\"");
}

TEST(LangevinConfig, TheIntegratorRefusesInertiaWithHydrodynamicInteractions) {
  RunConfig c = parse_config(kMixed, "mixed");
  c.mobility.method = rpyfmm::rpy::MobilityMethod::direct;
  try {
    (void)make_integrator(c, std::vector<double>(6, 0.0), {0, 1});
    FAIL() << "inertia with direct RPY accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("hydrodynamic interactions with inertia"), std::string::npos) << e.what();
  }
  c.mobility.method = rpyfmm::rpy::MobilityMethod::none;
  std::vector<double> v(6, 0.0);
  v[0] = 1.0;  // particle 0 is Brownian
  EXPECT_THROW(Integrator(rpyfmm::rpy::make_mobility(c.mobility, 2), make_force_field(c), c.integrator,
                          std::vector<double>(6, 0.0), {0, 1}, c.neighbours, 0, {}, v),
               Error);
}
