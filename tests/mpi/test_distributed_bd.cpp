// Free-draining Brownian dynamics across ranks (rpyfmm/mpi/brownian_dynamics.hpp) against the
// serial engine, bd::Integrator with rpy::FreeDrainingMobility on the whole set: the positions after
// every step agree bit for bit on any number of ranks, for any input split, with repartitions, and
// across a checkpoint written on 2 ranks and continued on P. The reason the agreement is exact: each
// owned particle's force is summed over the same neighbours in the same order (its halo holds every
// neighbour, its part is ordered by global index) and its noise is keyed by its global index. With
// hydrodynamic interactions the positions follow the serial engine with the same operator to
// round-off (direct in free space, pse in a periodic box) or to the FMM's tolerance. With rotation
// the orientations agree as the positions do (free draining bit for bit, direct to round-off, fmm to
// the tolerance), also across a version 3 checkpoint. With inertial (Langevin) types beside
// Brownian ones the positions and half-step velocities are the serial engine's bit for bit, also
// across a version 4 checkpoint. The split displacements (M F dt and the Brownian part) are the
// serial engine's as the positions are, and sum to the step; force callbacks on the whole system
// keep free-draining positions the serial engine's bit for bit.
#include <gtest/gtest.h>
#include <mpi.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <numbers>
#include <numeric>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/output.hpp"
#include "rpyfmm/bd/torque_field.hpp"
#include "rpyfmm/mpi/bd_stepper.hpp"
#include "rpyfmm/mpi/brownian_dynamics.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/free_draining.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace {

using rpyfmm::ErrorCode;
using rpyfmm::bd::ForceField;
using rpyfmm::bd::PairKind;
using rpyfmm::mpi::BdShare;
using rpyfmm::mpi::DistributedBd;
using rpyfmm::mpi::DistributedBdOptions;
using rpyfmm::rpy::Geometry;
using namespace rpyfmm_mpi_test;

// A whole system: positions and types, the same on every rank.
struct System {
  std::vector<double> x;
  std::vector<std::uint32_t> types;
  [[nodiscard]] std::size_t size() const { return types.size(); }
};

// k^3 particles on a cubic lattice of spacing h from the origin, jittered by up to 0.1 h, the type
// alternating between `ntypes` types.
System lattice(int k, double h, std::uint32_t ntypes, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.1 * h, 0.1 * h);
  System s;
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j)
      for (int l = 0; l < k; ++l) {
        for (const int c : {i, j, l}) s.x.push_back((c + 0.5) * h + jitter(rng));
        s.types.push_back(static_cast<std::uint32_t>(s.types.size() % ntypes));
      }
  return s;
}

// Two types (radii 0.5 and 0.7) with WCA pairs: a suspension in a periodic box or a cluster.
ForceField wca_mixture() {
  rpyfmm::bd::ParticleType a{.name = "A", .radius = 0.5};
  rpyfmm::bd::ParticleType b{.name = "B", .radius = 0.7};
  ForceField forces({a, b});
  for (std::uint32_t t1 = 0; t1 < 2; ++t1)
    for (std::uint32_t t2 = t1; t2 < 2; ++t2) forces.set_pair(t1, t2, {.kind = PairKind::wca});
  return forces;
}

// Attractive LJ 36-18 spheres of radius 0.5 in a harmonic trap, pulled along x.
ForceField sticky_trapped() {
  rpyfmm::bd::ParticleType a{.name = "A", .radius = 0.5};
  ForceField forces({a});
  forces.set_pair(0, 0, {.kind = PairKind::lj36_18, .epsilon = 1.0});
  forces.set_trap(0.05);
  forces.set_global_force({0.3, 0.0, 0.0});
  return forces;
}

DistributedBdOptions options_with(double dt, std::uint64_t seed = 7) {
  DistributedBdOptions o;
  o.integrator.dt = dt;
  o.integrator.kT = 1.0;
  o.integrator.seed = seed;
  o.viscosity = kViscosity;
  return o;
}

// The serial engine's positions after `steps` steps from step 0.
std::vector<double> serial_run(const ForceField& forces, const Geometry& geometry, const DistributedBdOptions& o,
                               const System& s, std::uint64_t steps) {
  rpyfmm::bd::Integrator bd(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(geometry, o.viscosity), forces,
                            o.integrator, s.x, s.types, o.neighbours);
  bd.run(steps);
  return {bd.positions().begin(), bd.positions().end()};
}

// This rank's share: the particles whose position in `order` (a permutation of the global indices)
// falls in its contiguous piece of `split`, with their global indices when `with_ids` and their
// orientations from `q` (4 per particle of the whole system) where it is not empty.
BdShare share_of(const System& s, Split split, const std::vector<std::size_t>& order, bool with_ids,
                 const std::vector<double>& q = {}) {
  const auto counts = split_counts(s.size(), static_cast<std::size_t>(world_size()), split);
  const std::size_t first = std::accumulate(counts.begin(), counts.begin() + world_rank(), std::size_t{0});
  BdShare share;
  for (std::size_t k = first; k < first + counts[static_cast<std::size_t>(world_rank())]; ++k) {
    const std::size_t i = order[k];
    share.positions.insert(share.positions.end(), &s.x[3 * i], &s.x[3 * i + 3]);
    share.types.push_back(s.types[i]);
    if (with_ids) share.ids.push_back(i);
    if (!q.empty()) share.orientations.insert(share.orientations.end(), &q[4 * i], &q[4 * i + 4]);
  }
  return share;
}

std::vector<std::size_t> identity(std::size_t n) {
  std::vector<std::size_t> v(n);
  std::iota(v.begin(), v.end(), std::size_t{0});
  return v;
}

std::vector<std::size_t> shuffled(std::size_t n, std::uint64_t seed) {
  std::vector<std::size_t> v = identity(n);
  std::shuffle(v.begin(), v.end(), std::mt19937_64(seed));
  return v;
}

// Every rank: `gathered` (rank 0's array; ignored elsewhere) equals `expected` bit for bit
// (checked on rank 0, its verdict broadcast so that every rank reports it).
void expect_gathered_bitwise(const std::vector<double>& gathered, const std::vector<double>& expected,
                             const std::string& what) {
  int mismatches = 0;
  double worst = 0.0;
  if (world_rank() == 0) {
    EXPECT_EQ(gathered.size(), expected.size()) << what;
    for (std::size_t k = 0; k < std::min(gathered.size(), expected.size()); ++k) {
      if (gathered[k] != expected[k]) {
        ++mismatches;
        worst = std::max(worst, std::abs(gathered[k] - expected[k]));
      }
    }
  }
  MPI_Bcast(&mismatches, 1, MPI_INT, 0, MPI_COMM_WORLD);
  MPI_Bcast(&worst, 1, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  EXPECT_EQ(mismatches, 0) << what << ": " << mismatches << " coordinates differ, by up to " << worst;
}

// Every rank: the gathered positions equal `expected` bit for bit.
void expect_positions_bitwise(const DistributedBd& bd, const std::vector<double>& expected, const std::string& what) {
  expect_gathered_bitwise(bd.checkpoint(0).positions, expected, what);
}

TEST(MpiDistributedBd, PeriodicSuspensionEqualsTheSerialEngineBitForBitForEverySplit) {
  // 512 spheres of two sizes, volume fraction 0.12 in a periodic box; 60 steps with several list
  // rebuilds (the skin is crossed every ~10 steps).
  const System s = lattice(8, 1.6, 2, 11);
  const Geometry box = Geometry::periodic(8 * 1.6);
  const DistributedBdOptions o = options_with(4e-3);
  const std::vector<double> expected = serial_run(wca_mixture(), box, o, s, 60);
  for (const Split split : kSplits) {
    DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, o, share_of(s, split, identity(s.size()), false));
    bd.run(60);
    expect_positions_bitwise(bd, expected, "split " + std::to_string(static_cast<int>(split)));
    EXPECT_EQ(bd.step_count(), 60u);
    EXPECT_GE(bd.stats().rebuilds, 3u);
    EXPECT_EQ(bd.global_size(), s.size());
  }
}

