// The device engine behind Integrator (IntegratorOptions::engine; docs/gpu-bd.md): on the host
// launcher the Integrator's trajectory is the host launcher's (HostEngine, the device tests'
// reference) bit for bit, and the CPU engine's bit for bit where the build cannot fuse
// multiply-adds (else within the bound of docs/gpu-bd.md over the first steps), with the CPU
// engine's step reports and counters; a restart from positions and a step number continues bit
// for bit; engine_state() gives the engine's arrays in place; features the device engine lacks
// are refused by name; without a usable device the CUDA engine is refused at construction, saying
// why; and the engine is chosen from a mobility spec as a run configuration asks for it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "compare.hpp"
#include "device/host_engine.hpp"
#include "device_systems.hpp"
#include "require_device.hpp"
#include "rpyfmm/bd/device/device_support.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/step_engine.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/free_draining.hpp"

using namespace device_test;
using rpyfmm::bd::engine_mobility;
using rpyfmm::bd::Integrator;
using rpyfmm::bd::IntegratorOptions;
using rpyfmm::bd::NeighbourOptions;
using rpyfmm::bd::step_engine_for;
using rpyfmm::bd::StepEngine;
using rpyfmm::rpy::Geometry;

namespace {

constexpr double kEta = 0.7;
const NeighbourOptions kNeighbours{.skin = 0.1};  // rebuilds every few steps

/// A mixture (two types, a pair potential and cut-off per pair of types, external forces) with
/// harmonic and FENE bonds, a trap and a global force, in free space: 512 particles.
struct Mixture {
  std::vector<double> x = jittered_lattice(8, 1.6, 0.03, 61);
  std::vector<std::uint32_t> types = alternating_types(x.size() / 3);
  ForceField forces = [this] {
    ForceField f = mixture();
    add_chain_bonds(f, types.size());
    f.set_trap(0.02);
    f.set_global_force({0.1, -0.2, 0.05});
    return f;
  }();

  [[nodiscard]] Integrator integrator(StepEngine engine, const std::vector<double>& at = {},
                                      std::uint64_t first_step = 0) const {
    return Integrator(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(Geometry::open(), kEta), forces,
                      integrator_options(2e-4, 1.0, 4, engine), at.empty() ? x : at, types, kNeighbours, first_step);
  }
};

}  // namespace

// 60 steps on the host launcher: the host launcher's trajectory bit for bit; the CPU engine's
// positions, forces, energies, rebuild steps, reports and totals (bit for bit where the build
// cannot fuse; else positions within 1e-12 (step + 1) max|x| over the first 10 steps).
TEST(DeviceIntegrator, HostLauncherStepsAsTheLauncherAndTheCpuEngine) {
  const Mixture m;
  Integrator dev = m.integrator(StepEngine::host_launcher);
  Integrator cpu = m.integrator(StepEngine::cpu);
  rpyfmm::bd::device::HostEngine host(
      m.forces, m.types, Geometry::open(),
      rpyfmm::bd::device::engine_options_for(dev.options(), dev.mobility(), kNeighbours, m.forces.global_force()), m.x);
  EXPECT_EQ(copy(dev.positions()), m.x);
  EXPECT_EQ(copy(dev.last_forces()), std::vector<double>(m.x.size(), 0.0)) << "as the CPU engine before a step";
  double scale = 1.0;
  for (double v : m.x) scale = std::max(scale, std::abs(v));
  const int steps = kMayContract ? 10 : 60;
  for (int s = 0; s < steps; ++s) {
    const auto& rep = dev.step();
    cpu.step();
    host.step();
    ASSERT_EQ(copy(dev.positions()), copy(host.positions())) << "step " << s;
    ASSERT_EQ(copy(dev.last_forces()), copy(host.forces())) << "step " << s;
    ASSERT_EQ(rep.potential_energy, host.potential_energy()) << "step " << s;
    ASSERT_EQ(rep.neighbour_rebuild, cpu.last_report().neighbour_rebuild) << "step " << s;
    EXPECT_EQ(rep.mobility_products, cpu.last_report().mobility_products);
    EXPECT_EQ(rep.sqrt_iterations, cpu.last_report().sqrt_iterations);
    EXPECT_EQ(rep.shared_first_product, cpu.last_report().shared_first_product);
    const std::vector<double> bound(m.x.size(), 1e-12 * scale * (s + 1));
    expect_close(dev.positions(), cpu.positions(), bound, !kMayContract, "positions");
    expect_close(dev.last_forces(), cpu.last_forces(), std::vector<double>(m.x.size(), 1e-10 * scale), !kMayContract,
                 "forces");
    if (!kMayContract) {
      ASSERT_EQ(rep.potential_energy, cpu.last_report().potential_energy) << "step " << s;
    }
    ASSERT_FALSE(::testing::Test::HasFailure()) << "first difference at step " << s;
  }
  EXPECT_EQ(dev.step_count(), cpu.step_count());
  EXPECT_EQ(dev.time(), cpu.time());
  EXPECT_EQ(dev.neighbour_rebuilds(), cpu.neighbour_rebuilds());
  EXPECT_GE(dev.neighbour_rebuilds(), 3u) << "the run must rebuild its lists";
  EXPECT_EQ(dev.totals().steps, cpu.totals().steps);
  EXPECT_EQ(dev.totals().mobility_products, cpu.totals().mobility_products);
  EXPECT_EQ(dev.totals().sqrt_iterations, cpu.totals().sqrt_iterations);
  for (const char* part : {"neighbours", "forces", "update"}) EXPECT_GT(dev.totals().seconds.at(part), 0.0) << part;
  for (const char* part : {"plan", "drift", "sqrt"}) EXPECT_EQ(dev.totals().seconds.at(part), 0.0) << part;
}

