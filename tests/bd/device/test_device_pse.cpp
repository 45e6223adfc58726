// The device engine with PSE hydrodynamic interactions (EngineOptions::pse; docs/gpu-bd.md,
// "PSE"): behind Integrator on the host launcher, the CPU engine's fused PSE step (one
// apply_with_noise of PseRpy at the step's positions, dx = U dt, the blow-up guard) bit for bit
// for a periodic WCA suspension, with the same reports and totals; a restart from positions and
// a step number continues bit for bit; a PSE run is refused by name where the device engine
// cannot take it (open geometry, a sampler other than the split one, rotation, PseRpy on the CUDA
// engine); the engine is chosen from a mobility spec with method "pse"; and on a device the CUDA
// engine (PseRpyCuda's device entry points) follows the host launcher within a stated bound.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "compare.hpp"
#include "device_systems.hpp"
#include "require_device.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/step_engine.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

using namespace device_test;
using rpyfmm::bd::Integrator;
using rpyfmm::bd::IntegratorOptions;
using rpyfmm::bd::NeighbourOptions;
using rpyfmm::bd::StepEngine;
using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::pse::PseOptions;

namespace {

constexpr double kEta = 0.7;
constexpr int kSide = 5;  // 125 WCA spheres of radius 1
const NeighbourOptions kNeighbours{.skin = 0.1};

/// PSE at 1e-4 with double-precision wave grids (the precision both back ends share; docs/theory/pse.md section 2).
PseOptions pse_options() {
  PseOptions o;
  o.tolerance = 1e-4;
  o.wave_precision = rpyfmm::rpy::pse::WavePrecision::double_precision;
  return o;
}

/// A periodic WCA suspension at volume fraction ~0.23 (a jittered lattice of 125 spheres).
struct Suspension {
  double box = kSide * spacing(PairKind::wca);
  std::vector<double> x = jittered_lattice(kSide, spacing(PairKind::wca), 0.03, 71);
  std::vector<std::uint32_t> types = std::vector<std::uint32_t>(x.size() / 3, 0);
  ForceField forces = single_type(PairKind::wca);

  [[nodiscard]] std::unique_ptr<rpyfmm::rpy::MobilityOperator> pse(StepEngine engine) const {
    if (engine == StepEngine::cuda)
      return std::make_unique<rpyfmm::rpy::pse::PseRpyCuda>(Geometry::periodic(box), kEta, pse_options());
    return std::make_unique<rpyfmm::rpy::pse::PseRpy>(Geometry::periodic(box), kEta, pse_options());
  }

  [[nodiscard]] Integrator integrator(StepEngine engine, double kT = 1.0, const std::vector<double>& at = {},
                                      std::uint64_t first_step = 0) const {
    return Integrator(pse(engine), forces, integrator_options(1e-3, kT, 9, engine), at.empty() ? x : at, types,
                      kNeighbours, first_step);
  }
};

double max_abs(std::span<const double> v) {
  double m = 1.0;
  for (double e : v) m = std::max(m, std::abs(e));
  return m;
}

/// `steps` steps of the host launcher against the CPU engine: positions, forces, energies,
/// rebuilds and reports bit for bit (builds that may fuse: positions within
/// 1e-12 (step + 1) max|x| over the first 10 steps, as the free-draining trajectories).
void expect_host_launcher_as_cpu(double kT, int steps, std::size_t min_rebuilds) {
  const Suspension s;
  Integrator dev = s.integrator(StepEngine::host_launcher, kT);
  Integrator cpu = s.integrator(StepEngine::cpu, kT);
  const double scale = max_abs(s.x);
  const int checked = kMayContract ? std::min(steps, 10) : steps;
  for (int k = 0; k < checked; ++k) {
    const auto& rep = dev.step();
    const auto& ref = cpu.step();
    const std::vector<double> bound(s.x.size(), 1e-12 * scale * (k + 1));
    expect_close(dev.positions(), cpu.positions(), bound, !kMayContract, "positions");
    expect_close(dev.last_forces(), cpu.last_forces(), std::vector<double>(s.x.size(), 1e-10 * scale), !kMayContract,
                 "forces");
    if (!kMayContract) {
      ASSERT_EQ(rep.potential_energy, ref.potential_energy) << "step " << k;
    }
    ASSERT_EQ(rep.neighbour_rebuild, ref.neighbour_rebuild) << "step " << k;
    ASSERT_EQ(rep.mobility_products, ref.mobility_products) << "step " << k;
    ASSERT_EQ(rep.sqrt_iterations, ref.sqrt_iterations) << "step " << k;
    ASSERT_FALSE(::testing::Test::HasFailure()) << "first difference at step " << k;
  }
  EXPECT_EQ(dev.step_count(), cpu.step_count());
  EXPECT_EQ(dev.neighbour_rebuilds(), cpu.neighbour_rebuilds());
  EXPECT_GE(dev.neighbour_rebuilds(), min_rebuilds) << "the run must rebuild its lists";
  EXPECT_EQ(dev.totals().mobility_products, cpu.totals().mobility_products);
  EXPECT_EQ(dev.totals().sqrt_iterations, cpu.totals().sqrt_iterations);
  for (const char* part : {"neighbours", "forces", "plan", "drift", "update"})
    EXPECT_GT(dev.totals().seconds.at(part), 0.0) << part;
}

}  // namespace