TEST(MpiDistributedBd, ShuffledIdsAndARepartitionAtEveryRebuildKeepTheSerialTrajectory) {
  // An open cluster of sticky spheres in a trap, drifting along x; the input shares are a random
  // permutation of the particles, and every rebuild moves particles between ranks.
  const System s = lattice(7, 1.3, 1, 5);
  const Geometry open = Geometry::open();
  DistributedBdOptions o = options_with(1e-3, 99);
  o.repartition_imbalance = 1.0;
  const std::vector<double> expected = serial_run(sticky_trapped(), open, o, s, 80);
  DistributedBd bd(MPI_COMM_WORLD, sticky_trapped(), open, o, share_of(s, Split::even, shuffled(s.size(), 3), true));
  bd.run(80);
  expect_positions_bitwise(bd, expected, "shuffled ids");
  EXPECT_GE(bd.stats().rebuilds, 2u);
  if (world_size() > 1) {
    EXPECT_EQ(bd.stats().repartitions, bd.stats().rebuilds);
  }
  // The ranks' particles are a partition of the whole set.
  unsigned long long local = bd.local_size(), total = 0;
  MPI_Allreduce(&local, &total, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
  EXPECT_EQ(total, s.size());
}

TEST(MpiDistributedBd, HilbertCurvePartitionsKeepTheSerialTrajectory) {
  // Partitions along the Hilbert curve at every rebuild, in a periodic box (the halo across the
  // faces) and in open space: free-draining positions do not depend on the partition, so they stay
  // the serial engine's bit for bit.
  const System s = lattice(7, 1.3, 1, 5);
  DistributedBdOptions o = options_with(1e-3, 99);
  o.repartition_imbalance = 1.0;
  o.curve = rpyfmm::mpi::SfcCurve::hilbert;
  for (const Geometry& geometry : {Geometry::open(), Geometry::periodic(7 * 1.3)}) {
    const std::vector<double> expected = serial_run(sticky_trapped(), geometry, o, s, 60);
    DistributedBd bd(MPI_COMM_WORLD, sticky_trapped(), geometry, o,
                     share_of(s, Split::even, shuffled(s.size(), 4), true));
    bd.run(60);
    expect_positions_bitwise(bd, expected, geometry.is_periodic() ? "hilbert, periodic" : "hilbert, open");
    EXPECT_GE(bd.stats().rebuilds, 2u);
    if (world_size() > 1) {
      EXPECT_EQ(bd.stats().repartitions, bd.stats().rebuilds);
    }
  }
  // A curve that differs between ranks fails on every rank.
  DistributedBdOptions other = o;
  if (world_size() > 1 && world_rank() == world_size() - 1) other.curve = rpyfmm::mpi::SfcCurve::morton;
  if (world_size() > 1) {
    expect_collective_error(
        [&] {
          DistributedBd bd(MPI_COMM_WORLD, sticky_trapped(), Geometry::open(), other,
                           share_of(s, Split::even, identity(s.size()), false));
        },
        ErrorCode::invalid_argument, "different options");
  }
}

// A config's [partition] section (docs/bd-config.md) sets the curve and the repartition policy of
// the run across ranks; without it the options keep DistributedBdOptions' defaults.
TEST(MpiDistributedBd, ConfigPartitionSectionSetsTheOptions) {
  const std::string base =
      "[particles]\nsource = \"random\"\ncount = 8\n[integrator]\ndt = 0.001\nsteps = 1\n"
      "[mobility]\nmethod = \"none\"\n";
  const DistributedBdOptions defaults = rpyfmm::mpi::distributed_bd_options(rpyfmm::bd::parse_config(base, "base"));
  EXPECT_EQ(defaults.curve, rpyfmm::mpi::SfcCurve::morton);
  EXPECT_EQ(defaults.repartition_imbalance, DistributedBdOptions{}.repartition_imbalance);
  EXPECT_EQ(defaults.repartition_cost, DistributedBdOptions::Cost::model);
  const DistributedBdOptions set = rpyfmm::mpi::distributed_bd_options(rpyfmm::bd::parse_config(
      base + "[partition]\ncurve = \"hilbert\"\nrepartition_imbalance = 2.5\nrepartition_cost = \"measured_time\"\n",
      "set"));
  EXPECT_EQ(set.curve, rpyfmm::mpi::SfcCurve::hilbert);
  EXPECT_EQ(set.repartition_imbalance, 2.5);
  EXPECT_EQ(set.repartition_cost, DistributedBdOptions::Cost::measured_time);
}

TEST(MpiDistributedBd, MeasuredTimeCostsRepartitionAndKeepTheSerialTrajectory) {
  // Costs from each rank's measured seconds (partitions that follow the timings, different from run
  // to run): free-draining positions do not depend on the partition, so they stay the serial
  // engine's bit for bit; with threshold 1 every rebuild moves particles on more than one rank.
  const System s = lattice(7, 1.3, 1, 5);
  const Geometry open = Geometry::open();
  DistributedBdOptions o = options_with(1e-3, 99);
  o.repartition_imbalance = 1.0;
  o.repartition_cost = DistributedBdOptions::Cost::measured_time;
  const std::vector<double> expected = serial_run(sticky_trapped(), open, o, s, 80);
  DistributedBd bd(MPI_COMM_WORLD, sticky_trapped(), open, o,
                   share_of(s, Split::geometric, shuffled(s.size(), 8), true));
  bd.run(80);
  expect_positions_bitwise(bd, expected, "measured-time costs");
  EXPECT_GE(bd.stats().rebuilds, 2u);
  if (world_size() > 1) {
    EXPECT_EQ(bd.stats().repartitions, bd.stats().rebuilds);
  }
  EXPECT_TRUE(std::isfinite(bd.stats().imbalance));
  EXPECT_GE(bd.stats().imbalance, 1.0);
}

// One type of spheres of radius 0.5, no potentials.
ForceField one_type() {
  return ForceField({rpyfmm::bd::ParticleType{.name = "A", .radius = 0.5}});
}

// Bead-spring chains: FENE bonds between neighbours along each lattice row of k beads, and weak
// harmonic bonds between particle p and p + N / 2 (half the system apart, so their partners lie on
// other ranks and far outside the list radius).
ForceField with_chains(ForceField forces, int k, bool long_bonds) {
  const auto fene = forces.add_bond_potential({.kind = rpyfmm::bd::BondKind::fene, .k = 5.0, .length = 3.0});
  const auto spring = forces.add_bond_potential({.kind = rpyfmm::bd::BondKind::harmonic, .k = 0.02, .length = 5.0});
  std::vector<rpyfmm::bd::Bond> bonds;
  const auto n = static_cast<std::uint32_t>(k * k * k);
  for (std::uint32_t p = 0; p < n; ++p) {
    if ((p + 1) % static_cast<std::uint32_t>(k) != 0) bonds.push_back({p, p + 1, fene});
    if (long_bonds && p < n / 2 && p % 7 == 0) bonds.push_back({p, p + n / 2, spring});
  }
  forces.add_bonds(bonds);
  return forces;
}

TEST(MpiDistributedBd, BondedChainsEqualTheSerialEngineBitForBit) {
  // 512 beads in 64 FENE chains of 8 with WCA pairs in a periodic box, and long harmonic bonds: each
  // bond's partner travels with the halo, and each owned bead sums its bonds in the serial order.
  const System s = lattice(8, 1.6, 2, 13);
  const Geometry box = Geometry::periodic(8 * 1.6);
  DistributedBdOptions o = options_with(2e-3, 21);
  const ForceField chains = with_chains(wca_mixture(), 8, true);
  const std::vector<double> expected = serial_run(chains, box, o, s, 60);
  for (const Split split : kSplits) {
    DistributedBd bd(MPI_COMM_WORLD, chains, box, o, share_of(s, split, shuffled(s.size(), 5), true));
    bd.run(60);
    expect_positions_bitwise(bd, expected, "chains, split " + std::to_string(static_cast<int>(split)));
    EXPECT_GE(bd.stats().rebuilds, 2u);
  }
  o.repartition_imbalance = 1.0;  // particles (and their bonds' partners) move at every rebuild
  DistributedBd moving(MPI_COMM_WORLD, chains, box, o, share_of(s, Split::even, identity(s.size()), false));
  moving.run(60);
  expect_positions_bitwise(moving, expected, "chains, a repartition at every rebuild");
}

TEST(MpiDistributedBd, BondsWithoutPairPotentialsEqualTheSerialEngineBitForBit) {
  // Harmonic chains in free space with no pair potential: no neighbour lists, a halo of bond
  // partners alone.
  const System s = lattice(5, 1.3, 1, 17);
  ForceField forces = one_type();
  const auto spring = forces.add_bond_potential({.kind = rpyfmm::bd::BondKind::harmonic, .k = 2.0, .length = 1.3});
  std::vector<rpyfmm::bd::Bond> bonds;
  for (std::uint32_t p = 0; p + 1 < 125; ++p) bonds.push_back({p, p + 1, spring});  // one chain through all
  forces.add_bonds(bonds);
  const DistributedBdOptions o = options_with(2e-3, 3);
  const std::vector<double> expected = serial_run(forces, Geometry::open(), o, s, 40);
  DistributedBd bd(MPI_COMM_WORLD, forces, Geometry::open(), o,
                   share_of(s, Split::geometric, shuffled(s.size(), 9), true));
  bd.run(40);
  expect_positions_bitwise(bd, expected, "a chain without pair potentials");
}

TEST(MpiDistributedBd, AnOverstretchedBondFailsEveryRankNamingItsGlobalIndices) {
  // Bond 1 joins particles 0 and 63, 8.3 apart, beyond its FENE maximum extension 3: the rank that
  // owns either end words the serial engine's error with global indices, every rank throws it.
  const System s = lattice(4, 1.6, 1, 2);
  ForceField forces = one_type();
  forces.set_pair(0, 0, {.kind = PairKind::wca});
  const auto fene = forces.add_bond_potential({.kind = rpyfmm::bd::BondKind::fene, .k = 5.0, .length = 3.0});
  forces.add_bonds(std::vector<rpyfmm::bd::Bond>{{0, 1, fene}, {0, 63, fene}});
  const Geometry open = Geometry::open();
  const DistributedBdOptions o = options_with(1e-3);
  DistributedBd bd(MPI_COMM_WORLD, forces, open, o, share_of(s, Split::geometric, shuffled(64, 4), true));
  expect_collective_error([&] { bd.step(); }, ErrorCode::invalid_input,
                          "bond 1 between particles 0 and 63 at step 0 is stretched");
  try {  // the serial engine's words
    rpyfmm::bd::Integrator serial(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(open, o.viscosity), forces,
                                  o.integrator, s.x, s.types, o.neighbours);
    serial.step();
    ADD_FAILURE() << "the serial engine took the step";
  } catch (const rpyfmm::Error& e) {
    EXPECT_NE(std::string(e.what()).find("bond 1 between particles 0 and 63 at step 0 is stretched"), std::string::npos)
        << e.what();
  }
}

TEST(MpiDistributedBd, EnergyIsTheSerialEnergyToRoundOff) {
  // The sum over ranks adds the particles' shares in another order: agreement to a few ulps of the
  // sum of their magnitudes, here bounded by 1e-12 relative.
  const System s = lattice(7, 1.3, 1, 5);
  const DistributedBdOptions o = options_with(1e-3, 99);
  rpyfmm::bd::Integrator serial(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(Geometry::open(), o.viscosity),
                                sticky_trapped(), o.integrator, s.x, s.types, o.neighbours);
  DistributedBd bd(MPI_COMM_WORLD, sticky_trapped(), Geometry::open(), o,
                   share_of(s, Split::geometric, identity(s.size()), false));
  for (int k = 0; k < 5; ++k) {
    const double e = serial.step().potential_energy;
    bd.step();
    EXPECT_NEAR(bd.potential_energy(), e, 1e-12 * std::abs(e)) << "step " << k;
  }
}

// The checkpoint, through its file, of `steps` steps of a run on ranks 0 and 1 alone (rank 0 alone
// on one rank), each taking half of the particles (with orientations from q where not empty): read
// on rank 0, empty elsewhere.
rpyfmm::bd::Checkpoint checkpoint_from_two_ranks(const System& s, const std::vector<double>& q,
                                                 const ForceField& forces, const Geometry& box,
                                                 const DistributedBdOptions& o, std::uint64_t steps) {
  const int writers = std::min(2, world_size());
  MPI_Comm first;
  MPI_Comm_split(MPI_COMM_WORLD, world_rank() < writers ? 0 : MPI_UNDEFINED, world_rank(), &first);
  const auto path = std::filesystem::temp_directory_path() / ("rpyfmm_mpi_bd_" + std::to_string(::getpid()) + ".chk");
  const std::string path_text = broadcast_from_root(path.string());
  if (first != MPI_COMM_NULL) {
    const std::size_t n = s.size(), half = n / 2;
    BdShare share;
    const std::size_t lo = world_rank() == 0 ? 0 : half, hi = writers == 1 || world_rank() == 1 ? n : half;
    for (std::size_t i = lo; i < hi; ++i) {
      share.positions.insert(share.positions.end(), &s.x[3 * i], &s.x[3 * i + 3]);
      share.types.push_back(s.types[i]);
      if (!q.empty()) share.orientations.insert(share.orientations.end(), &q[4 * i], &q[4 * i + 4]);
    }
    DistributedBd bd(first, forces, box, o, std::move(share));
    bd.run(steps);
    const rpyfmm::bd::Checkpoint c = bd.checkpoint(0);
    if (world_rank() == 0) rpyfmm::bd::write_checkpoint(path_text, c);
    MPI_Comm_free(&first);
  }
  rpyfmm::bd::Checkpoint read;
  if (world_rank() == 0) {
    read = rpyfmm::bd::read_checkpoint(path_text);
    std::filesystem::remove(path_text);
  }
  return read;
}

TEST(MpiDistributedBd, CheckpointWrittenOnTwoRanksContinuesOnAllRanksBitForBit) {
  const System s = lattice(6, 1.6, 2, 23);
  const Geometry box = Geometry::periodic(6 * 1.6);
  const DistributedBdOptions o = options_with(4e-3, 5);
  const std::vector<double> expected = serial_run(wca_mixture(), box, o, s, 40);
  // The first 20 steps on ranks 0 and 1 only (rank 0 alone on one rank).
  const rpyfmm::bd::Checkpoint read = checkpoint_from_two_ranks(s, {}, wca_mixture(), box, o, 20);
  DistributedBd bd = rpyfmm::mpi::restart_distributed_bd(MPI_COMM_WORLD, wca_mixture(), box, o, read);
  EXPECT_EQ(bd.step_count(), 20u);
  bd.run(20);
  expect_positions_bitwise(bd, expected, "restarted on " + std::to_string(world_size()) + " ranks");
  // The positions at step 0 travel with the particles.
  const rpyfmm::bd::Checkpoint end = bd.checkpoint(0);
  if (world_rank() == 0) {
    EXPECT_EQ(end.reference_positions, s.x);
  }
}

TEST(MpiDistributedBd, FewerParticlesThanRanksAndNoPairs) {
  // 3 particles, all on the last rank's input; without pair potentials there is no halo.
  System s{{0.0, 0.0, 0.0, 1.0, 0.5, 0.0, -2.0, 0.0, 1.0}, {0, 0, 0}};
  rpyfmm::bd::ParticleType a{.name = "A", .radius = 0.5, .external_force = {0.0, 0.0, -1.0}};
  ForceField forces({a});
  forces.set_trap(0.2);
  const DistributedBdOptions o = options_with(1e-2);
  const std::vector<double> expected = serial_run(forces, Geometry::open(), o, s, 25);
  DistributedBd bd(MPI_COMM_WORLD, forces, Geometry::open(), o, share_of(s, Split::last_only, identity(3), false));
  bd.run(25);
  expect_positions_bitwise(bd, expected, "3 particles");
  EXPECT_EQ(bd.stats().halo_size, 0u);
}

// With hydrodynamic interactions: the serial engine with the same exact operator (DirectRpy) and
// the same sampler (Lanczos without preconditioner, tolerance 1e-8).
rpyfmm::bd::Integrator serial_with_hi(const ForceField& forces, const DistributedBdOptions& o, const System& s) {
  return rpyfmm::bd::Integrator(std::make_unique<rpyfmm::rpy::DirectRpy>(Geometry::open(), o.viscosity), forces,
                                o.integrator, s.x, s.types, o.neighbours);
}

DistributedBdOptions hydrodynamic_options(rpyfmm::rpy::MobilityMethod method) {
  DistributedBdOptions o = options_with(2e-3, 17);
  o.method = method;
  o.fmm = {.tolerance = 1e-6, .leaf_capacity = 16};  // small leaves: most pairs in the far field
  o.integrator.sqrt = {.method = rpyfmm::rpy::SqrtMethod::lanczos,
                       .tolerance = 1e-8,
                       .preconditioner = rpyfmm::rpy::SqrtPreconditioner::none};
  return o;
}

// The largest coordinate difference between the gathered positions and `expected` (on every rank).
double largest_difference(const DistributedBd& bd, std::span<const double> expected) {
  const rpyfmm::bd::Checkpoint c = bd.checkpoint(0);
  double worst = 0.0;
  if (world_rank() == 0)
    for (std::size_t k = 0; k < expected.size(); ++k) worst = std::max(worst, std::abs(c.positions[k] - expected[k]));
  MPI_Bcast(&worst, 1, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  return worst;
}

TEST(MpiDistributedBd, DirectHydrodynamicsFollowTheSerialEngineToRoundOff) {
  // 125 sticky spheres in a trap, 12 steps. DistributedDirectRpy sums the same pairs as DirectRpy in
  // another order (the ranks' shares), so each product differs in its last bits; the Lanczos
  // iterations carry such differences to about 1e-14 of a displacement, and 12 steps of this smooth
  // force field do not amplify them beyond 1e-12 (measured: 2e-15 on 1-4 ranks; coordinates of order 5).
  const System s = lattice(5, 1.3, 1, 9);
  const DistributedBdOptions o = hydrodynamic_options(rpyfmm::rpy::MobilityMethod::direct);
  rpyfmm::bd::Integrator serial = serial_with_hi(sticky_trapped(), o, s);
  serial.run(12);
  DistributedBd bd(MPI_COMM_WORLD, sticky_trapped(), Geometry::open(), o,
                   share_of(s, Split::geometric, shuffled(s.size(), 2), true));
  bd.run(12);
  const double worst = largest_difference(bd, serial.positions());
  EXPECT_LT(worst, 1e-12);
  // The step moved the particles by far more than that: the comparison is not of the start.
  double moved = 0.0;
  for (std::size_t k = 0; k < s.x.size(); ++k) moved = std::max(moved, std::abs(serial.positions()[k] - s.x[k]));
  EXPECT_GT(moved, 1e-2);
}

TEST(MpiDistributedBd, FmmHydrodynamicsFollowTheExactOperatorToTheTolerance) {
  // One step with the FMM at 1e-6 against the serial engine with the exact operator: u differs by at
  // most ~1e-6 of |u| (the operator's contract), and w by the same through the operator plus the
  // two samplers' own errors (each <= 10 x 1e-8), so the displacements agree to 1e-5 of their norm
  // (measured: 1.6e-6 - 3.2e-6 on 1-4 ranks, with leaves of 16 points).
  const System s = lattice(5, 1.3, 1, 9);
  const DistributedBdOptions o = hydrodynamic_options(rpyfmm::rpy::MobilityMethod::fmm);
  rpyfmm::bd::Integrator serial = serial_with_hi(sticky_trapped(), o, s);
  serial.step();
  DistributedBd bd(MPI_COMM_WORLD, sticky_trapped(), Geometry::open(), o,
                   share_of(s, Split::even, identity(s.size()), false));
  bd.step();
  const rpyfmm::bd::Checkpoint c = bd.checkpoint(0);
  double diff2 = 0.0, step2 = 0.0;
  if (world_rank() == 0) {
    for (std::size_t k = 0; k < s.x.size(); ++k) {
      diff2 += std::pow(c.positions[k] - serial.positions()[k], 2);
      step2 += std::pow(serial.positions()[k] - s.x[k], 2);
    }
  }
  double ratio = std::sqrt(diff2 / std::max(step2, 1e-300));
  MPI_Bcast(&ratio, 1, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  EXPECT_LT(ratio, 1e-5);
}

// Spheres of radius 0.5 (PSE takes one radius) with WCA pairs, those of type B pulled along x: the
// pulled spheres drag the others through the periodic flow.
ForceField wca_pulled() {
  rpyfmm::bd::ParticleType a{.name = "A", .radius = 0.5};
  rpyfmm::bd::ParticleType b{.name = "B", .radius = 0.5, .external_force = {2.0, 0.0, 0.0}};
  ForceField forces({a, b});
  for (std::uint32_t t1 = 0; t1 < 2; ++t1)
    for (std::uint32_t t2 = t1; t2 < 2; ++t2) forces.set_pair(t1, t2, {.kind = PairKind::wca});
  return forces;
}

// The pse method with double wave-space grids (those of DistributedPseRpy) and the default sampler
// (automatic: PSE's split sampler, drift and noise fused).
DistributedBdOptions pse_options() {
  DistributedBdOptions o = options_with(2e-3, 31);
  o.method = rpyfmm::rpy::MobilityMethod::pse;
  o.pse.tolerance = 1e-4;
  o.pse.wave_precision = rpyfmm::rpy::pse::WavePrecision::double_precision;
  return o;
}

TEST(MpiDistributedBd, PseHydrodynamicsInAPeriodicBoxFollowTheSerialEngineToRoundOff) {
  // 125 spheres at volume fraction 0.065 in a periodic box, 10 steps, against bd::Integrator with
  // PseRpy on the whole set (the same options). DistributedPseRpy's fused drift and noise equal
  // PseRpy::apply_with_noise to round-off (the same sums in another order; tests/mpi/
  // test_distributed_pse.cpp), also with the real-space noise keyed by the global indices of
  // particles that the ranks hold in Morton order; the forces are the serial engine's bit for bit.
  // Ten steps of this smooth field carry the differences to about 1e-15 of the coordinates (of
  // order 10), bounded here by 1e-12.
  const System s = lattice(5, 2.0, 2, 13);
  const Geometry box = Geometry::periodic(5 * 2.0);
  const DistributedBdOptions o = pse_options();
  rpyfmm::bd::Integrator serial(std::make_unique<rpyfmm::rpy::pse::PseRpy>(box, o.viscosity, o.pse), wca_pulled(),
                                o.integrator, s.x, s.types, o.neighbours);
  serial.run(10);
  double moved = 0.0;
  for (std::size_t k = 0; k < s.x.size(); ++k) moved = std::max(moved, std::abs(serial.positions()[k] - s.x[k]));
  EXPECT_GT(moved, 1e-2);  // the comparison is not of the start
  for (const Split split : kSplits) {
    for (const bool shuffle : {false, true}) {
      const std::vector<std::size_t> order = shuffle ? shuffled(s.size(), 6) : identity(s.size());
      DistributedBd bd(MPI_COMM_WORLD, wca_pulled(), box, o, share_of(s, split, order, shuffle));
      bd.run(10);
      const double worst = largest_difference(bd, serial.positions());
      EXPECT_LT(worst, 1e-12) << "split " << static_cast<int>(split) << (shuffle ? ", shuffled ids" : "");
      if (world_rank() == 0 && split == Split::even)
        std::printf("  [bd pse] %d ranks%s: largest coordinate difference %.2e\n", world_size(),
                    shuffle ? ", shuffled ids" : "", worst);
    }
  }
}

TEST(MpiDistributedBd, PseWithoutNoiseIsTheSerialDrift) {
  // kT = 0: u = M F alone (PseRpy::apply), no sampler; the same bound as with noise.
  const System s = lattice(5, 2.0, 2, 3);
  const Geometry box = Geometry::periodic(5 * 2.0);
  DistributedBdOptions o = pse_options();
  o.integrator.kT = 0.0;
  rpyfmm::bd::Integrator serial(std::make_unique<rpyfmm::rpy::pse::PseRpy>(box, o.viscosity, o.pse), wca_pulled(),
                                o.integrator, s.x, s.types, o.neighbours);
  serial.run(5);
  DistributedBd bd(MPI_COMM_WORLD, wca_pulled(), box, o, share_of(s, Split::geometric, shuffled(s.size(), 1), true));
  bd.run(5);
  EXPECT_LT(largest_difference(bd, serial.positions()), 1e-12);
}

TEST(MpiDistributedBd, HydrodynamicsThatDoNotFitTheGeometryAreRefused) {
  const System s = lattice(4, 1.6, 2, 1);
  const auto refused = [&](const DistributedBdOptions& o, const Geometry& geometry, const std::string& text) {
    expect_collective_error(
        [&] {
          DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), geometry, o, share_of(s, Split::even, identity(64), false));
        },
        ErrorCode::not_supported, text);
  };
  const Geometry box = Geometry::periodic(6.4);
  refused(hydrodynamic_options(rpyfmm::rpy::MobilityMethod::direct), box, "a periodic box needs pse");
  refused(hydrodynamic_options(rpyfmm::rpy::MobilityMethod::fmm), box, "a periodic box needs pse");
  DistributedBdOptions o = pse_options();
  refused(o, Geometry::open(), "'pse' across ranks needs a periodic box");
  o.integrator.sqrt.method = rpyfmm::rpy::SqrtMethod::lanczos;
  refused(o, box, "split sampler");
  o = pse_options();
  o.method = rpyfmm::rpy::MobilityMethod::automatic;
  refused(o, box, "is not run across ranks");
  if (world_size() > 1) {  // a PSE option that differs between ranks
    o = pse_options();
    if (world_rank() == world_size() - 1) o.pse.tolerance = 1e-5;
    expect_collective_error(
        [&] { DistributedBd bd(MPI_COMM_WORLD, wca_pulled(), box, o, share_of(s, Split::even, identity(64), false)); },
        ErrorCode::invalid_argument, "different options");
  }
}

TEST(MpiDistributedBd, BadInputOnOneRankFailsEveryRank) {
  const System s = lattice(4, 1.6, 2, 1);
  const Geometry box = Geometry::periodic(4 * 1.6);
  const DistributedBdOptions o = options_with(1e-3);
  const int last = world_size() - 1;
  {  // a NaN coordinate on the last rank
    BdShare share = share_of(s, Split::even, identity(s.size()), false);
    if (world_rank() == last) share.positions[1] = std::nan("");
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, o, share); },
                            ErrorCode::invalid_input, "is not finite");
  }
  {  // an id given twice
    BdShare share = share_of(s, Split::even, identity(s.size()), true);
    if (world_rank() == last) share.ids.back() = 0;
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, o, share); },
                            ErrorCode::invalid_input, "given twice");
  }
  {  // an id beyond N
    BdShare share = share_of(s, Split::even, identity(s.size()), true);
    if (world_rank() == last) share.ids.back() = 1000;
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, o, share); },
                            ErrorCode::invalid_input, "is not below the number of particles");
  }
  {  // a dt that differs between ranks
    DistributedBdOptions other = o;
    if (world_rank() == last && world_size() > 1) other.integrator.dt = 2e-3;
    if (world_size() > 1) {
      expect_collective_error(
          [&] {
            DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, other, share_of(s, Split::even, identity(64), false));
          },
          ErrorCode::invalid_argument, "different options");
    }
  }
  {  // features of the serial engine that runs across ranks do not have
    ForceField bonded = wca_mixture();
    bonded.add_bonds(std::vector<rpyfmm::bd::Bond>{{0, 64, bonded.add_bond_potential({})}});
    expect_collective_error(
        [&] { DistributedBd bd(MPI_COMM_WORLD, bonded, box, o, share_of(s, Split::even, identity(64), false)); },
        ErrorCode::invalid_input, "bond (0, 64) refers to a particle >= N = 64");
    if (world_size() > 1) {  // callbacks on some ranks only (each rank would gather, or not)
      ForceField called = wca_mixture();
      if (world_rank() == last) called.add_callback([](auto, auto, auto) {});
      expect_collective_error(
          [&] { DistributedBd bd(MPI_COMM_WORLD, called, box, o, share_of(s, Split::even, identity(64), false)); },
          ErrorCode::invalid_argument, "different options");
    }
  }
  {  // no particle anywhere
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, o, BdShare{}); },
                            ErrorCode::invalid_input, "no particles");
  }
}