// engine_state(): the engine's own arrays in place (docs/python.md, "Device arrays"), equal to
// positions() and last_forces() at every step; the positions alternate between two arrays, the
// forces stay at one address; the CPU engine has none.
TEST(DeviceIntegrator, EngineStateIsTheEnginesArraysInPlace) {
  const Mixture m;
  Integrator dev = m.integrator(StepEngine::host_launcher);
  EXPECT_FALSE(m.integrator(StepEngine::cpu).engine_state().has_value());
  const auto first = dev.engine_state();
  ASSERT_TRUE(first.has_value());
  EXPECT_LT(first->device, 0) << "the host launcher's arrays are host memory";
  ASSERT_EQ(first->size, m.x.size());
  std::vector<const double*> addresses;
  for (int s = 0; s < 6; ++s) {
    dev.step();
    const auto state = dev.engine_state();
    ASSERT_TRUE(state.has_value());
    EXPECT_EQ(copy({state->positions, state->size}), copy(dev.positions())) << "step " << s;
    EXPECT_EQ(copy({state->forces, state->size}), copy(dev.last_forces())) << "step " << s;
    EXPECT_EQ(state->forces, first->forces) << "step " << s;
    addresses.push_back(state->positions);
  }
  for (std::size_t s = 2; s < addresses.size(); ++s) EXPECT_EQ(addresses[s], addresses[s - 2]) << "step " << s;
  EXPECT_NE(addresses[0], addresses[1]);
}

// Restarted from the positions and step number at step 25, the host launcher continues as the run
// straight through, bit for bit; the Integrator moves with its engine.
TEST(DeviceIntegrator, RestartFromPositionsAndStepContinuesBitForBit) {
  const Mixture m;
  Integrator whole = m.integrator(StepEngine::host_launcher);
  whole.run(25);
  Integrator restarted = m.integrator(StepEngine::host_launcher, copy(whole.positions()), whole.step_count());
  Integrator moved = std::move(restarted);
  whole.run(20);
  moved.run(20);
  EXPECT_EQ(moved.step_count(), 45u);
  EXPECT_EQ(copy(moved.positions()), copy(whole.positions()));
  EXPECT_EQ(moved.last_report().potential_energy, whole.last_report().potential_energy);
  EXPECT_EQ(moved.totals().steps, 20u);
}

// A step the blow-up guard refuses leaves the engine at the last good step, as on the CPU.
TEST(DeviceIntegrator, BlowUpKeepsTheLastGoodStep) {
  const auto x = jittered_lattice(5, 2.15, 0.03, 62);
  const std::vector<std::uint32_t> types(x.size() / 3, 0);
  Integrator dev(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(Geometry::open(), 1.0), single_type(PairKind::wca),
                 integrator_options(5.0, 1.0, 8, StepEngine::host_launcher), x, types);
  expect_blow_up_keeps_the_start(dev, x);
}