// 30 steps with Brownian motion: the host launcher's PSE step is the CPU engine's, bit for bit
// (the same forces, the same PseRpy calls on the same arrays, dx = U dt and the same guard).
TEST(DevicePse, HostLauncherStepsAsTheCpuEngine) {
  expect_host_launcher_as_cpu(1.0, 30, 2);
  const Suspension s;
  Integrator dev = s.integrator(StepEngine::host_launcher);
  dev.step();
  EXPECT_GT(dev.last_report().sqrt_iterations, 0) << "the split sampler's Lanczos ran";
  EXPECT_NE(copy(dev.positions()), s.x);
}

// Without noise (kT = 0) the step is U = M F alone, as on the CPU.
TEST(DevicePse, HostLauncherWithoutNoiseStepsAsTheCpuEngine) {
  expect_host_launcher_as_cpu(0.0, 20, 1);
}

// Restarted from the positions and step number at step 20, the host launcher continues as the run
// straight through, bit for bit (the operator is placed anew at every step).
TEST(DevicePse, RestartFromPositionsAndStepContinuesBitForBit) {
  const Suspension s;
  Integrator whole = s.integrator(StepEngine::host_launcher);
  whole.run(20);
  Integrator restarted = s.integrator(StepEngine::host_launcher, 1.0, copy(whole.positions()), whole.step_count());
  whole.run(15);
  restarted.run(15);
  EXPECT_EQ(restarted.step_count(), 35u);
  EXPECT_EQ(copy(restarted.positions()), copy(whole.positions()));
  EXPECT_EQ(restarted.last_report().potential_energy, whole.last_report().potential_energy);
  EXPECT_EQ(copy(restarted.last_forces()), copy(whole.last_forces()));
}

// A step the blow-up guard refuses leaves the engine at the last good step, as on the CPU.
TEST(DevicePse, BlowUpKeepsTheLastGoodStep) {
  const Suspension s;
  IntegratorOptions o = integrator_options(5.0, 1.0, 9, StepEngine::host_launcher);
  Integrator dev(s.pse(StepEngine::host_launcher), s.forces, o, s.x, s.types, kNeighbours);
  expect_blow_up_keeps_the_start(dev, s.x);
}

// What the device engine cannot take with PSE is refused at construction, naming it.
TEST(DevicePse, RefusesWhatTheDeviceEngineLacksByName) {
  const Suspension s;
  const auto on_host = [&](std::unique_ptr<rpyfmm::rpy::MobilityOperator> mobility, const IntegratorOptions& o) {
    return refusal([&] { return Integrator(std::move(mobility), s.forces, o, s.x, s.types, kNeighbours); });
  };
  const IntegratorOptions o = integrator_options(1e-3, 1.0, 9, StepEngine::host_launcher);
  // Open geometry: PSE's free-space operator is not the periodic one the engine runs.
  const std::string open = on_host(std::make_unique<rpyfmm::rpy::pse::OpenPseRpy>(kEta, pse_options()), o);
  EXPECT_NE(open.find("pse-open"), std::string::npos) << open;
  EXPECT_NE(open.find("periodic box"), std::string::npos) << open;
  IntegratorOptions lanczos = o;
  lanczos.sqrt.method = rpyfmm::rpy::SqrtMethod::lanczos;
  const std::string sampler = on_host(s.pse(StepEngine::host_launcher), lanczos);
  EXPECT_NE(sampler.find("split sampler"), std::string::npos) << sampler;
  EXPECT_NE(sampler.find("lanczos"), std::string::npos) << sampler;
  IntegratorOptions rotation = o;
  rotation.rotation = true;
  EXPECT_NE(on_host(s.pse(StepEngine::host_launcher), rotation).find("rotation"), std::string::npos);
  IntegratorOptions split = o;
  split.keep_split_displacements = true;
  EXPECT_NE(on_host(s.pse(StepEngine::host_launcher), split).find("split displacements"), std::string::npos);
  if (rpyfmm::bd::device::DeviceEngine::device_available()) {
    IntegratorOptions cuda = o;
    cuda.engine = StepEngine::cuda;
    const std::string cpu_operator = on_host(s.pse(StepEngine::host_launcher), cuda);
    EXPECT_NE(cpu_operator.find("'pse-cuda'"), std::string::npos) << cpu_operator;
  }
}