TEST(MpiDistributedBd, BlowUpAndOverlapFailEveryRankAndKeepTheState) {
  // Particle 37 pushed hard: the guard refuses the step on every rank, naming it by global index.
  System s = lattice(4, 1.6, 1, 2);
  rpyfmm::bd::ParticleType a{.name = "A", .radius = 0.5};
  rpyfmm::bd::ParticleType pushed{.name = "pushed", .radius = 0.5, .external_force = {1e4, 0.0, 0.0}};
  ForceField forces({a, pushed});
  for (std::uint32_t t1 = 0; t1 < 2; ++t1)
    for (std::uint32_t t2 = t1; t2 < 2; ++t2) forces.set_pair(t1, t2, {.kind = PairKind::wca});
  s.types[37] = 1;
  const Geometry box = Geometry::periodic(4 * 1.6);
  const DistributedBdOptions o = options_with(1e-2);
  DistributedBd bd(MPI_COMM_WORLD, forces, box, o, share_of(s, Split::geometric, shuffled(64, 8), true));
  const rpyfmm::bd::Checkpoint before = bd.checkpoint(0);
  expect_collective_error([&] { bd.step(); }, ErrorCode::numerical_failure, "blow-up at step 0: particle 37");
  const rpyfmm::bd::Checkpoint after = bd.checkpoint(0);
  if (world_rank() == 0) {
    EXPECT_EQ(before.positions, after.positions);
  }
  EXPECT_EQ(bd.step_count(), 0u);

  // Particles 5 and 40 inside each other's hard core: named by their global indices.
  System overlapping = lattice(4, 1.6, 2, 2);
  for (int c = 0; c < 3; ++c) overlapping.x[3 * 40 + c] = overlapping.x[3 * 5 + c] + (c == 0 ? 0.3 : 0.0);
  DistributedBd hard(MPI_COMM_WORLD, wca_mixture(), box, o, share_of(overlapping, Split::even, shuffled(64, 4), true));
  // The lowest failing rank words the error, from the side of the pair it owns.
  const std::string message =
      expect_collective_error([&] { hard.step(); }, ErrorCode::invalid_input, "overlap at step 0");
  EXPECT_TRUE(message.find("particles 5 and 40") != std::string::npos ||
              message.find("particles 40 and 5") != std::string::npos)
      << message;
}