// Every feature the device engine lacks is refused at construction, naming it; the CPU list is
// refused by name on the device engine.
TEST(DeviceIntegrator, RefusesWhatTheDeviceEngineLacksByName) {
  const Mixture m;
  const auto on_host = [&](auto&& change) {
    return refusal([&] {
      ForceField forces = m.forces;
      IntegratorOptions o = integrator_options(2e-4, 1.0, 4, StepEngine::host_launcher);
      std::unique_ptr<rpyfmm::rpy::MobilityOperator> mobility =
          std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(Geometry::open(), kEta);
      change(forces, o, mobility);
      return Integrator(std::move(mobility), forces, o, m.x, m.types, kNeighbours);
    });
  };
  using Mobility = std::unique_ptr<rpyfmm::rpy::MobilityOperator>;
  EXPECT_NE(on_host([](ForceField&, IntegratorOptions&, Mobility& mob) {
              mob = std::make_unique<rpyfmm::rpy::DirectRpy>(Geometry::open(), kEta);
            }).find("free draining"),
            std::string::npos);
  EXPECT_NE(on_host([](ForceField&, IntegratorOptions& o, Mobility&) { o.rotation = true; }).find("rotation"),
            std::string::npos);
  EXPECT_NE(on_host([](ForceField&, IntegratorOptions& o, Mobility&) {
              o.inertia = {rpyfmm::bd::LangevinParticle{1.0, 2.0}};
            }).find("Langevin"),
            std::string::npos);
  EXPECT_NE(on_host([](ForceField&, IntegratorOptions& o, Mobility&) {
              o.keep_split_displacements = true;
            }).find("split displacements"),
            std::string::npos);
  EXPECT_NE(on_host([](ForceField& f, IntegratorOptions&, Mobility&) {
              f.add_callback([](std::span<const double>, std::uint64_t, std::span<double>) {});
            }).find("force callbacks"),
            std::string::npos);
  const Integrator dev = m.integrator(StepEngine::host_launcher);
  EXPECT_NE(refusal([&] { return dev.neighbour_list().size(); }).find("Verlet rows on the device"), std::string::npos);
  EXPECT_TRUE(dev.orientations().empty());
  EXPECT_TRUE(dev.deterministic_displacement().empty());
  EXPECT_TRUE(dev.inertial().empty());
}

// Without a usable device the CUDA engine is refused at construction with the reason.
TEST(DeviceIntegrator, CudaWithoutADeviceRefusedSayingWhy) {
  if (device_expected() || rpyfmm::bd::device::DeviceEngine::device_available())
    GTEST_SKIP() << "a usable CUDA device: the engine starts (CudaEngineStepsAsTheHostLauncher)";
  const std::string what = refusal([] { return Mixture().integrator(StepEngine::cuda); });
  EXPECT_TRUE(what.find("no usable CUDA device: ") != std::string::npos ||
              what.find("no CUDA support") != std::string::npos)
      << what;
}

// On a device: the CUDA engine behind the Integrator steps as the host launcher, bit for bit
// (a mixture without FENE bonds: only correctly rounded operations).
TEST(DeviceIntegrator, CudaEngineStepsAsTheHostLauncher) {
  REQUIRE_BD_DEVICE();
  auto x = jittered_lattice(9, spacing(PairKind::wca), 0.03, 63);
  const std::vector<std::uint32_t> types(x.size() / 3, 0);
  const auto make = [&](StepEngine engine) {
    return Integrator(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(Geometry::periodic(9 * 2.15), kEta),
                      single_type(PairKind::wca), integrator_options(2e-4, 1.0, 5, engine), x, types, kNeighbours);
  };
  Integrator dev = make(StepEngine::cuda);
  Integrator host = make(StepEngine::host_launcher);
  for (int s = 0; s < 30; ++s) {
    ASSERT_EQ(dev.step().potential_energy, host.step().potential_energy) << "step " << s;
    ASSERT_EQ(copy(dev.positions()), copy(host.positions())) << "step " << s;
  }
  EXPECT_EQ(dev.neighbour_rebuilds(), host.neighbour_rebuilds());
}

// The engine a mobility spec asks for: the device engine for device "cuda" with method "none"
// (on the launcher asked for; "pse": DevicePse.EngineChosenFromTheMobilitySpec), the CPU engine
// otherwise; its mobility is the CPU's "none".
TEST(DeviceIntegrator, EngineChosenFromTheMobilitySpec) {
  using rpyfmm::bd::DeviceLauncher;
  using rpyfmm::rpy::ComputeDevice;
  using rpyfmm::rpy::MobilityMethod;
  rpyfmm::rpy::MobilitySpec spec;
  spec.method = MobilityMethod::none;
  spec.viscosity = kEta;
  EXPECT_EQ(step_engine_for(spec), StepEngine::cpu);
  spec.device = ComputeDevice::cuda;
  EXPECT_EQ(step_engine_for(spec), StepEngine::cuda);
  EXPECT_EQ(step_engine_for(spec, DeviceLauncher::host), StepEngine::host_launcher);
  const auto mobility = engine_mobility(spec, StepEngine::host_launcher, 10);
  EXPECT_EQ(mobility->name(), "none");
  EXPECT_EQ(mobility->viscosity(), kEta);
  spec.method = MobilityMethod::direct;
  EXPECT_EQ(step_engine_for(spec, DeviceLauncher::host), StepEngine::cpu) << "no device engine for direct sums";
  EXPECT_STREQ(to_string(StepEngine::host_launcher), "host launcher");
  EXPECT_STREQ(to_string(StepEngine::cuda), "cuda");
  EXPECT_STREQ(to_string(StepEngine::cpu), "cpu");
}
