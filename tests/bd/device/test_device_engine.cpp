// The CUDA engine (bd/src/device/device_engine.cu) against the host launcher: the same stage
// functions, one thread per particle on the device and a host loop. Both keep a * b + c unfused
// (nvcc --fmad=false, -ffp-contract=off), so the rows, positions and energies agree bit for bit
// with LJ 36-18, WCA and soft pairs and harmonic bonds (only +, -, *, / and sqrt, correctly
// rounded on both); DLVO and FENE call exp and log, whose device versions differ from the host's
// by about an ulp, so those runs compare within the bound of docs/gpu-bd.md.
// The scenarios also run on the host launcher against the CPU Integrator where no device is
// (DeviceScenarios.*), so that they are known to be valid runs: no overlap, no blow-up, rebuilds.
// Without a usable device the device tests skip, saying why (require_device.hpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <string>

#include "compare.hpp"
#include "device/host_engine.hpp"
#include "device_systems.hpp"
#include "require_device.hpp"
#include "rpyfmm/bd/device/device_engine.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/free_draining.hpp"

using namespace device_test;
using rpyfmm::bd::device::DeviceEngine;
using rpyfmm::bd::device::EngineOptions;
using rpyfmm::bd::device::HostEngine;
using rpyfmm::rpy::Geometry;

namespace {

EngineOptions options(double dt, std::uint64_t seed) {
  EngineOptions o;
  o.dt = dt;
  o.seed = seed;
  o.viscosity = 0.7;
  o.neighbours.skin = 0.1;  // rebuilds every few steps
  return o;
}

/// One run: `ulps` = 0: device and host agree bit for bit; > 0: within that many ulps of the
/// coordinate scale per step.
struct Scenario {
  std::string name;
  ForceField forces;
  std::vector<std::uint32_t> types;
  Geometry geometry;
  std::vector<double> x;
  EngineOptions options;
  int steps;
  double ulps;
};

/// Jittered lattices (+-0.03) at each potential's spacing, time steps far below the guard.
std::vector<Scenario> scenarios() {
  std::vector<Scenario> s;
  {  // 8000 particles: the cell path, many blocks
    const double L = 20 * spacing(PairKind::lj36_18);
    auto x = jittered_lattice(20, spacing(PairKind::lj36_18), 0.03, 61);
    unwrap_some(x, L);
    s.push_back({"lj36_18 periodic", single_type(PairKind::lj36_18), std::vector<std::uint32_t>(8000, 0),
                 Geometry::periodic(L), x, options(2e-4, 3), 40, 0.0});
    s.push_back({"wca periodic", single_type(PairKind::wca), std::vector<std::uint32_t>(8000, 0), Geometry::periodic(L),
                 x, options(2e-4, 5), 30, 0.0});
  }
  {  // a mixture with harmonic bonds, external forces and a trap, open
    ForceField forces = mixture();
    forces.add_bond_potential({rpyfmm::bd::BondKind::harmonic, 20.0, 1.6});
    std::vector<rpyfmm::bd::Bond> bonds;
    for (std::uint32_t i = 0; i + 1 < 4096; i += 2) bonds.push_back({i, i + 1, 0});
    forces.add_bonds(bonds);
    forces.set_trap(0.01);
    s.push_back({"mixture, open", forces, alternating_types(4096), Geometry::open(),
                 jittered_lattice(16, 1.6, 0.03, 62), options(2e-4, 4), 50, 0.0});
  }
  // 27 particles: the rows from all pairs
  s.push_back({"27 particles", single_type(PairKind::wca), std::vector<std::uint32_t>(27, 0),
               Geometry::periodic(3 * spacing(PairKind::wca)), jittered_lattice(3, spacing(PairKind::wca), 0.03, 63),
               options(2e-4, 8), 50, 0.0});
  {  // no pair potential (no lists): harmonic bonds and external forces only
    ForceField forces({ParticleType{"A", 1.0, {0.1, 0.0, -0.2}, 0.0}});
    forces.add_bond_potential({rpyfmm::bd::BondKind::harmonic, 5.0, 2.0});
    std::vector<rpyfmm::bd::Bond> bonds;
    for (std::uint32_t i = 0; i + 1 < 512; ++i) bonds.push_back({i, i + 1, 0});
    forces.add_bonds(bonds);
    s.push_back({"bonds only", forces, std::vector<std::uint32_t>(512, 0), Geometry::open(),
                 jittered_lattice(8, 2.0, 0.03, 67), options(1e-3, 10), 30, 0.0});
  }
  // exp and log: DLVO, FENE
  s.push_back({"dlvo", single_type(PairKind::dlvo), std::vector<std::uint32_t>(1728, 0), Geometry::open(),
               jittered_lattice(12, spacing(PairKind::dlvo), 0.03, 64), options(2e-4, 6), 40, 64.0});
  ForceField chain = single_type(PairKind::soft);
  add_chain_bonds(chain, 1728);
  s.push_back({"fene", chain, std::vector<std::uint32_t>(1728, 0), Geometry::open(),
               jittered_lattice(12, spacing(PairKind::soft), 0.03, 65), options(2e-3, 7), 20, 64.0});
  return s;
}

/// Steps both engines, comparing rows, positions and energies at every step.
void run_both(const Scenario& c) {
  HostEngine host(c.forces, c.types, c.geometry, c.options, c.x);
  DeviceEngine dev(c.forces, c.types, c.geometry, c.options, c.x);
  double scale = 1.0;
  for (double v : c.x) scale = std::max(scale, std::abs(v));
  const bool exact = c.ulps == 0.0;
  for (int s = 0; s < c.steps; ++s) {
    host.step();
    dev.step();
    ASSERT_EQ(dev.last_step_rebuilt(), host.last_step_rebuilt()) << c.name << ", step " << s;
    if (exact) {
      const auto rows = dev.neighbour_rows();
      ASSERT_EQ(rows.offsets, host.neighbour_rows().offsets) << c.name << ", step " << s;
      ASSERT_EQ(rows.indices, host.neighbour_rows().indices) << c.name << ", step " << s;
      EXPECT_EQ(dev.potential_energy(), host.potential_energy()) << c.name << ", step " << s;
    }
    const double b = c.ulps * std::numeric_limits<double>::epsilon() * scale * (s + 1);
    expect_close(dev.positions(), host.positions(), std::vector<double>(c.x.size(), b), exact, c.name.c_str());
    if (::testing::Test::HasFailure()) {
      ADD_FAILURE() << c.name << ": first difference at step " << s;
      return;
    }
  }
  EXPECT_EQ(dev.rebuilds(), host.rebuilds()) << c.name;
  EXPECT_EQ(dev.step_count(), host.step_count()) << c.name;
}

}  // namespace