// ---- Rotation (docs/theory/bd.md Sec. 7) ----

// Unit quaternions of n random orientations (normalized Gaussian 4-vectors).
std::vector<double> random_orientations(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::vector<double> q(4 * n);
  for (std::size_t i = 0; i < n; ++i) {
    double norm = 0.0;
    for (int c = 0; c < 4; ++c) norm += std::pow(q[4 * i + c] = normal(rng), 2);
    for (int c = 0; c < 4; ++c) q[4 * i + c] /= std::sqrt(norm);
  }
  return q;
}

// `forces` with dipoles on type 0 in a uniform field and a constant torque on type 1 (and on every
// particle): torques that depend on the orientation and differ between the types.
ForceField with_torques(ForceField forces) {
  const std::size_t types = forces.types().size();
  std::vector<rpyfmm::bd::TypeTorque> t(types);
  t[0].dipole = 3.0;
  if (types > 1) t[1].torque = {0.0, 0.0, 2.0};
  forces.set_torque_field(rpyfmm::bd::TorqueField(t, {0.5, 0.0, 0.0}, {0.0, 1.5, 0.0}));
  return forces;
}

DistributedBdOptions rotating(DistributedBdOptions o) {
  o.integrator.rotation = true;
  return o;
}

// The serial engine's state after `steps` steps with rotation: positions, orientations, the summed
// rotation vectors (as the run's log sums them) and the rotation moments' sums.
struct SerialRotation {
  std::vector<double> x, q, rotation_vectors;
  std::array<double, 2> moment_sums{};
  double energy = 0.0;
};