// The engine a mobility spec asks for: the device engine for device "cuda" with method "pse",
// whose operator is PseRpy on the host launcher (PseRpyCuda on the CUDA engine).
TEST(DevicePse, EngineChosenFromTheMobilitySpec) {
  using rpyfmm::bd::DeviceLauncher;
  using rpyfmm::rpy::ComputeDevice;
  using rpyfmm::rpy::MobilityMethod;
  rpyfmm::rpy::MobilitySpec spec;
  spec.method = MobilityMethod::pse;
  spec.geometry = Geometry::periodic(14.0);
  spec.viscosity = kEta;
  EXPECT_EQ(rpyfmm::bd::step_engine_for(spec), StepEngine::cpu);
  spec.device = ComputeDevice::cuda;
  EXPECT_EQ(rpyfmm::bd::step_engine_for(spec), StepEngine::cuda);
  EXPECT_EQ(rpyfmm::bd::step_engine_for(spec, DeviceLauncher::host), StepEngine::host_launcher);
  const auto mobility = rpyfmm::bd::engine_mobility(spec, StepEngine::host_launcher, 10);
  EXPECT_EQ(mobility->name(), "pse");
  EXPECT_EQ(mobility->viscosity(), kEta);
  if (rpyfmm::rpy::pse::PseRpyCuda::device_available()) {
    EXPECT_EQ(rpyfmm::bd::engine_mobility(spec, StepEngine::cuda, 10)->name(), "pse-cuda");
  }
  spec.method = MobilityMethod::automatic;  // PSE in a periodic box
  EXPECT_EQ(rpyfmm::bd::step_engine_for(spec, DeviceLauncher::host), StepEngine::host_launcher);
  EXPECT_EQ(rpyfmm::bd::engine_mobility(spec, StepEngine::host_launcher, 10)->name(), "pse");
  spec.geometry = Geometry::open();  // direct or FMM there
  EXPECT_EQ(rpyfmm::bd::step_engine_for(spec, DeviceLauncher::host), StepEngine::cpu);
  spec.method = MobilityMethod::direct;
  EXPECT_EQ(rpyfmm::bd::step_engine_for(spec, DeviceLauncher::host), StepEngine::cpu);
}

// On a device: the CUDA engine (forces and update kernels, PseRpyCuda::set_positions_device and
// apply_with_noise_device) against the host launcher (PseRpy). Same algorithm, same noise key,
// double wave grids on both; the device sums the real-space rows, the spreading and the FFTs in
// another order, so the velocities agree to ~1e-12 relative (pse_rpy_cuda.hpp), a position by
// that fraction of |U dt| per step. Bound: positions within 1e-12 (step + 1) max|x| over 10
// steps, the forces (then computed at positions that differ by that much) within 1e-8 max|F|.
TEST(DevicePse, CudaEngineFollowsTheHostLauncher) {
  REQUIRE_BD_DEVICE();
  if (!rpyfmm::rpy::pse::PseRpyCuda::device_available()) GTEST_SKIP() << "no device for PseRpyCuda";
  const Suspension s;
  Integrator dev = s.integrator(StepEngine::cuda);
  Integrator host = s.integrator(StepEngine::host_launcher);
  const double scale = max_abs(s.x);
  for (int k = 0; k < 10; ++k) {
    const auto& rep = dev.step();
    const auto& ref = host.step();
    expect_close(dev.positions(), host.positions(), std::vector<double>(s.x.size(), 1e-12 * scale * (k + 1)), false,
                 "positions");
    const double fmax = max_abs(host.last_forces());
    expect_close(dev.last_forces(), host.last_forces(), std::vector<double>(s.x.size(), 1e-8 * fmax), false, "forces");
    EXPECT_EQ(rep.neighbour_rebuild, ref.neighbour_rebuild) << "step " << k;
    ASSERT_FALSE(::testing::Test::HasFailure()) << "first difference at step " << k;
  }
  // The operator's host copy of the positions (those of the last step's product) is read back from
  // the device, wrapped into the box.
  const auto& op = dynamic_cast<const rpyfmm::rpy::pse::PseRpyCuda&>(dev.mobility());
  const auto wrapped = copy(op.positions());
  ASSERT_EQ(wrapped.size(), s.x.size());
  for (double v : wrapped) {
    EXPECT_GE(v, 0.0);
    EXPECT_LT(v, s.box);
  }
}
