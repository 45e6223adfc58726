// Hostile input to the BD engine's C++ entry points: a RunConfig built in code (not parsed), the
// Integrator's options and state, a thermal energy that is subnormal or whose noise variance
// under- or overflows, orientations of extreme magnitude, the step counter at its end.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "../common/expect_error.hpp"
#include "config_helpers.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/bd/quaternion.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/rpy/free_draining.hpp"

namespace {

namespace fs = std::filesystem;
using rpyfmm::ErrorCode;
using rpyfmm::bd::Integrator;
using rpyfmm::bd::IntegratorOptions;
using rpyfmm::bd::RunConfig;
using rpyfmm_test::expect_error;

const double kNaN = std::numeric_limits<double>::quiet_NaN();

// A free-draining config of 10 random particles in open geometry, writing into a fresh folder.
RunConfig small_config(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("rpyfmm_hostile_bd_" + std::to_string(::getpid()) + "_" + name);
  fs::remove_all(dir);
  return rpyfmm::bd::parse_config(
      "[particles]\nsource = \"random\"\ncount = 10\n[integrator]\ndt = 0.001\nsteps = 2\n"
      "[mobility]\nmethod = \"none\"\n[output]\ndir = \"" +
          dir.string() + "\"\n",
      "test");
}

Integrator free_draining(IntegratorOptions o, std::vector<double> x, std::vector<double> orientations = {},
                         std::uint64_t first_step = 0) {
  const std::size_t n = x.size() / 3;
  return Integrator(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(), rpyfmm::bd::ForceField{}, o, std::move(x),
                    std::vector<std::uint32_t>(n, 0), {}, first_step, std::move(orientations));
}

// A RunConfig filled in code skips the parser's checks; make_particles (run_bd) repeats them. A NaN
// volume fraction made random placement loop forever, a NaN cluster packing too, a count of 2^64-1
// ended in std::length_error, a subnormal volume fraction in infinite positions.
TEST(HostileBdInputs, GeneratedParticlesOfAConfigBuiltInCode) {
  using Source = rpyfmm::bd::ParticleSpec::Source;
  const auto refused = [](auto edit, const std::string& key) {
    RunConfig c = small_config("spec");
    edit(c);
    expect_error([&] { (void)rpyfmm::bd::run_bd(c); }, ErrorCode::invalid_argument, "'" + key + "'");
    EXPECT_FALSE(fs::exists(c.output.dir)) << key;
  };
  refused([](RunConfig& c) { c.particles.volume_fraction = kNaN; }, "particles.volume_fraction");
  refused([](RunConfig& c) { c.particles.volume_fraction = 5e-324; }, "particles.volume_fraction");
  refused([](RunConfig& c) { c.particles.count = std::numeric_limits<std::size_t>::max(); }, "particles.count");
  refused([](RunConfig& c) { c.particles.count = 0; }, "particles.count");
  refused(
      [](RunConfig& c) {
        c.particles.source = Source::clusters;
        c.particles.clusters = 2;
        c.particles.cluster_size = 3;
        c.particles.cluster_volume_fraction = kNaN;
      },
      "particles.cluster_volume_fraction");
  refused(
      [](RunConfig& c) {
        c.particles.source = Source::chains;
        c.particles.chains = std::numeric_limits<std::size_t>::max();
        c.particles.beads = 2;
      },
      "particles.chains");
}

// kT > 0 must give noise: a subnormal kT, or 2 kT dt below the normal range, made every Brownian
// displacement exactly 0 (kT = 5e-324 at dt = 1e-3 ran as deterministic dynamics); 2 kT dt
// overflowing made it infinite. kT = 0 remains the way to ask for no noise.
TEST(HostileBdInputs, ThermalEnergyMustGiveNormalNoise) {
  const std::vector<double> x{0, 0, 0, 5, 0, 0};
  expect_error([&] { (void)free_draining({.dt = 1e-3, .kT = 5e-324}, x); }, ErrorCode::invalid_argument,
               "kT must be 0 or a normal number");
  expect_error([&] { (void)free_draining({.dt = 1e-200, .kT = 1e-200}, x); }, ErrorCode::invalid_argument,
               "2 kT dt = 0 (kT = 1e-200) underflows");
  expect_error([&] { (void)free_draining({.dt = 1e200, .kT = 1e200}, x); }, ErrorCode::invalid_argument,
               "2 kT dt = inf (kT = 1e+200) overflows");
  expect_error([&] { (void)free_draining({.dt = 1e-3, .kT = -1e-10}, x); }, ErrorCode::invalid_argument,
               "got -1e-10");  // printed as %g (std::to_string gave "-0.000000")
  Integrator deterministic = free_draining({.dt = 1e-3, .kT = 0.0}, x);
  deterministic.step();
  EXPECT_EQ(deterministic.positions()[3], 5.0);
  // The same rule for a parsed config (naming the key) and for one built in code (run_bd).
  bdtest::expect_refused(
      "[system]\nkT = 5e-324\n[particles]\nsource = \"random\"\ncount = 10\n[integrator]\ndt = 0.01\nsteps = 1\n",
      "system.kT", "must be 0 or a normal number");
  RunConfig c = small_config("kT");
  c.integrator.kT = 5e-324;
  expect_error([&] { (void)rpyfmm::bd::run_bd(c); }, ErrorCode::invalid_argument, "kT must be 0 or a normal number");
  EXPECT_FALSE(fs::exists(c.output.dir));
}

// Quaternions of 1e300 are valid orientations: their norm overflowed to infinity, and the
// normalized orientation became NaN (then every later rotation).
TEST(HostileBdInputs, OrientationsOfExtremeMagnitudeAreNormalized) {
  const auto q = rpyfmm::bd::quaternion::checked({1e300, 1e300, 0.0, 0.0}, 1, "test", "particle");
  const double h = std::sqrt(0.5);
  EXPECT_NEAR(q[0], h, 1e-15);
  EXPECT_NEAR(q[1], h, 1e-15);
  EXPECT_EQ(q[2], 0.0);
  EXPECT_EQ(q[3], 0.0);
  Integrator in = free_draining({.dt = 1e-3, .kT = 1.0, .rotation = true}, {0, 0, 0}, {-1e308, 0.0, 1e308, 1e308});
  in.step();
  for (double v : in.orientations()) EXPECT_TRUE(std::isfinite(v));
}

// The noise is keyed by the step number: at 2^64-1 the next step would wrap to 0 and repeat the
// noise of step 0 (a run started there advanced its counter to 2 after three steps).
TEST(HostileBdInputs, StepCounterDoesNotWrap) {
  const std::uint64_t last = std::numeric_limits<std::uint64_t>::max();
  Integrator in = free_draining({.dt = 1e-3, .kT = 1.0}, {0, 0, 0}, {}, last - 1);
  in.step();
  EXPECT_EQ(in.step_count(), last);
  expect_error([&] { in.step(); }, ErrorCode::invalid_input, "2^64-1");
  EXPECT_EQ(in.step_count(), last);
}

// A step that would carry a particle beyond the largest double is a blow-up: with a huge
// max_displacement the guard passed it, and the next step failed on "positions entry (0, 0) is
// infinite", the Integrator's own state.
TEST(HostileBdInputs, StepBeyondTheLargestDoubleIsABlowUp) {
  rpyfmm::bd::ForceField forces;
  forces.set_global_force({1e308, 0.0, 0.0});
  Integrator in(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(), forces,
                {.dt = 10.0, .kT = 0.0, .max_displacement = 1e308}, {1.7e308, 0.0, 0.0}, {0});
  expect_error([&] { in.step(); }, ErrorCode::numerical_failure, "beyond the largest double");
  EXPECT_EQ(in.positions()[0], 1.7e308);  // the last good state
}

// Subnormal masses and frictions of inertial types gave NaN velocities (then a blow-up "would move
// -nan"); they are refused like every other subnormal scale.
TEST(HostileBdInputs, SubnormalInertiaIsRefused) {
  IntegratorOptions o{.dt = 1e-3, .kT = 1.0};
  o.inertia = {rpyfmm::bd::LangevinParticle{.mass = 5e-324, .friction = 1.0}};
  expect_error([&] { (void)free_draining(o, {0, 0, 0}); }, ErrorCode::invalid_argument, "normal");
  o.inertia = {rpyfmm::bd::LangevinParticle{.mass = 1.0, .friction = 1e-310}};
  expect_error([&] { (void)free_draining(o, {0, 0, 0}); }, ErrorCode::invalid_argument, "normal");
}

}  // namespace