SerialRotation serial_rotation_run(std::unique_ptr<rpyfmm::rpy::MobilityOperator> mobility, const ForceField& forces,
                                   const DistributedBdOptions& o, const System& s, const std::vector<double>& q,
                                   std::uint64_t steps) {
  rpyfmm::bd::Integrator bd(std::move(mobility), forces, o.integrator, s.x, s.types, o.neighbours, 0, q);
  SerialRotation r;
  r.rotation_vectors.assign(3 * s.size(), 0.0);
  for (std::uint64_t k = 0; k < steps; ++k) {
    r.energy = bd.step().potential_energy;
    for (std::size_t c = 0; c < r.rotation_vectors.size(); ++c) r.rotation_vectors[c] += bd.last_rotations()[c];
  }
  r.x.assign(bd.positions().begin(), bd.positions().end());
  r.q.assign(bd.orientations().begin(), bd.orientations().end());
  r.moment_sums = rpyfmm::bd::rotation_moment_sums(bd.orientations(), q, r.rotation_vectors);
  return r;
}

// Every rank: the number of values of `got` (on rank 0) that differ from `expected`, and the largest
// difference, broadcast from rank 0.
std::pair<int, double> differences(const std::vector<double>& got, const std::vector<double>& expected) {
  int mismatches = 0;
  double worst = 0.0;
  if (world_rank() == 0) {
    mismatches = got.size() == expected.size() ? 0 : 1;
    for (std::size_t k = 0; k < std::min(got.size(), expected.size()); ++k) {
      if (got[k] != expected[k]) ++mismatches;
      worst = std::max(worst, std::abs(got[k] - expected[k]));
    }
  }
  MPI_Bcast(&mismatches, 1, MPI_INT, 0, MPI_COMM_WORLD);
  MPI_Bcast(&worst, 1, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  return {mismatches, worst};
}

// The gathered positions, orientations and summed rotation vectors equal the serial ones bit for bit.
void expect_rotation_state_bitwise(const DistributedBd& bd, const SerialRotation& serial, const std::string& what) {
  const rpyfmm::bd::Checkpoint c = bd.checkpoint(0);
  for (const auto& [name, got, expected] :
       {std::tuple{"positions", &c.positions, &serial.x}, std::tuple{"orientations", &c.orientations, &serial.q},
        std::tuple{"rotation vectors", &c.rotation_vectors, &serial.rotation_vectors}}) {
    const auto [mismatches, worst] = differences(*got, *expected);
    EXPECT_EQ(mismatches, 0) << what << ": " << mismatches << " " << name << " values differ, by up to " << worst;
  }
}

TEST(MpiDistributedBd, FreeDrainingRotationEqualsTheSerialEngineBitForBitForEverySplit) {
  // 216 spheres of two sizes with WCA pairs in a periodic box, dipoles in a field and constant
  // torques, 40 steps with list rebuilds: positions and orientations are bd::Integrator's bit for
  // bit (each particle's torque, angular velocity and rotational noise are its own, keyed by its
  // global index), for every split, and with shuffled ids and a repartition at every rebuild.
  const System s = lattice(6, 1.6, 2, 5);
  const Geometry box = Geometry::periodic(6 * 1.6);
  const ForceField forces = with_torques(wca_mixture());
  const std::vector<double> q = random_orientations(s.size(), 3);
  DistributedBdOptions o = rotating(options_with(4e-3, 13));
  const SerialRotation serial =
      serial_rotation_run(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(box, o.viscosity), forces, o, s, q, 40);
  const auto run = [&](const DistributedBdOptions& options, BdShare share, const std::string& what) {
    DistributedBd bd(MPI_COMM_WORLD, forces, box, options, std::move(share));
    bd.run(40);
    expect_rotation_state_bitwise(bd, serial, what);
    EXPECT_GE(bd.stats().rebuilds, 2u) << what;
    // The log's moments are sums over the ranks' shares in another order: each is a mean of N terms
    // of magnitude <= ~1 (|phi|^2 ~ 4 D_r t here, u . u0 <= 1), so the reordering changes it by at
    // most ~N eps / N ~ 1e-15 of the largest term; bounded by 1e-13.
    const std::array<double, 2> m = bd.rotation_moments();
    const auto n = static_cast<double>(s.size());
    EXPECT_NEAR(m[0], serial.moment_sums[0] / n, 1e-13) << what;
    EXPECT_NEAR(m[1], serial.moment_sums[1] / n, 1e-13) << what;
    // The energy (pairs and dipoles) is a sum in another order too: 1e-12 of its size.
    EXPECT_NEAR(bd.potential_energy(), serial.energy, 1e-12 * std::max(1.0, std::abs(serial.energy))) << what;
  };
  for (const Split split : kSplits)
    run(o, share_of(s, split, identity(s.size()), false, q), "split " + std::to_string(static_cast<int>(split)));
  o.repartition_imbalance = 1.0;
  run(o, share_of(s, Split::geometric, shuffled(s.size(), 6), true, q), "shuffled ids, repartitions");
}

TEST(MpiDistributedBd, RotationAtZeroTemperatureIsTheSerialDeterministicTurnBitForBit) {
  // kT = 0: no noise drawn, each particle turns by omega dt alone (dipoles aligning with the field,
  // constant torques), bit for bit bd::Integrator's, with particles on every rank and on one only.
  const System s = lattice(4, 1.6, 2, 31);
  const ForceField forces = with_torques(wca_mixture());
  const std::vector<double> q = random_orientations(s.size(), 9);
  DistributedBdOptions o = rotating(options_with(4e-3, 3));
  o.integrator.kT = 0.0;
  const SerialRotation serial = serial_rotation_run(
      std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(Geometry::open(), o.viscosity), forces, o, s, q, 10);
  EXPECT_GT(differences(serial.q, q).second, 1e-3);  // the torques turned the particles
  for (const Split split : {Split::even, Split::last_only}) {
    DistributedBd bd(MPI_COMM_WORLD, forces, Geometry::open(), o, share_of(s, split, identity(s.size()), false, q));
    bd.run(10);
    expect_rotation_state_bitwise(bd, serial, "kT = 0, split " + std::to_string(static_cast<int>(split)));
  }
}

TEST(MpiDistributedBd, RotationCheckpointWrittenOnTwoRanksContinuesOnAllRanksBitForBit) {
  // 20 steps on ranks 0 and 1, a version 3 checkpoint (orientations, those at step 0, the summed
  // rotation vectors) through the file, 20 more on every rank: the serial 40 steps bit for bit.
  const System s = lattice(5, 1.6, 2, 29);
  const Geometry box = Geometry::periodic(5 * 1.6);
  const ForceField forces = with_torques(wca_mixture());
  const std::vector<double> q = random_orientations(s.size(), 4);
  const DistributedBdOptions o = rotating(options_with(4e-3, 21));
  const SerialRotation serial =
      serial_rotation_run(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(box, o.viscosity), forces, o, s, q, 40);
  const rpyfmm::bd::Checkpoint read = checkpoint_from_two_ranks(s, q, forces, box, o, 20);
  if (world_rank() == 0) {
    EXPECT_EQ(read.orientations.size(), 4 * s.size());
  }
  DistributedBd bd = rpyfmm::mpi::restart_distributed_bd(MPI_COMM_WORLD, forces, box, o, read);
  bd.run(20);
  expect_rotation_state_bitwise(bd, serial, "restarted on " + std::to_string(world_size()) + " ranks");
  const rpyfmm::bd::Checkpoint end = bd.checkpoint(0);
  if (world_rank() == 0) {
    EXPECT_EQ(end.reference_orientations, q);  // they travel with the particles
  }
  // Without rotation in the options the checkpoint is refused.
  expect_collective_error(
      [&] { (void)rpyfmm::mpi::restart_distributed_bd(MPI_COMM_WORLD, forces, box, options_with(4e-3, 21), read); },
      ErrorCode::invalid_argument, "holds orientations but the options have no rotation");
}

// The largest difference between the orientations' quaternions gathered on rank 0 and `expected`.
double largest_orientation_difference(const DistributedBd& bd, const std::vector<double>& expected) {
  return differences(bd.checkpoint(0).orientations, expected).second;
}

// Sticky spheres (k^3) in a trap with dipoles in a field and torques, random orientations, and the
// serial engine's state after `steps` steps with DirectRpy and the options of `method`.
struct HydrodynamicRotation {
  System s;
  ForceField forces;
  std::vector<double> q;
  DistributedBdOptions o;
  SerialRotation serial;
};

HydrodynamicRotation hydrodynamic_rotation(rpyfmm::rpy::MobilityMethod method, int k, std::uint64_t seed,
                                           std::uint64_t steps) {
  HydrodynamicRotation c{lattice(k, 1.3, 1, 9), with_torques(sticky_trapped()), {}, {}, {}};
  c.q = random_orientations(c.s.size(), seed);
  c.o = rotating(hydrodynamic_options(method));
  c.serial = serial_rotation_run(std::make_unique<rpyfmm::rpy::DirectRpy>(Geometry::open(), c.o.viscosity), c.forces,
                                 c.o, c.s, c.q, steps);
  return c;
}

TEST(MpiDistributedBd, DirectHydrodynamicsWithRotationFollowTheSerialEngineToRoundOff) {
  // 64 sticky spheres in a trap with dipoles in a field and torques, 6 steps, against bd::Integrator
  // with DirectRpy and the same sampler (Lanczos without preconditioner, tolerance 1e-8). The grand
  // mobility is summed over the ranks' shares, the sampler's global vector is in the ranks' order
  // rather than the global one, so each product differs in its last bits: not bit for bit. As for
  // translation alone the iterations carry this to ~1e-14 of a displacement or rotation vector, and
  // 6 steps of these smooth fields keep it below 1e-12 (coordinates of order 5, unit quaternions;
  // measured: 0 on 1 and 2 ranks, up to 1.8e-15 for coordinates and 4.7e-16 for quaternions on 3-4).
  const auto [s, forces, q, o, serial] = hydrodynamic_rotation(rpyfmm::rpy::MobilityMethod::direct, 4, 5, 6);
  DistributedBd bd(MPI_COMM_WORLD, forces, Geometry::open(), o,
                   share_of(s, Split::geometric, shuffled(s.size(), 2), true, q));
  bd.run(6);
  const double dx = largest_difference(bd, serial.x), dq = largest_orientation_difference(bd, serial.q);
  if (world_rank() == 0)
    std::printf("  [bd direct rotation] %d ranks: largest coordinate difference %.3g, quaternion %.3g\n", world_size(),
                dx, dq);
  EXPECT_LT(dx, 1e-12);
  EXPECT_LT(dq, 1e-12);
  // The particles turned by far more than that: the comparison is not of the start.
  EXPECT_GT(differences(serial.q, q).second, 1e-2);
}

TEST(MpiDistributedBd, FmmHydrodynamicsWithRotationFollowTheExactOperatorToTheTolerance) {
  // One step with the FMM at 1e-6 against the serial engine with the exact grand mobility: U and W
  // differ by ~1e-6 of their size (the operator's contract), and the samples by that plus the two
  // samplers' errors (each <= 10 x 1e-8), so the displacements and rotation vectors agree to 1e-5
  // of their norms (measured: displacements 1.6e-6 - 3.3e-6, rotation vectors 5.8e-7 - 1.5e-6 on
  // 1-4 ranks, leaves of 16 points).
  const auto [s, forces, q, o, serial] = hydrodynamic_rotation(rpyfmm::rpy::MobilityMethod::fmm, 5, 6, 1);
  DistributedBd bd(MPI_COMM_WORLD, forces, Geometry::open(), o, share_of(s, Split::even, identity(s.size()), false, q));
  bd.step();
  const rpyfmm::bd::Checkpoint c = bd.checkpoint(0);
  std::array<double, 2> ratio{};
  if (world_rank() == 0) {
    double dx2 = 0.0, x2 = 0.0, dphi2 = 0.0, phi2 = 0.0;
    for (std::size_t k = 0; k < s.x.size(); ++k) {
      dx2 += std::pow(c.positions[k] - serial.x[k], 2);
      x2 += std::pow(serial.x[k] - s.x[k], 2);
      dphi2 += std::pow(c.rotation_vectors[k] - serial.rotation_vectors[k], 2);
      phi2 += std::pow(serial.rotation_vectors[k], 2);
    }
    ratio = {std::sqrt(dx2 / std::max(x2, 1e-300)), std::sqrt(dphi2 / std::max(phi2, 1e-300))};
  }
  MPI_Bcast(ratio.data(), 2, MPI_DOUBLE, 0, MPI_COMM_WORLD);
  if (world_rank() == 0)
    std::printf("  [bd fmm rotation] %d ranks: relative difference of the displacements %.3g, rotations %.3g\n",
                world_size(), ratio[0], ratio[1]);
  EXPECT_LT(ratio[0], 1e-5);
  EXPECT_LT(ratio[1], 1e-5);
}

TEST(MpiDistributedBd, PseHydrodynamicsWithRotationFollowTheSerialEngineToRoundOff) {
  // 125 spheres with WCA pairs, dipoles in a field and torques in a periodic box, 6 steps, against
  // bd::Integrator with PseRpy (double wave grids) on the whole set. With rotation the serial step is
  // the grand product and PseRpy::apply_sqrt_rotation (not the fused drift and noise), whose wave
  // noise is keyed by the hash of the whole [z_t; z_r] in global index order; DistributedBd passes
  // the particles' global indices, so the key is the serial one for every split and id order. The
  // products and the Lanczos iteration agree with the serial ones to round-off (their sums in
  // another order; test_distributed_pse.cpp), and 6 steps of these smooth fields keep the coordinates
  // (of order 10) and unit quaternions within 1e-12 (a different key would move them by the noise
  // itself, ~1e-2).
  const System s = lattice(5, 2.0, 2, 13);
  const Geometry box = Geometry::periodic(5 * 2.0);
  const ForceField forces = with_torques(wca_pulled());
  const std::vector<double> q = random_orientations(s.size(), 12);
  const DistributedBdOptions o = rotating(pse_options());
  const SerialRotation serial =
      serial_rotation_run(std::make_unique<rpyfmm::rpy::pse::PseRpy>(box, o.viscosity, o.pse), forces, o, s, q, 6);
  EXPECT_GT(differences(serial.q, q).second, 1e-2);  // the comparison is not of the start
  for (const Split split : {Split::even, Split::geometric}) {
    for (const bool shuffle : {false, true}) {
      const std::vector<std::size_t> order = shuffle ? shuffled(s.size(), 8) : identity(s.size());
      DistributedBd bd(MPI_COMM_WORLD, forces, box, o, share_of(s, split, order, shuffle, q));
      bd.run(6);
      const double dx = largest_difference(bd, serial.x), dq = largest_orientation_difference(bd, serial.q);
      EXPECT_LT(dx, 1e-12) << "split " << static_cast<int>(split) << (shuffle ? ", shuffled ids" : "");
      EXPECT_LT(dq, 1e-12) << "split " << static_cast<int>(split) << (shuffle ? ", shuffled ids" : "");
      if (world_rank() == 0 && split == Split::even)
        std::printf("  [bd pse rotation] %d ranks%s: largest coordinate difference %.3g, quaternion %.3g\n",
                    world_size(), shuffle ? ", shuffled ids" : "", dx, dq);
    }
  }
}

TEST(MpiDistributedBd, BadRotationInputOnOneRankFailsEveryRank) {
  const System s = lattice(4, 1.6, 2, 1);
  const Geometry box = Geometry::periodic(4 * 1.6);
  const ForceField forces = with_torques(wca_mixture());
  const std::vector<double> q = random_orientations(s.size(), 7);
  const DistributedBdOptions o = rotating(options_with(1e-3));
  const int last = world_size() - 1;
  const auto refused = [&](const DistributedBdOptions& options, const BdShare& share, ErrorCode code,
                           const std::string& text) {
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, forces, box, options, share); }, code, text);
  };
  {  // a NaN quaternion component on the last rank
    BdShare share = share_of(s, Split::even, identity(s.size()), false, q);
    if (world_rank() == last) share.orientations[2] = std::nan("");
    refused(o, share, ErrorCode::invalid_input, "orientations");
  }
  {  // a zero quaternion on the last rank
    BdShare share = share_of(s, Split::even, identity(s.size()), false, q);
    if (world_rank() == last) std::fill(share.orientations.begin(), share.orientations.begin() + 4, 0.0);
    refused(o, share, ErrorCode::invalid_input, "is a zero quaternion");
  }
  {  // too few orientations on the last rank
    BdShare share = share_of(s, Split::even, identity(s.size()), false, q);
    if (world_rank() == last) share.orientations.pop_back();
    refused(o, share, ErrorCode::invalid_input, "orientations have");
  }
  // Orientations without rotation.
  refused(options_with(1e-3), share_of(s, Split::even, identity(s.size()), false, q), ErrorCode::invalid_argument,
          "rotation is off");
}

