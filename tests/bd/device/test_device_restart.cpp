// Restarts and thread counts of the host launcher (bd/src/device), and restarts of the CUDA engine
// where a device is usable: a run restarted from its positions and step number continues bit for
// bit (the lists are rebuilt at the restart, and sorted rows make the forces independent of when
// they were built, as in the CPU engine: docs/theory/bd.md); the launcher's results do not depend
// on the number of OpenMP threads (atomic binning, store_min slots).
#include <gtest/gtest.h>
#include <omp.h>

#include <vector>

#include "device/host_engine.hpp"
#include "device_systems.hpp"
#include "require_device.hpp"
#include "rpyfmm/bd/device/device_engine.hpp"

using namespace device_test;
using rpyfmm::bd::device::DeviceEngine;
using rpyfmm::bd::device::EngineOptions;
using rpyfmm::bd::device::HostEngine;
using rpyfmm::rpy::Geometry;

namespace {

EngineOptions options() {
  EngineOptions o;
  o.dt = 2e-4;
  o.seed = 17;
  o.neighbours.skin = 0.1;
  return o;
}

struct System {
  ForceField forces = single_type(PairKind::lj36_18);
  std::vector<double> x;
  std::vector<std::uint32_t> types;
  Geometry geometry = Geometry::open();
};

/// 16^3 = 4096 particles (the launcher's loops run on the OpenMP threads from 4096 items on).
System lattice_system() {
  System s;
  const int side = 16;
  const double L = side * spacing(PairKind::lj36_18);
  s.x = jittered_lattice(side, spacing(PairKind::lj36_18), 0.03, 71);
  unwrap_some(s.x, L);
  s.types.assign(s.x.size() / 3, 0);
  s.geometry = Geometry::periodic(L);
  return s;
}

/// Positions after `total` steps, run straight through and restarted after `first` steps.
template <class Engine, class Positions>
void expect_restart_continues(const System& s, int first, int total, Positions&& positions) {
  Engine straight(s.forces, s.types, s.geometry, options(), s.x);
  straight.run(total);
  Engine before(s.forces, s.types, s.geometry, options(), s.x);
  before.run(first);
  const std::vector<double> at = positions(before);
  Engine after(s.forces, s.types, s.geometry, options(), at, before.step_count());
  after.run(total - first);
  EXPECT_EQ(after.step_count(), straight.step_count());
  EXPECT_EQ(positions(after), positions(straight));
  EXPECT_GE(straight.rebuilds(), 3u) << "the restart must fall between rebuilds to test anything";
}

std::vector<double> host_positions(const HostEngine& e) {
  return {e.positions().begin(), e.positions().end()};
}

}  // namespace

TEST(DeviceRestart, HostLauncherContinuesBitForBit) {
  expect_restart_continues<HostEngine>(lattice_system(), 23, 60, host_positions);
}

TEST(DeviceRestart, HostLauncherIndependentOfThreads) {
  const System s = lattice_system();
  const int threads = omp_get_max_threads();
  std::vector<std::vector<double>> x;
  std::vector<std::vector<std::uint32_t>> rows;
  for (const int t : {1, 2}) {
    omp_set_num_threads(t);
    HostEngine e(s.forces, s.types, s.geometry, options(), s.x);
    e.run(30);
    x.push_back(host_positions(e));
    rows.push_back(e.neighbour_rows().indices);
  }
  omp_set_num_threads(threads);
  EXPECT_EQ(x[0], x[1]);
  EXPECT_EQ(rows[0], rows[1]);
}

TEST(DeviceRestart, DeviceEngineContinuesBitForBit) {
  REQUIRE_BD_DEVICE();
  expect_restart_continues<DeviceEngine>(lattice_system(), 23, 60, [](const DeviceEngine& e) { return e.positions(); });
}
