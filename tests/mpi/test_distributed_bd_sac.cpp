// The SAC scheme across ranks (rpyfmm/mpi/brownian_dynamics.hpp; Algorithm 2 of Tran et al. (2015),
// docs/theory/bd.md Sec. 9) against the serial engine, bd::Integrator with the scheme on the whole
// set: after every step the positions, the carriers' half-step velocities and each particle's
// complex are the serial engine's bit for bit, and so are the numbers of complexes and adsorbed
// particles, on any number of ranks, for any input split, with a repartition at every rebuild, and
// across a checkpoint written on 2 ranks and continued on P. Complexes straddle ranks: a carrier's
// adsorbed particles on other ranks (counted) add their forces to the carrier's and take its step.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numbers>
#include <numeric>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/sac.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"
#include "rpyfmm/rpy/free_draining.hpp"

namespace {

using rpyfmm::ErrorCode;
using rpyfmm::bd::Complexes;
using rpyfmm::bd::ForceField;
using rpyfmm::bd::PairKind;
using rpyfmm::mpi::BdShare;
using rpyfmm::mpi::DistributedBd;
using rpyfmm::mpi::DistributedBdOptions;
using rpyfmm::rpy::Geometry;
using namespace rpyfmm_mpi_test;

constexpr double kSpacing = 5.0;  // carrier lattice
constexpr int kSide = 3;          // kSide^3 carriers
const Geometry kBox = Geometry::periodic(kSide * kSpacing);

// Carriers "L" (type 0: radius 1, inertial) on a jittered lattice, each with 4 adsorbers "S"
// (type 1: radius 0.25, Brownian) at 1.3 from its centre in random directions, inside
// R_A = 1.5 x 1.25 = 1.875, and a free adsorber between carriers. Types: 0 carrier, 1 adsorber.
struct System {
  std::vector<double> x;
  std::vector<std::uint32_t> types;
  [[nodiscard]] std::size_t size() const { return types.size(); }
};

System complexes_in_a_box(std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  std::normal_distribution<double> direction(0.0, 1.0);
  System s;
  const auto add = [&](const std::array<double, 3>& p, std::uint32_t type) {
    s.x.insert(s.x.end(), p.begin(), p.end());
    s.types.push_back(type);
  };
  for (int i = 0; i < kSide; ++i)
    for (int j = 0; j < kSide; ++j)
      for (int l = 0; l < kSide; ++l) {
        const std::array<double, 3> c{(i + 0.5) * kSpacing + jitter(rng), (j + 0.5) * kSpacing + jitter(rng),
                                      (l + 0.5) * kSpacing + jitter(rng)};
        add(c, 0);
        for (int a = 0; a < 4; ++a) {
          std::array<double, 3> u{direction(rng), direction(rng), direction(rng)};
          const double norm = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
          add({c[0] + 1.3 * u[0] / norm, c[1] + 1.3 * u[1] / norm, c[2] + 1.3 * u[2] / norm}, 1);
        }
        add({c[0] + 0.5 * kSpacing, c[1] + 0.5 * kSpacing, c[2]}, 1);
      }
  return s;
}

// Soft repulsion between carriers and adsorbers and among adsorbers (cut-offs 1.25 and 0.5, both
// below R_A: the halo's reach is the adsorption radius), or no pair potentials at all (the halo is
// there for the complexes alone); a constant pull along x in both. With `callback` also a force
// callback on the whole system, 0.2 sin(x) per coordinate (it sees the forces from outside the
// complexes, as serially).
ForceField sac_forces(bool pairs, bool callback = false) {
  rpyfmm::bd::ParticleType l{.name = "L", .radius = 1.0};
  rpyfmm::bd::ParticleType a{.name = "S", .radius = 0.25};
  ForceField forces({l, a});
  if (pairs) {
    forces.set_pair(0, 1, {.kind = PairKind::soft, .epsilon = 5.0});
    forces.set_pair(1, 1, {.kind = PairKind::soft, .epsilon = 5.0});
  }
  forces.set_global_force({0.5, 0.0, 0.0});
  if (callback)
    forces.add_callback([](std::span<const double> x, std::uint64_t, std::span<double> f) {
      for (std::size_t k = 0; k < x.size(); ++k) f[k] += 0.2 * std::sin(x[k]);
    });
  return forces;
}

// The carriers' mass makes gamma dt / m = 1 (between the overdamped and the inertial regime).
DistributedBdOptions sac_options(std::uint64_t seed) {
  DistributedBdOptions o;
  o.integrator.dt = 1e-3;
  o.integrator.kT = 1.0;
  o.integrator.seed = seed;
  const double friction = 6.0 * std::numbers::pi * kViscosity * 1.0;
  o.integrator.inertia = {rpyfmm::bd::LangevinParticle{.mass = friction * 1e-3, .friction = friction}};
  o.integrator.sac = {.enabled = true, .adsorption_factor = 1.5};
  o.viscosity = kViscosity;
  o.repartition_imbalance = 1.0;  // every rebuild moves particles between ranks
  return o;
}

rpyfmm::bd::Integrator serial_engine(const ForceField& forces, const DistributedBdOptions& o, const System& s) {
  return {std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(kBox, o.viscosity),
          forces,
          o.integrator,
          s.x,
          s.types,
          o.neighbours};
}

// This rank's contiguous piece of `split` of the particles in the order of a random permutation.
BdShare shuffled_share(const System& s, Split split, std::uint64_t seed) {
  std::vector<std::size_t> order(s.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::shuffle(order.begin(), order.end(), std::mt19937_64(seed));
  const auto counts = split_counts(s.size(), static_cast<std::size_t>(world_size()), split);
  const std::size_t first = std::accumulate(counts.begin(), counts.begin() + world_rank(), std::size_t{0});
  BdShare share;
  for (std::size_t k = first; k < first + counts[static_cast<std::size_t>(world_rank())]; ++k) {
    const std::size_t i = order[k];
    share.positions.insert(share.positions.end(), &s.x[3 * i], &s.x[3 * i + 3]);
    share.types.push_back(s.types[i]);
    share.ids.push_back(i);
  }
  return share;
}

// The owned particles' disagreements with the serial engine (positions, velocities, the forces the
// last step used, complex ids), summed over the ranks, and the adsorbed particles whose carrier
// another rank owns.
struct Comparison {
  std::uint64_t differences = 0;
  std::uint64_t straddling = 0;
};

Comparison compare(const DistributedBd& bd, const rpyfmm::bd::Integrator& serial, bool forces = true) {
  const auto x = serial.positions();
  const auto v = serial.inertial().velocities();
  const auto f = serial.last_forces();
  const auto owner = serial.complexes().owner();
  std::uint64_t mine[2] = {0, 0}, all[2] = {0, 0};
  for (std::size_t i = 0; i < bd.local_size(); ++i) {
    const std::uint64_t id = bd.ids()[i];
    for (std::size_t c = 0; c < 3; ++c) {
      mine[0] += bd.positions()[3 * i + c] != x[3 * id + c] ? 1 : 0;
      mine[0] += bd.velocities()[3 * i + c] != v[3 * id + c] ? 1 : 0;
      mine[0] += forces && bd.last_forces()[3 * i + c] != f[3 * id + c] ? 1 : 0;
    }
    const std::uint32_t complex = bd.complex_ids()[i];
    mine[0] += complex != owner[id] ? 1 : 0;
    if (complex != Complexes::kFree && complex != id)
      mine[1] += std::binary_search(bd.ids().begin(), bd.ids().end(), std::uint64_t{complex}) ? 0 : 1;
  }
  MPI_Allreduce(mine, all, 2, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  return {all[0], all[1]};
}

// Steps both engines `steps` times, checking the state and the complexes' counts after each.
// Returns the adsorbed particles on another rank than their carrier, summed over the steps.
std::uint64_t expect_lockstep(DistributedBd& bd, rpyfmm::bd::Integrator& serial, int steps, const std::string& what) {
  std::uint64_t straddling = 0;
  for (int k = 0; k < steps; ++k) {
    bd.step();
    serial.step();
    const Comparison c = compare(bd, serial);
    EXPECT_EQ(c.differences, 0u) << what << ", step " << bd.step_count();
    straddling += c.straddling;
    const std::array<std::uint64_t, 2> counts = bd.complex_counts();
    EXPECT_EQ(counts[0], serial.complexes().count()) << what << ", step " << bd.step_count();
    EXPECT_EQ(counts[1], serial.complexes().adsorbed_total()) << what << ", step " << bd.step_count();
  }
  return straddling;
}

TEST(MpiDistributedBdSac, TrajectoryAndComplexesEqualTheSerialEngineBitForBitForEverySplit) {
  // 162 particles (27 complexes of 1 + 4, 27 free adsorbers), 30 steps, with and without pair
  // potentials, and with pairs and a callback. Equality is exact: each particle's forces, noise
  // and step are the serial engine's arithmetic on the same values in the same order
  // (bd_complexes.cpp).
  const System s = complexes_in_a_box(5);
  for (const int variant : {0, 1, 2}) {
    const bool pairs = variant != 1, callback = variant == 2;
    const DistributedBdOptions o = sac_options(23 + static_cast<std::uint64_t>(variant));
    for (const Split split : kSplits) {
      const std::string what = std::string(pairs ? "soft pairs" : "no pairs") + (callback ? " and a callback" : "") +
                               ", split " + std::to_string(static_cast<int>(split));
      rpyfmm::bd::Integrator serial = serial_engine(sac_forces(pairs, callback), o, s);
      DistributedBd bd(MPI_COMM_WORLD, sac_forces(pairs, callback), kBox, o, shuffled_share(s, split, 9));
      // The complexes at the start (27 carriers with 4 each), before any step.
      EXPECT_EQ(compare(bd, serial).differences, 0u) << what;
      EXPECT_EQ(bd.complex_counts(), (std::array<std::uint64_t, 2>{27, 108})) << what;
      const std::uint64_t straddling = expect_lockstep(bd, serial, 30, what);
      EXPECT_GE(bd.stats().rebuilds, 2u) << what;
      if (world_size() > 1) {
        EXPECT_GT(straddling, 0u) << what << ": no complex straddled two ranks";
      }
      // The potential energy of the last step: a sum over the ranks in another order than the
      // serial engine's, so equal to round-off (~160 terms of size <= 5: below 1e-12 absolute).
      EXPECT_NEAR(bd.potential_energy(), serial.last_report().potential_energy, 1e-12) << what;
    }
  }
}

TEST(MpiDistributedBdSac, CheckpointWrittenOnTwoRanksContinuesOnAllRanksBitForBit) {
  const System s = complexes_in_a_box(7);
  const DistributedBdOptions o = sac_options(31);
  rpyfmm::bd::Integrator serial = serial_engine(sac_forces(true), o, s);
  serial.run(15);
  // The first 15 steps on ranks 0 and 1 only; the checkpoint on rank 0 holds no membership (it is
  // a function of the positions).
  rpyfmm::bd::Checkpoint written;
  MPI_Comm two = MPI_COMM_NULL;
  MPI_Comm_split(MPI_COMM_WORLD, world_rank() < 2 ? 0 : MPI_UNDEFINED, world_rank(), &two);
  if (two != MPI_COMM_NULL) {
    DistributedBd first(two, sac_forces(true), kBox, o, [&] {
      BdShare share;
      if (world_rank() == 0) {
        share.positions = s.x;
        share.types = s.types;
      }
      return share;
    }());
    first.run(15);
    written = first.checkpoint(0);
    MPI_Comm_free(&two);
  }
  DistributedBd bd = rpyfmm::mpi::restart_distributed_bd(MPI_COMM_WORLD, sac_forces(true), kBox, o, written);
  EXPECT_EQ(bd.step_count(), 15u);
  EXPECT_EQ(compare(bd, serial, false).differences, 0u);  // a checkpoint holds no forces
  (void)expect_lockstep(bd, serial, 15, "restarted on " + std::to_string(world_size()) + " ranks");
}

TEST(MpiDistributedBdSac, OptionsTheSerialEngineRefusesFailEveryRank) {
  const System s = complexes_in_a_box(3);
  const BdShare share = shuffled_share(s, Split::even, 1);
  {  // no carrier type
    DistributedBdOptions o = sac_options(1);
    o.integrator.inertia.clear();
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, sac_forces(true), kBox, o, share); },
                            ErrorCode::invalid_argument, "needs carriers");
  }
  {  // bonds
    ForceField bonded = sac_forces(true);
    bonded.add_bond_potential({.kind = rpyfmm::bd::BondKind::harmonic, .k = 1.0, .length = 1.3});
    const rpyfmm::bd::Bond bond{.i = 0, .j = 1, .type = 0};
    bonded.add_bonds(std::span<const rpyfmm::bd::Bond>(&bond, 1));
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, bonded, kBox, sac_options(1), share); },
                            ErrorCode::invalid_argument, "does not support bonds");
  }
  {  // a bad adsorption factor
    DistributedBdOptions o = sac_options(1);
    o.integrator.sac.adsorption_factor = 0.0;
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, sac_forces(true), kBox, o, share); },
                            ErrorCode::invalid_argument, "adsorption_factor must be finite and > 0");
  }
  {  // carriers only
    BdShare carriers = share;
    std::fill(carriers.types.begin(), carriers.types.end(), 0u);
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, sac_forces(true), kBox, sac_options(1), carriers); },
                            ErrorCode::invalid_input, "one adsorbing (Brownian) particle");
  }
}

}  // namespace