TEST(MpiDistributedBd, ATurnBeyondMaxDisplacementFailsEveryRankAndKeepsTheState) {
  // Particle 37 under a huge torque: the guard refuses the turn on every rank, naming it by its
  // global index, and the orientations stay at the last good step.
  System s = lattice(4, 1.6, 1, 2);
  s.types[37] = 1;
  rpyfmm::bd::ParticleType a{.name = "A", .radius = 0.5};
  rpyfmm::bd::ParticleType spun{.name = "spun", .radius = 0.5};
  ForceField forces({a, spun});
  std::vector<rpyfmm::bd::TypeTorque> t(2);
  t[1].torque = {0.0, 1e4, 0.0};
  forces.set_torque_field(rpyfmm::bd::TorqueField(t, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}));
  const std::vector<double> q = random_orientations(s.size(), 8);
  DistributedBd bd(MPI_COMM_WORLD, forces, Geometry::open(), rotating(options_with(1e-2)),
                   share_of(s, Split::geometric, shuffled(64, 8), true, q));
  expect_collective_error([&] { bd.step(); }, ErrorCode::numerical_failure,
                          "blow-up at step 0: particle 37 would turn by");
  const rpyfmm::bd::Checkpoint after = bd.checkpoint(0);
  if (world_rank() == 0) {
    EXPECT_EQ(after.orientations, q);
  }
  EXPECT_EQ(bd.step_count(), 0u);
}

// Brownian spheres of type A beside inertial (Langevin) spheres of type B in a periodic box: the
// mass of B makes gamma dt / m = 1, between the overdamped and the inertial regime (docs/theory/bd.md,
// the Langevin section).
DistributedBdOptions langevin_options(std::uint64_t seed) {
  DistributedBdOptions o = options_with(4e-3, seed);
  const double friction = 6.0 * std::numbers::pi * kViscosity * 0.7;
  o.integrator.inertia = {std::nullopt, rpyfmm::bd::LangevinParticle{.mass = friction * 4e-3, .friction = friction}};
  return o;
}

