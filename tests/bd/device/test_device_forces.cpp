// Forces of the host launcher (bd/src/device) against the CPU engine: each pair and bond
// formula against evaluate_pair / evaluate_bond, and whole force fields (every pair potential,
// mixtures, bonds, external and global forces, the trap, open and periodic) against
// ForceField::compute, with the energy. Bit for bit where the build cannot fuse multiply-adds
// (the stages do the CPU's operations in its order); else within the bound of docs/gpu-bd.md.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "compare.hpp"
#include "device/host_engine.hpp"
#include "device/pair_potentials.hpp"
#include "device_systems.hpp"
#include "rpyfmm/core/error.hpp"

using namespace device_test;
using rpyfmm::bd::EnergyForce;
using rpyfmm::bd::NeighbourList;
using rpyfmm::bd::PairTerm;
using rpyfmm::bd::device::EngineOptions;
using rpyfmm::bd::device::HostEngine;
using rpyfmm::rpy::Geometry;

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();

/// The bound of a value computed in a few dozen operations by two orderings of roundings:
/// 64 eps relative (docs/gpu-bd.md, bounds).
double formula_bound(double v) {
  return 64.0 * kEps * std::abs(v);
}

void expect_same_value(double device, double cpu, const char* what, double r) {
  if (kMayContract) {
    EXPECT_LE(std::abs(device - cpu), formula_bound(cpu)) << what << " at r = " << r;
  } else {
    EXPECT_EQ(device, cpu) << what << " at r = " << r;
  }
}

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

TEST(DeviceForces, PairFormulasMatchCpu) {
  for (PairKind kind : {PairKind::lj36_18, PairKind::wca, PairKind::soft, PairKind::dlvo}) {
    const ForceField f = single_type(kind);
    const PairTerm& t = f.pair(0, 0);
    // From the hard core (DLVO: from contact, where its logarithms are defined) to the cut-off.
    const double from = kind == PairKind::dlvo ? t.sigma : t.min_distance;
    for (int k = 1; k < 400; ++k) {
      const double r = from + (t.cutoff - from) * k / 400.0;
      const EnergyForce cpu = rpyfmm::bd::evaluate_pair(t, r);
      const EnergyForce dev = rpyfmm::bd::device::pair_energy_force(t, r);
      expect_same_value(dev.energy, cpu.energy, rpyfmm::bd::to_string(kind), r);
      expect_same_value(dev.s, cpu.s, rpyfmm::bd::to_string(kind), r);
    }
  }
  // Unequal radii: the DLVO and Born terms' a_i - a_j poles.
  PairPotential d;
  d.kind = PairKind::dlvo;
  d.hamaker = 2.0;
  d.permittivity = 500.0;
  d.kappa = 3.0;
  d.core = rpyfmm::bd::DlvoCore::born;
  const PairTerm t = rpyfmm::bd::resolve_pair(d, 1.0, 0.3, 0.05, -0.02);
  for (double r = 1.32; r < t.cutoff; r += 0.01) {
    expect_same_value(rpyfmm::bd::device::pair_energy_force(t, r).s, rpyfmm::bd::evaluate_pair(t, r).s, "dlvo", r);
  }
}

TEST(DeviceForces, BondFormulasMatchCpu) {
  for (BondKind kind : {BondKind::harmonic, BondKind::fene}) {
    const BondPotential b{kind, 30.0, 1.5};
    for (double r = 0.05; r < 1.5; r += 0.01) {
      const EnergyForce cpu = rpyfmm::bd::evaluate_bond(b, r);
      const EnergyForce dev = rpyfmm::bd::device::bond_energy_force(b, r);
      expect_same_value(dev.energy, cpu.energy, "bond", r);
      expect_same_value(dev.s, cpu.s, "bond", r);
    }
  }
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
