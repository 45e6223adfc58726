// Forces of the host launcher (bd/src/device) against the CPU engine: whole force fields (every
// pair potential, DLVO with the Born core between unequal radii, mixtures, bonds, external and
// global forces, the trap, open and periodic) against ForceField::compute, with the energy. The
// formulas are one implementation (device/pair_potentials.hpp); what differs is the compilation
// (host_engine.cpp with -ffp-contract=off) and the order of the sums. Bit for bit where the build cannot fuse
// multiply-adds (the stages do the CPU's operations in its order); else within the bound of docs/gpu-bd.md.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "compare.hpp"
#include "device/host_engine.hpp"
#include "device_systems.hpp"
#include "rpyfmm/core/error.hpp"

using namespace device_test;
using rpyfmm::bd::NeighbourList;
using rpyfmm::bd::device::EngineOptions;
using rpyfmm::bd::device::HostEngine;
using rpyfmm::rpy::Geometry;

namespace {

struct Case {
  const char* name;
  ForceField forces;
  std::vector<std::uint32_t> types;
  Geometry geometry;
  std::vector<double> x;
};

/// Launcher forces and energy against ForceField::compute over the CPU's list.
void compare_forces(const Case& c, const EngineOptions& options) {
  HostEngine host(c.forces, c.types, c.geometry, options, c.x);
  host.step();  // builds the rows, computes the forces at x (then moves)
  NeighbourList list(c.geometry, c.forces.max_cutoff(), options.neighbours);
  if (c.forces.has_pairs()) list.set_pair_cutoffs(c.types, c.forces.pair_cutoffs(), c.forces.types().size());
  list.build(c.x);
  std::vector<double> f(c.x.size());
  const double energy = c.forces.compute(c.x, c.types, list, 0, f);
  // Builds that fuse multiply-adds: 1e-10 of the system's largest force component (docs/gpu-bd.md:
  // on these lattices no pair term exceeds it tenfold, so the bound leaves 1e4 eps per term).
  double scale = 1.0;
  for (double v : f) scale = std::max(scale, std::abs(v));
  const std::vector<double> bound(f.size(), 1e-10 * scale);
  expect_close(host.forces(), f, bound, !kMayContract, c.name);
  if (kMayContract) {
    EXPECT_LE(std::abs(host.potential_energy() - energy),
              1e-10 * (std::abs(energy) + static_cast<double>(c.types.size())))
        << c.name;
  } else {
    EXPECT_EQ(host.potential_energy(), energy) << c.name;
  }
  EXPECT_NE(energy, 0.0) << c.name << ": no interaction, nothing compared";
}

}  // namespace

// Unequal radii: the DLVO and Born terms' a_i - a_j poles, and surface potentials of both signs.
// Types alternate along a lattice of odd side, so nearest neighbours are A-B pairs (contact 1.3)
// and A-A pairs (contact 2) lie a diagonal apart.
TEST(DeviceForces, DlvoWithBornBetweenUnequalRadii) {
  ForceField forces({ParticleType{"A", 1.0, {0.0, 0.0, 0.0}, 0.05}, ParticleType{"B", 0.3, {0.0, 0.0, 0.0}, -0.02}});
  PairPotential d;
  d.kind = PairKind::dlvo;
  d.hamaker = 2.0;
  d.permittivity = 500.0;
  d.kappa = 3.0;
  d.core = rpyfmm::bd::DlvoCore::born;
  for (std::uint32_t t1 = 0; t1 < 2; ++t1)
    for (std::uint32_t t2 = t1; t2 < 2; ++t2) forces.set_pair(t1, t2, d);
  const auto x = jittered_lattice(9, 2.15, 0.05, 51);
  EngineOptions o;
  o.dt = 1e-6;
  compare_forces({"dlvo with born, radii 1 and 0.3", forces, alternating_types(x.size() / 3), Geometry::open(), x}, o);
}

TEST(DeviceForces, EveryPotentialOpenAndPeriodic) {
  EngineOptions o;
  o.dt = 1e-6;
  // Jitter +-0.05 per coordinate: pairs within 0.18 of the spacing, outside the hard cores and
  // (DLVO) contact, inside the cut-offs.
  const int side = 9;
  for (PairKind kind : {PairKind::lj36_18, PairKind::wca, PairKind::soft, PairKind::dlvo}) {
    const double L = side * spacing(kind);
    const auto x = jittered_lattice(side, spacing(kind), 0.05, 20 + static_cast<unsigned>(kind));
    const std::vector<std::uint32_t> types(x.size() / 3, 0);
    compare_forces({rpyfmm::bd::to_string(kind), single_type(kind), types, Geometry::open(), x}, o);
    auto xp = x;
    unwrap_some(xp, L);
    compare_forces({rpyfmm::bd::to_string(kind), single_type(kind), types, Geometry::periodic(L), xp}, o);
  }
}

TEST(DeviceForces, MixtureBondsExternalGlobalAndTrap) {
  const int side = 10;
  const double h = 1.6, L = side * h;
  auto x = jittered_lattice(side, h, 0.05, 31);
  const std::size_t n = x.size() / 3;
  ForceField forces = mixture();
  add_chain_bonds(forces, n);
  EngineOptions o;
  o.dt = 1e-6;
  o.global_force = {0.0, 0.3, -0.1};
  forces.set_global_force(o.global_force);
  compare_forces({"mixture with bonds", forces, alternating_types(n), Geometry::periodic(L), x}, o);
  ForceField trapped = forces;
  trapped.set_trap(0.05);
  compare_forces({"mixture with bonds in a trap", trapped, alternating_types(n), Geometry::open(), x}, o);
}

TEST(DeviceForces, OverlapAndBrokenBondAreRefused) {
  auto x = jittered_lattice(5, 2.15, 0.05, 41);
  const std::size_t n = x.size() / 3;
  for (int c = 0; c < 3; ++c) x[3 * 7 + c] = x[3 * 8 + c] + (c == 0 ? 1.0 : 0.0);  // 7 and 8 at r = 1 < 1.6
  EngineOptions o;
  o.dt = 1e-6;
  HostEngine host(single_type(PairKind::lj36_18), std::vector<std::uint32_t>(n, 0), Geometry::open(), o, x);
  try {
    host.step();
    ADD_FAILURE() << "an overlap passed";
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), rpyfmm::ErrorCode::invalid_input);
    EXPECT_NE(std::string(e.what()).find("particle 7"), std::string::npos) << e.what();
  }
  EXPECT_EQ(host.step_count(), 0u);
  EXPECT_EQ(std::vector<double>(host.positions().begin(), host.positions().end()), x) << "state must be kept";
  // A FENE bond (maximum extension 6) over a pair 8 apart.
  ForceField bonded = single_type(PairKind::soft);
  const auto fene = bonded.add_bond_potential(BondPotential{BondKind::fene, 5.0, 6.0});
  const std::vector<rpyfmm::bd::Bond> bonds{{0, 1, fene}, {2, 60, fene}};
  bonded.add_bonds(bonds);
  auto y = jittered_lattice(5, 2.15, 0.05, 42);
  HostEngine chain(bonded, std::vector<std::uint32_t>(n, 0), Geometry::open(), o, y);
  EXPECT_THROW(chain.step(), rpyfmm::Error);
}