// The serial engine after `steps` steps: positions, half-step velocities and kinetic temperature.
struct LangevinState {
  std::vector<double> x, v;
  double kinetic_temperature = 0.0;
};

LangevinState serial_langevin(const ForceField& forces, const Geometry& geometry, const DistributedBdOptions& o,
                              const System& s, std::uint64_t steps) {
  rpyfmm::bd::Integrator bd(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(geometry, o.viscosity), forces,
                            o.integrator, s.x, s.types, o.neighbours);
  bd.run(steps);
  const auto v = bd.inertial().velocities();
  return {{bd.positions().begin(), bd.positions().end()}, {v.begin(), v.end()}, bd.inertial().kinetic_temperature()};
}

// Every rank: positions and velocities bit for bit `expected`, the kinetic temperature to round-off.
void expect_langevin_state(const DistributedBd& bd, const LangevinState& expected, const std::string& what) {
  const rpyfmm::bd::Checkpoint c = bd.checkpoint(0);
  expect_gathered_bitwise(c.positions, expected.x, what + ": positions");
  expect_gathered_bitwise(c.velocities, expected.v, what + ": velocities");
  // A mean of ~100 positive terms summed in another order: relative error <= N eps ~ 2e-14.
  EXPECT_NEAR(bd.kinetic_temperature(), expected.kinetic_temperature, 1e-12 * expected.kinetic_temperature) << what;
}

TEST(MpiDistributedBdLangevin, MixtureEqualsTheSerialEngineBitForBitForEverySplit) {
  // 216 spheres, half of them inertial, volume fraction 0.12 with WCA pairs; 40 steps. The shares
  // are a random permutation of the particles, and every rebuild moves particles between ranks
  // (the velocities with them).
  const System s = lattice(6, 1.6, 2, 31);
  const Geometry box = Geometry::periodic(6 * 1.6);
  DistributedBdOptions o = langevin_options(17);
  o.repartition_imbalance = 1.0;
  const LangevinState expected = serial_langevin(wca_mixture(), box, o, s, 40);
  ASSERT_GT(expected.kinetic_temperature, 0.0);
  for (const Split split : kSplits) {
    DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, o, share_of(s, split, shuffled(s.size(), 8), true));
    EXPECT_TRUE(bd.inertial());
    bd.run(40);
    expect_langevin_state(bd, expected, "split " + std::to_string(static_cast<int>(split)));
    EXPECT_GE(bd.stats().rebuilds, 2u);
    if (world_size() > 1) {
      EXPECT_EQ(bd.stats().repartitions, bd.stats().rebuilds);
    }
  }
}

TEST(MpiDistributedBdLangevin, CheckpointWrittenOnTwoRanksContinuesOnAllRanksBitForBit) {
  const System s = lattice(5, 1.6, 2, 37);
  const Geometry box = Geometry::periodic(5 * 1.6);
  const DistributedBdOptions o = langevin_options(3);
  const LangevinState expected = serial_langevin(wca_mixture(), box, o, s, 40);
  // The first 20 steps on ranks 0 and 1 only, through a version 4 file (with the velocities).
  const rpyfmm::bd::Checkpoint read = checkpoint_from_two_ranks(s, {}, wca_mixture(), box, o, 20);
  if (world_rank() == 0) {
    EXPECT_EQ(read.velocities.size(), 3 * s.size());
  }
  DistributedBd bd = rpyfmm::mpi::restart_distributed_bd(MPI_COMM_WORLD, wca_mixture(), box, o, read);
  EXPECT_EQ(bd.step_count(), 20u);
  bd.run(20);
  expect_langevin_state(bd, expected, "restarted on " + std::to_string(world_size()) + " ranks");
  // Without the inertial types the checkpoint's velocities are refused on every rank.
  expect_collective_error(
      [&] {
        (void)rpyfmm::mpi::restart_distributed_bd(MPI_COMM_WORLD, wca_mixture(), box, options_with(4e-3, 3), read);
      },
      ErrorCode::invalid_argument, "disagree with the checkpoint's velocities");
}

TEST(MpiDistributedBdLangevin, BadInertialInputOnOneRankFailsEveryRank) {
  const System s = lattice(4, 1.6, 2, 1);
  const Geometry box = Geometry::periodic(4 * 1.6);
  const DistributedBdOptions o = langevin_options(5);
  const int last = world_size() - 1;
  // Velocities given on every rank: zeros (Brownian particles must have 0).
  const auto with_velocities = [&] {
    BdShare share = share_of(s, Split::even, identity(s.size()), false);
    share.velocities.assign(3 * share.types.size(), 0.0);
    return share;
  };
  {  // one velocity short on the last rank
    BdShare share = with_velocities();
    if (world_rank() == last) share.velocities.pop_back();
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, o, share); },
                            ErrorCode::invalid_input, "velocities has");
  }
  {  // a Brownian particle (type A) moving on the last rank
    BdShare share = with_velocities();
    const auto brownian = std::find(share.types.begin(), share.types.end(), 0u) - share.types.begin();
    if (world_rank() == last) share.velocities[3 * static_cast<std::size_t>(brownian)] = 1.0;
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, o, share); },
                            ErrorCode::invalid_input, "is Brownian but has a non-zero velocity");
  }
  {  // velocities without inertial types
    expect_collective_error(
        [&] { DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, options_with(4e-3), with_velocities()); },
        ErrorCode::invalid_argument, "no particle is inertial");
  }
  if (world_size() > 1) {  // velocities on some ranks only
    BdShare share = with_velocities();
    if (world_rank() == last) share.velocities.clear();
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, o, share); },
                            ErrorCode::invalid_input, "some ranks gave velocities");
  }
  {  // a non-positive mass
    DistributedBdOptions massless = o;
    massless.integrator.inertia[1]->mass = 0.0;
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, massless, with_velocities()); },
                            ErrorCode::invalid_argument, "mass and friction must be finite and > 0");
  }
  {  // the serial engine's conditions: free draining, no rotation
    DistributedBdOptions pse = o;
    pse.method = rpyfmm::rpy::MobilityMethod::pse;
    expect_collective_error([&] { DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, pse, with_velocities()); },
                            ErrorCode::invalid_argument, "free-draining mobility");
    DistributedBdOptions rotation = o;
    rotation.integrator.rotation = true;
    expect_collective_error(
        [&] {
          DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), box, rotation,
                           share_of(s, Split::even, identity(s.size()), false));
        },
        ErrorCode::invalid_argument, "do not support rotation");
  }
}

}  // namespace

// ---- Split displacements and force callbacks ----

