// Verlet rows of the host launcher (bd/src/device) against the CPU engine's NeighbourList: equal
// as sets for random, clustered and periodic configurations (positions unwrapped across the
// faces), on both of the CPU's build paths (cells, all pairs), and after every rebuild of a
// trajectory run side by side with the CPU Integrator.
#include <gtest/gtest.h>

#include <memory>

#include "compare.hpp"
#include "device/host_engine.hpp"
#include "device_systems.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/rpy/free_draining.hpp"

using namespace device_test;
using rpyfmm::bd::NeighbourList;
using rpyfmm::bd::NeighbourOptions;
using rpyfmm::bd::device::EngineOptions;
using rpyfmm::bd::device::HostEngine;
using rpyfmm::rpy::Geometry;

namespace {

/// Builds both lists for x and compares them row by row.
void compare_build(const ForceField& forces, const std::vector<std::uint32_t>& types, const Geometry& geometry,
                   const std::vector<double>& x, const char* what, NeighbourOptions options = {}) {
  EngineOptions o;
  o.dt = 1e-4;
  o.neighbours = options;
  HostEngine host(forces, types, geometry, o, x);
  host.build_lists();
  NeighbourList cpu(geometry, forces.max_cutoff(), options);
  cpu.set_pair_cutoffs(types, forces.pair_cutoffs(), forces.types().size());
  cpu.build(x);
  expect_same_rows(host.neighbour_rows(), cpu, what);
  EXPECT_GT(cpu.pair_entries(), 0u) << what << ": a test without pairs tests nothing";
}

}  // namespace

TEST(DeviceLists, RandomOpenMixture) {
  const auto forces = mixture();
  const auto x = uniform_cloud(3000, 30.0, 1);
  compare_build(forces, alternating_types(3000), Geometry::open(), x, "random open mixture");
}

TEST(DeviceLists, ClusteredOpen) {
  const auto forces = single_type(PairKind::lj36_18);
  const auto x = clustered_cloud(2000, 80.0, 3.0, 2);
  compare_build(forces, std::vector<std::uint32_t>(2000, 0), Geometry::open(), x, "clustered open",
                NeighbourOptions{.skin = 0.7});
}

TEST(DeviceLists, PeriodicUnwrapped) {
  const double L = 24.0;
  const auto forces = mixture();
  auto x = uniform_cloud(2500, L, 3);
  unwrap_some(x, L);
  compare_build(forces, alternating_types(2500), Geometry::periodic(L), x, "periodic cube");
  auto y = uniform_cloud(2000, 20.0, 4);
  unwrap_some(y, 20.0);
  compare_build(forces, alternating_types(2000), Geometry::periodic(20.0, 26.0, 17.0), y, "periodic box");
}

TEST(DeviceLists, PeriodicClusteredAcrossFaces) {
  // Clusters centred anywhere, so that many straddle the faces (coordinates outside [0, L)).
  const double L = 30.0;
  const auto forces = single_type(PairKind::wca);
  const auto x = clustered_cloud(2000, L, 2.0, 5);
  compare_build(forces, std::vector<std::uint32_t>(2000, 0), Geometry::periodic(L), x, "periodic clusters");
}

TEST(DeviceLists, LargeSystemsBinnedInParallel) {
  // 20000 particles: the launcher's loops run on the OpenMP threads (atomic ranks in any order,
  // then each cell sorted), open and periodic.
  const auto forces = mixture();
  const auto types = alternating_types(20000);
  compare_build(forces, types, Geometry::open(), uniform_cloud(20000, 60.0, 9), "20000 open");
  auto x = uniform_cloud(20000, 50.0, 10);
  unwrap_some(x, 50.0);
  compare_build(forces, types, Geometry::periodic(50.0), x, "20000 periodic");
}

TEST(DeviceLists, AllPairsPaths) {
  // Fewer than 64 particles, and a periodic box of fewer than 3 cells a side: the CPU compares all
  // pairs there, and so does the launcher.
  const auto forces = mixture();
  compare_build(forces, alternating_types(50), Geometry::open(), uniform_cloud(50, 6.0, 6), "50 particles");
  auto x = uniform_cloud(300, 8.0, 7);
  unwrap_some(x, 8.0);
  compare_build(forces, alternating_types(300), Geometry::periodic(8.0), x, "small periodic box");
}

TEST(DeviceLists, SameRowsAfterEveryRebuild) {
  // Soft spheres (overlaps allowed) with a large time step: the lists are rebuilt every few steps;
  // the launcher and the CPU Integrator must rebuild at the same steps with the same rows.
  for (const bool periodic : {false, true}) {
    const double L = 18.0;
    const auto forces = single_type(PairKind::soft);
    auto x = uniform_cloud(900, L, 8);
    if (periodic) unwrap_some(x, L);
    const Geometry geometry = periodic ? Geometry::periodic(L) : Geometry::open();
    const std::vector<std::uint32_t> types(900, 0);
    rpyfmm::bd::IntegratorOptions io;
    io.dt = 0.02;
    io.kT = 1.0;
    io.seed = 11;
    io.max_displacement = 2.0;
    rpyfmm::bd::Integrator cpu(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(geometry, 1.0), forces, io, x,
                               types);
    EngineOptions o;
    o.dt = io.dt;
    o.kT = io.kT;
    o.seed = io.seed;
    o.max_displacement = io.max_displacement;
    HostEngine host(forces, types, geometry, o, x);
    int rebuilds = 0;
    for (int s = 0; s < 40; ++s) {
      cpu.step();
      host.step();
      ASSERT_EQ(host.last_step_rebuilt(), cpu.last_report().neighbour_rebuild) << "step " << s;
      if (host.last_step_rebuilt()) {
        ++rebuilds;
        expect_same_rows(host.neighbour_rows(), cpu.neighbour_list(), periodic ? "periodic rebuild" : "open rebuild");
      }
    }
    EXPECT_GE(rebuilds, 5) << "too few rebuilds to test them";
  }
}
