// A free-draining trajectory of the host launcher (bd/src/device) against the CPU Integrator with
// the mobility "none": positions, forces and energies at every step, bit for bit where the build
// cannot fuse multiply-adds (the same operations in the same order, the same noise), else within
// the bound of docs/gpu-bd.md for the first steps; the same rebuild steps; and the blow-up guard
// refusing the same step with the state kept.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>

#include "compare.hpp"
#include "device/host_engine.hpp"
#include "device_systems.hpp"
#include "rpyfmm/bd/device/device_support.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/free_draining.hpp"

using namespace device_test;
using rpyfmm::bd::Integrator;
using rpyfmm::bd::IntegratorOptions;
using rpyfmm::bd::device::engine_options_for;
using rpyfmm::bd::device::HostEngine;
using rpyfmm::rpy::Geometry;

namespace {

/// Runs both engines `steps` steps, comparing after each. Builds that fuse: positions within
/// 1e-12 of the box scale per step taken (docs/gpu-bd.md), checked over the first 10 steps only.
/// A skin of 0.1 (the default `neighbours`) makes the lists rebuild every few steps.
void run_side_by_side(const ForceField& forces, const std::vector<std::uint32_t>& types, const Geometry& geometry,
                      const std::vector<double>& x, const IntegratorOptions& io, int steps, const char* what,
                      const rpyfmm::bd::NeighbourOptions& neighbours = {.skin = 0.1}) {
  const double eta = 0.7;
  Integrator cpu(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(geometry, eta), forces, io, x, types, neighbours);
  HostEngine host(forces, types, geometry, engine_options_for(io, cpu.mobility(), neighbours), x);
  double scale = 1.0;
  for (double v : x) scale = std::max(scale, std::abs(v));
  std::size_t rebuilds = 0;
  for (int s = 0; s < steps; ++s) {
    if (kMayContract && s >= 10) break;
    cpu.step();
    host.step();
    ASSERT_EQ(host.last_step_rebuilt(), cpu.last_report().neighbour_rebuild) << what << ", step " << s;
    const std::vector<double> bound(x.size(), 1e-12 * scale * (s + 1));
    expect_close(host.forces(), cpu.last_forces(), std::vector<double>(x.size(), 1e-10 * scale), !kMayContract, what);
    expect_close(host.positions(), cpu.positions(), bound, !kMayContract, what);
    if (!kMayContract) {
      ASSERT_EQ(host.potential_energy(), cpu.last_report().potential_energy) << what << ", step " << s;
    }
    if (::testing::Test::HasFailure()) {
      ADD_FAILURE() << what << ": first difference at step " << s;
      return;
    }
    rebuilds += host.last_step_rebuilt() ? 1 : 0;
  }
  EXPECT_EQ(host.step_count(), cpu.step_count());
  EXPECT_EQ(host.rebuilds(), cpu.neighbour_rebuilds()) << what;
  if (!kMayContract) {
    EXPECT_GE(rebuilds, 2u) << what << ": the lists were rebuilt too rarely to test the rebuilds";
  }
}

}  // namespace

// Lattices jittered by +-0.03 and time steps at which the largest step of a particle stays well
// below the guard (max_displacement = 1 radius) over the runs.

TEST(DeviceTrajectory, Lj3618PeriodicHundredSteps) {
  // The potential of Tran et al. (2015) (eps = 14 kT), positions unwrapped across the faces, 100 steps.
  const int side = 9;
  const double L = side * spacing(PairKind::lj36_18);
  auto x = jittered_lattice(side, spacing(PairKind::lj36_18), 0.03, 51);
  unwrap_some(x, L);
  run_side_by_side(single_type(PairKind::lj36_18), std::vector<std::uint32_t>(x.size() / 3, 0), Geometry::periodic(L),
                   x, integrator_options(2e-4, 1.0, 3), 100, "lj36_18 periodic");
}

TEST(DeviceTrajectory, MixtureWithBondsAndTrapOpenHundredSteps) {
  auto x = jittered_lattice(8, 1.6, 0.03, 52);
  const std::size_t n = x.size() / 3;
  ForceField forces = mixture();
  add_chain_bonds(forces, n);
  forces.set_trap(0.02);
  run_side_by_side(forces, alternating_types(n), Geometry::open(), x, integrator_options(2e-4, 1.0, 4), 100,
                   "mixture with bonds");
}

TEST(DeviceTrajectory, WcaDlvoAndDeterministicSoft) {
  const int side = 7;
  const std::vector<std::uint32_t> types(side * side * side, 0);
  const double Lw = side * spacing(PairKind::wca);
  run_side_by_side(single_type(PairKind::wca), types, Geometry::periodic(Lw),
                   jittered_lattice(side, spacing(PairKind::wca), 0.03, 53), integrator_options(2e-4, 1.0, 5), 100,
                   "wca");
  run_side_by_side(single_type(PairKind::dlvo), types, Geometry::open(),
                   jittered_lattice(side, spacing(PairKind::dlvo), 0.03, 54), integrator_options(1e-4, 1.0, 6), 100,
                   "dlvo");
  // Deterministic: soft spheres overlapping by a quarter of sigma push the lattice's surface out.
  run_side_by_side(single_type(PairKind::soft), types, Geometry::open(), jittered_lattice(side, 1.5, 0.03, 55),
                   integrator_options(0.5, 0.0, 7), 30, "soft, kT = 0");
}

TEST(DeviceTrajectory, FixedIntervalRebuildsAtTheSameSteps) {
  // The fixed-interval strategy of Tran et al. (2015) (Table 1), every 7 steps, with the default skin.
  auto x = jittered_lattice(8, spacing(PairKind::wca), 0.03, 57);
  run_side_by_side(single_type(PairKind::wca), std::vector<std::uint32_t>(x.size() / 3, 0), Geometry::open(), x,
                   integrator_options(2e-4, 1.0, 9), 40, "fixed interval", {.fixed_interval = 7});
}

TEST(DeviceTrajectory, BlowUpRefusedAtTheSameStep) {
  // A huge time step: the first step would move particles by more than a radius.
  auto x = jittered_lattice(5, 2.15, 0.03, 56);
  const std::vector<std::uint32_t> types(x.size() / 3, 0);
  const auto io = integrator_options(5.0, 1.0, 8);
  Integrator cpu(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(Geometry::open(), 1.0), single_type(PairKind::wca),
                 io, x, types);
  HostEngine host(single_type(PairKind::wca), types, Geometry::open(), engine_options_for(io, cpu.mobility(), {}), x);
  rpyfmm::ErrorCode cpu_code{}, host_code{};
  try {
    cpu.step();
  } catch (const rpyfmm::Error& e) {
    cpu_code = e.code();
  }
  try {
    host.step();
  } catch (const rpyfmm::Error& e) {
    host_code = e.code();
  }
  EXPECT_EQ(cpu_code, rpyfmm::ErrorCode::numerical_failure);
  EXPECT_EQ(host_code, cpu_code);
  EXPECT_EQ(host.step_count(), 0u);
  EXPECT_EQ(std::vector<double>(host.positions().begin(), host.positions().end()), x);
}