namespace {

// Every rank: this rank's values (`per` per particle, in the order of its ids) of every rank placed
// by global index.
std::vector<double> all_by_index(const DistributedBd& bd, std::span<const double> local, std::size_t per) {
  std::vector<double> packed;
  for (std::size_t i = 0; i < bd.local_size(); ++i) {
    packed.push_back(static_cast<double>(bd.ids()[i]));
    packed.insert(packed.end(), &local[per * i], &local[per * i + per]);
  }
  const int mine = static_cast<int>(packed.size());
  std::vector<int> counts(static_cast<std::size_t>(world_size())), displs(counts.size(), 0);
  MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  for (std::size_t r = 1; r < counts.size(); ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(static_cast<std::size_t>(displs.back() + counts.back()));
  MPI_Allgatherv(packed.data(), mine, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, MPI_COMM_WORLD);
  std::vector<double> placed(per * bd.global_size());
  for (std::size_t k = 0; (per + 1) * k < all.size(); ++k) {
    const auto id = static_cast<std::size_t>(all[(per + 1) * k]);
    std::copy(&all[(per + 1) * k + 1], &all[(per + 1) * k + 1 + per], &placed[per * id]);
  }
  return placed;
}

// The largest difference between a and b (same size).
double largest(const std::vector<double>& a, std::span<const double> b) {
  double worst = a.size() == b.size() ? 0.0 : INFINITY;
  for (std::size_t k = 0; k < std::min(a.size(), b.size()); ++k) worst = std::max(worst, std::abs(a[k] - b[k]));
  return worst;
}

// One step of both engines: the distributed split displacements against the serial ones (within
// `bound`; 0: bit for bit), and x_before + (drift + noise) == x_after bit for bit on every rank.
// Returns the largest difference of the parts.
double step_and_compare_split(DistributedBd& bd, rpyfmm::bd::Integrator& serial, double bound,
                              const std::string& what) {
  const std::vector<double> before = all_by_index(bd, bd.positions(), 3);
  bd.step();
  serial.step();
  const std::vector<double> after = all_by_index(bd, bd.positions(), 3);
  const std::vector<double> drift = all_by_index(bd, bd.deterministic_displacement(), 3);
  const std::vector<double> noise = all_by_index(bd, bd.brownian_displacement(), 3);
  const double d = largest(drift, serial.deterministic_displacement());
  const double b = largest(noise, serial.brownian_displacement());
  if (bound == 0.0) {
    EXPECT_EQ(d, 0.0) << what;
    EXPECT_EQ(b, 0.0) << what;
    EXPECT_EQ(bitwise_mismatches(
                  drift, {serial.deterministic_displacement().begin(), serial.deterministic_displacement().end()}),
              0u)
        << what;
    EXPECT_EQ(bitwise_mismatches(noise, {serial.brownian_displacement().begin(), serial.brownian_displacement().end()}),
              0u)
        << what;
  } else {
    EXPECT_LT(d, bound) << what;
    EXPECT_LT(b, bound) << what;
  }
  std::size_t off = 0;
  for (std::size_t k = 0; k < after.size(); ++k)
    if (before[k] + (drift[k] + noise[k]) != after[k]) ++off;
  EXPECT_EQ(off, 0u) << what << ": drift + noise is not the step's displacement";
  return std::max(d, b);
}

// `steps` steps of both engines with hydrodynamic interactions, the parts within `bound` of the
// serial ones after each; prints the largest difference (rank 0) and checks that the serial noise
// is a real sample (the comparison is not of zeros).
void run_and_compare_split(DistributedBd& bd, rpyfmm::bd::Integrator& serial, int steps, double bound,
                           const std::string& method) {
  double worst = 0.0;
  for (int k = 0; k < steps; ++k)
    worst = std::max(worst, step_and_compare_split(bd, serial, bound, method + ", step " + std::to_string(k)));
  if (world_rank() == 0)
    std::printf("  [bd split %s] %d ranks: largest difference of the parts %.2e\n", method.c_str(), world_size(),
                worst);
  double noise = 0.0;
  for (const double b : serial.brownian_displacement()) noise = std::max(noise, std::abs(b));
  EXPECT_GT(noise, 1e-3) << method;
}

DistributedBdOptions splitting(DistributedBdOptions o) {
  o.integrator.keep_split_displacements = true;
  return o;
}

}  // namespace

TEST(MpiDistributedBdSplit, FreeDrainingSplitDisplacementsEqualTheSerialEngineBitForBit) {
  // The sticky cluster in a trap of the repartition test: shuffled ids, every rebuild moves
  // particles between ranks. Each particle's mu F dt and sqrt(2 kT dt) sqrt(mu) z are products of
  // its own force (the serial one bit for bit) and noise (keyed by its global index) with the same
  // per-type constants, so they are the serial engine's bit for bit on every rank count.
  const System s = lattice(6, 1.3, 1, 5);
  DistributedBdOptions o = splitting(options_with(1e-3, 99));
  o.repartition_imbalance = 1.0;
  rpyfmm::bd::Integrator serial(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(Geometry::open(), o.viscosity),
                                sticky_trapped(), o.integrator, s.x, s.types, o.neighbours);
  DistributedBd bd(MPI_COMM_WORLD, sticky_trapped(), Geometry::open(), o,
                   share_of(s, Split::even, shuffled(s.size(), 3), true));
  EXPECT_EQ(bd.deterministic_displacement().size(), 0u);  // before the first step
  for (int k = 0; k < 40; ++k) step_and_compare_split(bd, serial, 0.0, "step " + std::to_string(k));
  EXPECT_GE(bd.stats().rebuilds, 2u);
  if (world_size() > 1) {
    EXPECT_GE(bd.stats().repartitions, 2u);
  }
}

TEST(MpiDistributedBdSplit, FreeDrainingSplitWithRotationEqualsTheSerialEngineBitForBit) {
  // With rotation the serial engine splits the translational step (u dt, noise w_t); the
  // rotational part turns the particles as without the split (checked with the positions).
  const System s = lattice(5, 1.6, 2, 4);
  const Geometry box = Geometry::periodic(5 * 1.6);
  const DistributedBdOptions o = splitting(rotating(options_with(2e-3, 21)));
  const std::vector<double> q = random_orientations(s.size(), 8);
  rpyfmm::bd::Integrator serial(std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(box, o.viscosity),
                                with_torques(wca_mixture()), o.integrator, s.x, s.types, o.neighbours, 0, q);
  DistributedBd bd(MPI_COMM_WORLD, with_torques(wca_mixture()), box, o,
                   share_of(s, Split::geometric, shuffled(s.size(), 4), true, q));
  for (int k = 0; k < 10; ++k) step_and_compare_split(bd, serial, 0.0, "rotation, step " + std::to_string(k));
  const std::vector<double> orientations = all_by_index(bd, bd.orientations(), 4);
  EXPECT_EQ(bitwise_mismatches(orientations, {serial.orientations().begin(), serial.orientations().end()}), 0u);
}

TEST(MpiDistributedBdSplit, DirectSplitDisplacementsFollowTheSerialEngineToRoundOff) {
  // As DirectHydrodynamicsFollowTheSerialEngineToRoundOff: u and w are products summed in another
  // order, equal to round-off (about 1e-15 of the displacements, which are ~1e-2 here), and 6 steps
  // of this smooth field keep the parts within the positions' bound of 1e-12.
  const System s = lattice(5, 1.3, 1, 9);
  const DistributedBdOptions o = splitting(hydrodynamic_options(rpyfmm::rpy::MobilityMethod::direct));
  rpyfmm::bd::Integrator serial = serial_with_hi(sticky_trapped(), o, s);
  DistributedBd bd(MPI_COMM_WORLD, sticky_trapped(), Geometry::open(), o,
                   share_of(s, Split::geometric, shuffled(s.size(), 2), true));
  run_and_compare_split(bd, serial, 6, 1e-12, "direct");
}

TEST(MpiDistributedBdSplit, PseSplitDisplacementsFollowTheSerialEngineToRoundOff) {
  // The serial engine with split displacements samples PSE by PseRpy::apply_sqrt (no fused pass),
  // its wave noise keyed by the hash of the whole z in global index order; across ranks the same
  // products on the particles in blocks of global indices (DistributedPseRpy, double grids), equal
  // to round-off as in PseHydrodynamicsInAPeriodicBoxFollowTheSerialEngineToRoundOff: the positions'
  // bound of 1e-12 (a wrong noise key would differ by the noise itself, ~1e-2).
  const System s = lattice(5, 2.0, 2, 13);
  const Geometry box = Geometry::periodic(5 * 2.0);
  const DistributedBdOptions o = splitting(pse_options());
  rpyfmm::bd::Integrator serial(std::make_unique<rpyfmm::rpy::pse::PseRpy>(box, o.viscosity, o.pse), wca_pulled(),
                                o.integrator, s.x, s.types, o.neighbours);
  DistributedBd bd(MPI_COMM_WORLD, wca_pulled(), box, o, share_of(s, Split::geometric, shuffled(s.size(), 6), true));
  run_and_compare_split(bd, serial, 5, 1e-12, "pse");
}

TEST(MpiDistributedBdSplit, SplitDisplacementsWithInertialTypesAreRefusedAsSerially) {
  const System s = lattice(4, 1.6, 2, 1);
  DistributedBdOptions o = splitting(options_with(1e-3));
  o.integrator.inertia = {std::nullopt, rpyfmm::bd::LangevinParticle{.mass = 1.0, .friction = 1.0}};
  expect_collective_error(
      [&] {
        DistributedBd bd(MPI_COMM_WORLD, wca_mixture(), Geometry::periodic(6.4), o,
                         share_of(s, Split::even, identity(s.size()), false));
      },
      ErrorCode::invalid_argument, "do not apply to inertial");
}

namespace {

// A harmonic pull of every particle towards the centre of mass of all of them: each force depends
// on every position. Adds -k (x_i - c) to the forces there.
void pull_to_centre(std::span<const double> x, std::uint64_t, std::span<double> f) {
  constexpr double k = 0.4;
  const std::size_t n = x.size() / 3;
  double c[3] = {0.0, 0.0, 0.0};
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) c[a] += x[3 * i + a];
  for (double& v : c) v /= static_cast<double>(n);
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) f[3 * i + a] += -k * (x[3 * i + a] - c[a]);
}

}  // namespace

TEST(MpiDistributedBdCallbacks, APullToTheCentreOfMassEqualsTheSerialEngineBitForBit) {
  // Two callbacks (the pull, then a force that reads the forces so far: it doubles the x component)
  // on the sticky cluster with shuffled ids and a repartition at every rebuild: the callbacks see
  // the serial engine's arrays (positions and forces in global index order), so the positions are
  // bd::Integrator's bit for bit.
  const System s = lattice(6, 1.3, 1, 5);
  ForceField forces = sticky_trapped();
  forces.add_callback(pull_to_centre);
  forces.add_callback([](std::span<const double>, std::uint64_t, std::span<double> f) {
    for (std::size_t k = 0; k < f.size(); k += 3) f[k] += 0.5 * f[k];
  });
  DistributedBdOptions o = options_with(1e-3, 42);
  o.repartition_imbalance = 1.0;
  const std::vector<double> expected = serial_run(forces, Geometry::open(), o, s, 50);
  for (const bool shuffle : {false, true}) {
    DistributedBd bd(MPI_COMM_WORLD, forces, Geometry::open(), o,
                     share_of(s, shuffle ? Split::even : Split::geometric,
                              shuffle ? shuffled(s.size(), 7) : identity(s.size()), shuffle));
    bd.run(50);
    expect_positions_bitwise(bd, expected, shuffle ? "callbacks, shuffled ids" : "callbacks");
    if (world_size() > 1 && shuffle) {
      EXPECT_GE(bd.stats().repartitions, 2u);
    }
  }
  // The pull changes the trajectory: not the run without callbacks.
  EXPECT_NE(bitwise_mismatches(expected, serial_run(sticky_trapped(), Geometry::open(), o, s, 50)), 0u);
}

TEST(MpiDistributedBdCallbacks, ACallbackThatThrowsOnOneRankFailsEveryRankAndKeepsTheState) {
  const System s = lattice(4, 1.6, 2, 1);
  const Geometry box = Geometry::periodic(4 * 1.6);
  const int last = world_size() - 1;
  ForceField forces = wca_mixture();
  forces.add_callback([last](std::span<const double>, std::uint64_t step, std::span<double>) {
    if (step == 3 && world_rank() == last) throw rpyfmm::Error(ErrorCode::invalid_input, "the callback refuses step 3");
  });
  DistributedBd bd(MPI_COMM_WORLD, forces, box, options_with(1e-3),
                   share_of(s, Split::even, identity(s.size()), false));
  bd.run(3);
  const std::vector<double> kept = all_by_index(bd, bd.positions(), 3);
  expect_collective_error([&] { bd.step(); }, ErrorCode::invalid_input, "the callback refuses step 3");
  EXPECT_EQ(bd.step_count(), 3u);
  EXPECT_EQ(bitwise_mismatches(all_by_index(bd, bd.positions(), 3), kept), 0u);
}