TEST(DeviceEngine, RefusedWithoutDevice) {
  if (DeviceEngine::device_available()) GTEST_SKIP() << "a device is present: the refusal is not reachable";
  if (device_expected()) FAIL() << "RPYFMM_EXPECT_CUDA is set, but no usable CUDA device";
  const auto x = jittered_lattice(4, 2.15, 0.03, 1);
  try {
    DeviceEngine dev(single_type(PairKind::wca), std::vector<std::uint32_t>(x.size() / 3, 0), Geometry::open(),
                     options(1e-3, 1), x);
    ADD_FAILURE() << "constructed without a device";
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), rpyfmm::ErrorCode::not_supported) << e.what();
  }
}

TEST(DeviceEngine, AgreesWithHostLauncher) {
  REQUIRE_BD_DEVICE();
  for (const Scenario& c : scenarios()) run_both(c);
}

TEST(DeviceEngine, BlowUpKeepsState) {
  REQUIRE_BD_DEVICE();
  const auto x = jittered_lattice(6, 2.15, 0.03, 66);
  DeviceEngine dev(single_type(PairKind::wca), std::vector<std::uint32_t>(x.size() / 3, 0), Geometry::open(),
                   options(5.0, 9), x);
  EXPECT_THROW(dev.step(), rpyfmm::Error);
  EXPECT_EQ(dev.positions(), x);
  EXPECT_EQ(dev.step_count(), 0u);
}

TEST(DeviceScenarios, HostLauncherMatchesCpuEngine) {
  // The device test's runs on the launcher against the CPU Integrator (free draining): they are
  // valid runs, with rebuilds, and the launcher is the CPU engine there (bit for bit where the
  // build cannot fuse multiply-adds).
  for (const Scenario& c : scenarios()) {
    rpyfmm::bd::IntegratorOptions io;
    io.dt = c.options.dt;
    io.kT = c.options.kT;
    io.seed = c.options.seed;
    io.max_displacement = c.options.max_displacement;
    rpyfmm::bd::Integrator cpu(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(c.geometry, c.options.viscosity),
                               c.forces, io, c.x, c.types, c.options.neighbours);
    HostEngine host(c.forces, c.types, c.geometry, c.options, c.x);
    const int steps = kMayContract ? std::min(c.steps, 10) : c.steps;
    ASSERT_NO_THROW(cpu.run(static_cast<std::uint64_t>(steps))) << c.name;
    ASSERT_NO_THROW(host.run(static_cast<std::uint64_t>(steps))) << c.name;
    EXPECT_EQ(host.rebuilds(), cpu.neighbour_rebuilds()) << c.name;
    if (c.forces.has_pairs()) {
      EXPECT_GE(host.rebuilds(), kMayContract ? 1u : 3u) << c.name << ": too few rebuilds to test them";
    } else {
      EXPECT_EQ(host.rebuilds(), 1u) << c.name << ": without pairs the lists are built once";
    }
    double scale = 1.0;
    for (double v : c.x) scale = std::max(scale, std::abs(v));
    expect_close(host.positions(), cpu.positions(), std::vector<double>(c.x.size(), 1e-11 * scale), !kMayContract,
                 c.name.c_str());
  }
}

namespace {

/// The three parts, each counted (> 0: every part of these steps does work).
void expect_stage_times(const rpyfmm::StageTimes& times, const char* engine) {
  for (const char* part : {"neighbours", "forces", "update"}) {
    ASSERT_EQ(times.count(part), 1u) << engine << ": no " << part;
    EXPECT_GT(times.at(part), 0.0) << engine << ": " << part;
  }
  EXPECT_EQ(times.size(), 3u) << engine;
}

}  // namespace

TEST(DeviceEngine, HostStageTimesPerPart) {
  const Scenario c = scenarios().front();
  HostEngine host(c.forces, c.types, c.geometry, c.options, c.x);
  host.run(5);
  expect_stage_times(host.stage_times(), "host launcher");
}

TEST(DeviceEngine, DeviceStageTimesPerPart) {
  REQUIRE_BD_DEVICE();
  const Scenario c = scenarios().front();
  DeviceEngine dev(c.forces, c.types, c.geometry, c.options, c.x);
  dev.run(5);
  expect_stage_times(dev.stage_times(), "device engine");
}
