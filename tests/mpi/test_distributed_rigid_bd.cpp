// rpyfmm::mpi::DistributedRigidBodyDynamics (rpyfmm/mpi/rigid_dynamics.hpp) against the serial
// bd::RigidBodyDynamics with DirectRpy on the same bodies, split over the ranks in uneven contiguous
// shares of whole bodies (some ranks own none): trajectories with kT > 0 and the RFD drift on
// DistributedDirectRpy and DistributedFmmRpy, with DistributedPseRpy in a periodic box against the
// serial engine with PseRpy, a restart against one longer run, and bad input on one rank.
#include <gtest/gtest.h>
#include <mpi.h>

#include <Eigen/Geometry>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"
#include "pse_test_support.hpp"
#include "rpyfmm/bd/rigid_dynamics.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/mpi/rigid_dynamics.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::bd::RigidBodyDynamics;
using rpyfmm::bd::RigidDynamicsOptions;
using rpyfmm::mpi::DistributedDirectRpy;
using rpyfmm::mpi::DistributedFmmRpy;
using rpyfmm::mpi::DistributedPseRpy;
using rpyfmm::mpi::DistributedRigidBodyDynamics;
using namespace rpyfmm_mpi_test;

namespace {

/// The whole set of bodies: body-frame shapes (beads relative to each reference point, body after
/// body), one radius per bead, body offsets, reference points and orientations.
struct Bodies {
  std::vector<double> shape, radii, positions, orientations;
  std::vector<std::size_t> offsets{0};
  [[nodiscard]] std::size_t bodies() const { return offsets.size() - 1; }
};

/// m bodies on a cubic lattice of spacing 3.2: icosphere shells of 12 touching beads (radius 1.2)
/// and tetrahedra of 4 beads (side 2.3, bead radius 0.5) alternately, each tracked at a point 0.3
/// off its centroid (so the drift does not vanish) and turned to a random orientation.
Bodies lattice(std::size_t m, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  const std::vector<double> shell = rpyfmm::rpy::icosphere_beads(0);
  const double shell_bead = 1.2 * rpyfmm::rpy::icosphere_bead_radius(0);
  const std::vector<double> tetrahedron{0.8, 0.8, 0.8, 0.8, -0.8, -0.8, -0.8, 0.8, -0.8, -0.8, -0.8, 0.8};
  Bodies b;
  for (std::size_t k = 0; k < m; ++k) {
    const bool sphere = k % 2 == 0;
    const std::vector<double>& beads = sphere ? shell : tetrahedron;
    for (std::size_t i = 0; i < beads.size(); i += 3) {
      for (int c = 0; c < 3; ++c) b.shape.push_back((sphere ? 1.2 : 1.0) * beads[i + c] - (c == 0 ? 0.3 : 0.0));
      b.radii.push_back(sphere ? shell_bead : 0.5);
    }
    b.offsets.push_back(b.radii.size());
    b.positions.insert(b.positions.end(), {3.2 * double(k % 3), 3.2 * double(k / 3 % 3), 3.2 * double(k / 9)});
    const Eigen::Quaterniond q = Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized();
    b.orientations.insert(b.orientations.end(), {q.w(), q.x(), q.y(), q.z()});
  }
  return b;
}

/// This rank's whole bodies of the set split by `split`.
struct LocalBodies {
  std::vector<double> shape, radii, positions, orientations;
  std::vector<std::size_t> offsets{0};
  std::size_t first_body = 0, bodies = 0;
};

LocalBodies local_bodies(const Bodies& b, Split split) {
  const Partition p = partition_of(b.bodies(), split);
  LocalBodies l;
  l.first_body = p.offset;
  l.bodies = p.n;
  const std::size_t first_bead = b.offsets[p.offset], beads = b.offsets[p.offset + p.n] - first_bead;
  l.shape = share(b.shape, 3, first_bead, beads);
  l.radii = share(b.radii, 1, first_bead, beads);
  l.positions = share(b.positions, 3, p.offset, p.n);
  l.orientations = share(b.orientations, 4, p.offset, p.n);
  for (std::size_t k = 1; k <= p.n; ++k) l.offsets.push_back(b.offsets[p.offset + k] - first_bead);
  return l;
}

/// A harmonic trap about the origin on each reference point and a torque from the orientation: loads
/// that depend on the state, so a wrong body's state in the function changes the trajectory.
void trap(const rpyfmm::bd::RigidBodyState& state, std::span<double> w) {
  for (std::size_t k = 0; 6 * k < w.size(); ++k)
    for (int c = 0; c < 3; ++c) {
      w[6 * k + c] = -0.4 * state.positions[3 * k + c];
      w[6 * k + 3 + c] = 0.5 * state.orientations[4 * k + 1 + c];
    }
}

/// kT 1 with the RFD drift, GMRES to 1e-8 (the RFD solves to 1e-9: min(1e-8, 1e-3 delta)), and
/// the principal square root by Lanczos to 1e-6: across the ranks its inner products are summed
/// in the serial order (rpyfmm/mpi/sqrt.hpp), so B z is the serial sampler's bit for bit.
RigidDynamicsOptions options(std::uint64_t first_step = 0) {
  return {.dt = 0.02,
          .kT = 1.0,
          .seed = 17,
          .first_step = first_step,
          .rfd_delta = 1e-3,
          .solver = {.tolerance = 1e-8},
          .sqrt = {.method = rpyfmm::rpy::SqrtMethod::lanczos,
                   .tolerance = 1e-6,
                   .preconditioner = rpyfmm::rpy::SqrtPreconditioner::none}};
}

constexpr std::size_t kBodies = 7;  // 4 shells of 12 beads and 3 tetrahedra: 60 beads
constexpr std::uint64_t kSteps = 3;

/// The serial engine's state after kSteps steps: positions, orientations, and iterations per step.
struct Trajectory {
  std::vector<double> positions, orientations;
  std::vector<int> iterations;   // GMRES, RFD and sampler iterations of each step
  std::vector<double> energies;  // the bead force field's potential energy of each step (run_steps)
  std::vector<int> rebuilds;     // whether each step rebuilt the bead neighbour list (run_steps)
};

Trajectory serial_run(const Bodies& b) {
  rpyfmm::rpy::DirectRpy direct(rpyfmm::rpy::Geometry::open(), kViscosity);
  RigidBodyDynamics sim(direct, b.shape, b.radii, b.offsets, b.positions, b.orientations, options(), trap);
  Trajectory t;
  for (std::uint64_t s = 0; s < kSteps; ++s) {
    const auto& r = sim.step();
    t.iterations.insert(t.iterations.end(), {r.solve_iterations, r.drift_iterations, r.sqrt_iterations});
  }
  t.positions.assign(sim.positions().begin(), sim.positions().end());
  t.orientations.assign(sim.orientations().begin(), sim.orientations().end());
  return t;
}

/// This rank's state after `steps` steps of the distributed engine started from `l`, with
/// DistributedDirectRpy, or with DistributedFmmRpy at 1e-8 (leaves of 16 beads, so that far-field
/// interactions are in use) where `fmm`.
Trajectory distributed_run(const LocalBodies& l, std::uint64_t first_step, std::uint64_t steps, bool fmm = false) {
  DistributedDirectRpy direct(MPI_COMM_WORLD, kViscosity);
  DistributedFmmRpy fmm_beads(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-8, .leaf_capacity = 16});
  std::unique_ptr<DistributedRigidBodyDynamics> made;
  if (fmm) {
    made = std::make_unique<DistributedRigidBodyDynamics>(fmm_beads, l.shape, l.radii, l.offsets, l.positions,
                                                          l.orientations, options(first_step), trap);
  } else {
    made = std::make_unique<DistributedRigidBodyDynamics>(direct, l.shape, l.radii, l.offsets, l.positions,
                                                          l.orientations, options(first_step), trap);
  }
  DistributedRigidBodyDynamics& sim = *made;
  Trajectory t;
  for (std::uint64_t s = 0; s < steps; ++s) {
    const auto& r = sim.step();
    t.iterations.insert(t.iterations.end(), {r.solve_iterations, r.drift_iterations, r.sqrt_iterations});
  }
  t.positions.assign(sim.local_positions().begin(), sim.local_positions().end());
  t.orientations.assign(sim.local_orientations().begin(), sim.local_orientations().end());
  return t;
}

/// The periodic box of the PSE runs.
constexpr double kBox = 10.0;
const rpyfmm::rpy::Geometry kPeriodic = rpyfmm::rpy::Geometry::periodic(kBox);

/// 4 icosphere shells of 12 touching beads (shell radius 1.5, every bead of radius 0.79: PSE takes
/// one radius), each tracked at a point 0.3 off its centroid and turned to a random orientation, on
/// a 2 x 2 lattice of spacing 5 (gaps of about 0.4 between neighbours, across the faces too) whose
/// first column sits at x = 0.2 (those shells straddle the face x = 0) and whose second row at
/// y = 9.9 (those straddle y = L); the last shell's reference point lies outside the box
/// (x = 15.2, an image of 5.2), as the engines never wrap reference points.
Bodies periodic_shells(unsigned seed) {
  std::vector<double> frame;  // one shell's beads about its reference point
  for (const double v : rpyfmm::rpy::icosphere_beads(0)) frame.push_back(1.5 * v);
  for (std::size_t i = 0; i < frame.size(); i += 3) frame[i] -= 0.3;
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  Bodies b;
  for (std::size_t k = 0; k < 4; ++k) {
    b.shape.insert(b.shape.end(), frame.begin(), frame.end());
    b.radii.insert(b.radii.end(), frame.size() / 3, 1.5 * rpyfmm::rpy::icosphere_bead_radius(0));
    b.offsets.push_back(b.radii.size());
    b.positions.insert(b.positions.end(),
                       {0.2 + 5.0 * double(k % 2) + (k == 3 ? kBox : 0.0), 4.9 + 5.0 * double(k / 2), 5.0});
    const Eigen::Quaterniond q = Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized();
    b.orientations.insert(b.orientations.end(), {q.w(), q.x(), q.y(), q.z()});
  }
  return b;
}

/// The PSE runs' options: those of options() with the bead noise by the split sampler, which the
/// serial RigidBodies takes from PseRpy::apply_sqrt (SqrtMethod automatic) and DistributedPseRpy
/// runs across the ranks, to its Lanczos tolerance 1e-6.
RigidDynamicsOptions pse_dynamics_options() {
  RigidDynamicsOptions o = options();
  o.sqrt = {.method = rpyfmm::rpy::SqrtMethod::automatic,
            .tolerance = 1e-6,
            .preconditioner = rpyfmm::rpy::SqrtPreconditioner::none};
  return o;
}

/// A trap about the box's centre on the (unwrapped) reference points and the torque of trap().
void centre_trap(const rpyfmm::bd::RigidBodyState& state, std::span<double> w) {
  trap(state, w);
  for (std::size_t k = 0; 6 * k < w.size(); ++k)
    for (int c = 0; c < 3; ++c) w[6 * k + c] += 0.4 * 0.5 * kBox;
}

/// Iterations and final state of `sim` after kSteps steps (serial or distributed engine).
template <class Engine>
Trajectory run_steps(Engine& sim, std::span<const double> (Engine::*positions)() const,
                     std::span<const double> (Engine::*orientations)() const) {
  Trajectory t;
  for (std::uint64_t s = 0; s < kSteps; ++s) {
    const auto& r = sim.step();
    t.iterations.insert(t.iterations.end(), {r.solve_iterations, r.drift_iterations, r.sqrt_iterations});
    t.energies.push_back(r.potential_energy);
    t.rebuilds.push_back(r.neighbour_rebuild ? 1 : 0);
  }
  const auto q = (sim.*positions)(), quat = (sim.*orientations)();
  t.positions.assign(q.begin(), q.end());
  t.orientations.assign(quat.begin(), quat.end());
  return t;
}

/// Checks this rank's state after the steps against its share of the serial engine's: the same
/// iterations in every step, positions and orientations within `bound` relative, and bit for bit
/// where `bitwise`; prints the measured differences under `label` on rank 0.
void expect_follows(const Trajectory& mine, const Trajectory& serial, const LocalBodies& l, Split split, double bound,
                    bool bitwise, const char* label) {
  EXPECT_EQ(mine.iterations, serial.iterations) << "split " << int(split);
  const std::vector<double> q_ref = share(serial.positions, 3, l.first_body, l.bodies);
  const std::vector<double> quat_ref = share(serial.orientations, 4, l.first_body, l.bodies);
  const double dq = global_relative_error(mine.positions, q_ref);
  const double dquat = global_relative_error(mine.orientations, quat_ref);
  if (world_rank() == 0)
    std::printf("[ measured ] %s, split %d: positions %.2e, orientations %.2e\n", label, int(split), dq, dquat);
  EXPECT_LE(dq, bound) << "split " << int(split);
  EXPECT_LE(dquat, bound) << "split " << int(split);
  if (bitwise) {
    EXPECT_EQ(bitwise_mismatches(mine.positions, q_ref), 0U) << "split " << int(split);
    EXPECT_EQ(bitwise_mismatches(mine.orientations, quat_ref), 0U) << "split " << int(split);
  }
}

}  // namespace

// The step's products are DirectRpy's bit for bit (DistributedDirectRpy), the bead noise z and the
// RFD direction w are the serial engine's draws by global index, and B z is the serial sampler's
// bit for bit (principal root: inner products summed in the serial order). What differs is the
// order in which GMRES sums its inner products (each rank's share, then the ranks' sums), in the
// three solves of a step: each differs from the serial solve by a few rounding errors
// (tests/mpi/test_distributed_rigid.cpp measures at most 5.6e-15 relative), and the RFD divides
// the difference of two solves by delta = 1e-3, so the drift may carry up to a thousand times
// that. Measured (AMD EPYC, AVX-512, 1-4 ranks, every split, three steps): the same GMRES and
// Lanczos iteration counts as the serial engine in every step, positions within 8.2e-16 and
// orientations within 9.6e-16 relative. Bound: 1e-11, the rounding of a solve times the RFD's
// 1e3 with a margin of over ten, and far below what a noise or RFD direction drawn for the wrong
// body or bead changes (measured 1.7e-4 with w keyed by the body index instead of two triples
// per body). Where one rank holds every body (and on one rank) the other ranks add exact zeros to
// every inner product: bit for bit.
TEST(MpiDistributedRigidBd, MatchesTheSerialEngine) {
  const Bodies b = lattice(kBodies, 5u);
  const Trajectory serial = serial_run(b);
  for (const Split split : kSplits) {
    const LocalBodies l = local_bodies(b, split);
    const Trajectory mine = distributed_run(l, 0, kSteps);
    expect_follows(mine, serial, l, split, 1e-11, world_size() == 1 || split == Split::last_only, "rigid BD");
  }
}

// The engine on DistributedFmmRpy at 1e-8 (leaves of 16 beads), split evenly, against the serial
// engine with DirectRpy. Each product lies within 1e-8 relative of the exact one, so each solve
// within a few times that, and the RFD divides the difference of its two solves by delta = 1e-3:
// bound 1e-5 on positions and orientations after three steps. Measured (AMD EPYC, AVX-512, 1-4
// ranks): at most 3.0e-13 (the FMM's error on 60 beads is far below its tolerance).
TEST(MpiDistributedRigidBd, FmmFollowsTheSerialEngine) {
  const Bodies b = lattice(kBodies, 5u);
  const Trajectory serial = serial_run(b);
  const LocalBodies l = local_bodies(b, Split::even);
  const Trajectory mine = distributed_run(l, 0, kSteps, true);
  const double dq = global_relative_error(mine.positions, share(serial.positions, 3, l.first_body, l.bodies));
  const double dquat = global_relative_error(mine.orientations, share(serial.orientations, 4, l.first_body, l.bodies));
  EXPECT_LE(dq, 1e-5);
  EXPECT_LE(dquat, 1e-5);
}

// The noise of a step is keyed by (seed, step) and no other state carries over, so a restart from
// the state after step 1 with first_step = 1 continues a run of three steps bit for bit.
TEST(MpiDistributedRigidBd, RestartContinuesBitForBit) {
  const Bodies b = lattice(kBodies, 6u);
  LocalBodies l = local_bodies(b, Split::geometric);
  const Trajectory whole = distributed_run(l, 0, kSteps);
  const Trajectory first = distributed_run(l, 0, 1);
  l.positions = first.positions;
  l.orientations = first.orientations;
  const Trajectory rest = distributed_run(l, 1, kSteps - 1);
  EXPECT_EQ(bitwise_mismatches(rest.positions, whole.positions), 0U);
  EXPECT_EQ(bitwise_mismatches(rest.orientations, whole.orientations), 0U);
}

// Bad input on one rank (the last) fails every rank with one message naming that rank; a force
// error and the blow-up guard on one rank's body fail every rank and leave every rank's state at
// the last good step.
TEST(MpiDistributedRigidBd, BadInputOnOneRankFailsEveryRank) {
  const Bodies b = lattice(kBodies, 7u);
  const bool last = world_rank() == world_size() - 1;
  const std::string who = "rank " + std::to_string(world_size() - 1) + " of " + std::to_string(world_size());
  const LocalBodies l = local_bodies(b, Split::even);
  DistributedDirectRpy direct(MPI_COMM_WORLD, kViscosity);
  const auto make = [&](LocalBodies given, RigidDynamicsOptions o, rpyfmm::bd::BodyForceFunction f = trap) {
    DistributedRigidBodyDynamics sim(direct, given.shape, given.radii, given.offsets, given.positions,
                                     given.orientations, o, f);
  };
  LocalBodies nan = l;
  if (last) nan.positions[1] = std::nan("");
  expect_collective_error([&] { make(nan, options()); }, ErrorCode::invalid_input, who);
  if (world_size() > 1) {
    RigidDynamicsOptions differ = options();
    if (last) differ.dt = 0.03;
    expect_collective_error([&] { make(l, differ); }, ErrorCode::invalid_argument, "different options");
  }
  LocalBodies collapsed = l;  // the last rank's last body with every bead at its reference point
  if (last)
    for (std::size_t i = 3 * collapsed.offsets[l.bodies - 1]; i < collapsed.shape.size(); ++i) collapsed.shape[i] = 0;
  expect_collective_error([&] { make(collapsed, options()); }, ErrorCode::invalid_input,
                          "body " + std::to_string(kBodies - 1) + " has all its beads at its reference point");

  // A non-finite force on the last body (on the last rank), then a push on it that moves the bodies
  // too far.
  for (const double load : {std::nan(""), 1e6}) {
    DistributedRigidBodyDynamics sim(direct, l.shape, l.radii, l.offsets, l.positions, l.orientations, options(),
                                     [&](const rpyfmm::bd::RigidBodyState& state, std::span<double> w) {
                                       trap(state, w);
                                       if (last && state.time > 0.0) w[w.size() - 6] = load;
                                     });
    sim.step();
    const std::vector<double> q(sim.local_positions().begin(), sim.local_positions().end());
    const std::string needle = std::isnan(load) ? "non-finite force on body " + std::to_string(kBodies - 1)
                                                : "step 1: body";  // the push moves every body, through the fluid
    expect_collective_error([&] { sim.step(); },
                            std::isnan(load) ? ErrorCode::invalid_input : ErrorCode::numerical_failure, needle);
    EXPECT_EQ(sim.step_count(), 1U);
    EXPECT_EQ(bitwise_mismatches(std::vector<double>(sim.local_positions().begin(), sim.local_positions().end()), q),
              0U);
  }
}

// In DistributedPseRpy's periodic box against the serial engine with PseRpy (double wave grids), with
// shells straddling the faces x = 0 and y = L and a reference point outside the box. The bead
// products agree to round-off (docs/mpi.md "Distributed PSE" bounds their relative difference by
// 1e-12), as does the split sampler's B z, with the same Lanczos iterations; the solves then differ
// by at most 1e-9 relative (1e-12 amplified up to 1000 times by the conditioning of the saddle-point
// system: the bound of tests/mpi/test_distributed_rigid_periodic.cpp), and the RFD divides the
// difference of its two solves by delta = 1e-3, so the drift differs by up to 1e-6 relative to
// the velocities. The update moves each body by dt times these: bound 1e-6 on positions and
// orientations after three steps, with the same GMRES, RFD and Lanczos iteration counts in every
// step. Measured (AMD EPYC, AVX-512, 1-4 ranks, every split): the same iteration counts, positions
// within 3.8e-16 and orientations within 1.2e-15 relative.
TEST(MpiDistributedRigidBd, PseInAPeriodicBoxMatchesTheSerialEngine) {
  const Bodies b = periodic_shells(8u);
  rpyfmm::rpy::pse::PseRpy serial_beads(kPeriodic, kViscosity, double_grid_pse_options());
  RigidBodyDynamics serial_sim(serial_beads, b.shape, b.radii, b.offsets, b.positions, b.orientations,
                               pse_dynamics_options(), centre_trap);
  const Trajectory serial = run_steps(serial_sim, &RigidBodyDynamics::positions, &RigidBodyDynamics::orientations);
  for (const Split split : kSplits) {
    const LocalBodies l = local_bodies(b, split);
    DistributedPseRpy beads(MPI_COMM_WORLD, kPeriodic, kViscosity, double_grid_pse_options());
    DistributedRigidBodyDynamics sim(beads, l.shape, l.radii, l.offsets, l.positions, l.orientations,
                                     pse_dynamics_options(), centre_trap);
    const Trajectory mine = run_steps(sim, &DistributedRigidBodyDynamics::local_positions,
                                      &DistributedRigidBodyDynamics::local_orientations);
    expect_follows(mine, serial, l, split, 1e-6, false, "rigid BD with PSE");
  }
}

namespace {

/// The bead force field of the pair tests: two bead types (0 the shells', 1 the tetrahedra's; radii
/// unused with sigma set), soft repulsion between all of them (shells 2.2, across 1.8, tetrahedra
/// 1.4: the lattice's neighbouring bodies have beads within these), a weak WCA core between the
/// tetrahedra's beads, a weak bead trap, a global force, two springs between beads of distant
/// bodies (the first and the last body, the second and the fourth: partners on other ranks), and a
/// callback on the whole system (each bead pulled towards the next bead in the global order), so
/// that every kind of term of bd::ForceField::compute is present.
rpyfmm::bd::ForceField pair_field() {
  using rpyfmm::bd::PairKind;
  rpyfmm::bd::ForceField field({rpyfmm::bd::ParticleType{.name = "S"}, rpyfmm::bd::ParticleType{.name = "T"}});
  field.set_pair(0, 0, {.kind = PairKind::soft, .epsilon = 4.0, .sigma = 2.2});
  field.set_pair(0, 1, {.kind = PairKind::soft, .epsilon = 4.0, .sigma = 1.8});
  field.set_pair(1, 1, {.kind = PairKind::wca, .epsilon = 0.5, .sigma = 0.9});
  field.set_trap(0.05);
  field.set_global_force({0.0, 0.0, -0.2});
  const std::uint32_t spring =
      field.add_bond_potential({.kind = rpyfmm::bd::BondKind::harmonic, .k = 0.5, .length = 3.0});
  const std::vector<rpyfmm::bd::Bond> bonds{{0, 59, spring}, {13, 30, spring}};
  field.add_bonds(bonds);
  field.add_callback([](std::span<const double> x, std::uint64_t, std::span<double> f) {
    for (std::size_t i = 0; i + 3 < x.size(); i += 3)
      for (int c = 0; c < 3; ++c) f[i + c] += 0.01 * (x[i + 3 + c] - x[i + c]);
  });
  return field;
}

/// A skin of 0.005 (the default 0.3 r_c would keep the first step's lists): the halo and the lists
/// are found again in every step, as the serial engine rebuilds its list.
constexpr rpyfmm::bd::NeighbourOptions kThinSkin{.skin = 0.005};

/// Each bead's type in the lattice (0 on the shells, 1 on the tetrahedra), beads first to last.
std::vector<std::uint32_t> lattice_types(const Bodies& b) {
  std::vector<std::uint32_t> types;
  for (std::size_t k = 0; k < b.bodies(); ++k) types.insert(types.end(), b.offsets[k + 1] - b.offsets[k], k % 2);
  return types;
}

}  // namespace

// Bead forces between bodies (set_bead_forces) across the ranks against the serial engine with the
// same field, with a thin skin so that the halo and the lists are found again in every step (the
// same rebuilds as the serial list). Every rank sums its own beads' rows over its beads and the
// halo within the list radius (and the bond partners) in the serial order, so the bead forces and
// the potential energy are the serial ones bit for bit at the same positions; what differs is what
// MatchesTheSerialEngine bounds (GMRES's inner-product sums): the same bound 1e-11, bit for bit on
// one rank and where one rank holds every body. The field changes the trajectory (the energy is
// checked to be far from zero, and the bodies move differently without it: at least 1e-3
// relative). Measured (AMD EPYC, AVX-512, 2 cores shared, 1-4 ranks, three splits): the same
// iteration counts and rebuilds, positions within 6.0e-16 and orientations within 1.1e-15
// relative, bit for bit on one rank and where one rank holds every body.
TEST(MpiDistributedRigidBd, BeadForcesMatchTheSerialEngine) {
  const Bodies b = lattice(kBodies, 5u);
  const std::vector<std::uint32_t> types = lattice_types(b);
  rpyfmm::rpy::DirectRpy direct(rpyfmm::rpy::Geometry::open(), kViscosity);
  RigidBodyDynamics serial_sim(direct, b.shape, b.radii, b.offsets, b.positions, b.orientations, options(), trap);
  serial_sim.set_bead_forces(pair_field(), types, kThinSkin);
  const Trajectory serial = run_steps(serial_sim, &RigidBodyDynamics::positions, &RigidBodyDynamics::orientations);
  EXPECT_EQ(serial.rebuilds, (std::vector<int>{1, 1, 1}));  // the thin skin: a rebuild in every step
  const Trajectory without = serial_run(b);
  EXPECT_GE(global_relative_error(without.positions, serial.positions), 1e-3);
  for (const double e : serial.energies) EXPECT_GT(std::abs(e), 0.1);
  for (const Split split : {Split::even, Split::last_only, Split::geometric}) {
    const LocalBodies l = local_bodies(b, split);
    DistributedDirectRpy beads(MPI_COMM_WORLD, kViscosity);
    DistributedRigidBodyDynamics sim(beads, l.shape, l.radii, l.offsets, l.positions, l.orientations, options(), trap);
    const std::size_t first_bead = b.offsets[l.first_body];
    sim.set_bead_forces(pair_field(),
                        std::vector<std::uint32_t>(types.begin() + std::ptrdiff_t(first_bead),
                                                   types.begin() + std::ptrdiff_t(first_bead + l.radii.size())),
                        kThinSkin);
    const Trajectory mine = run_steps(sim, &DistributedRigidBodyDynamics::local_positions,
                                      &DistributedRigidBodyDynamics::local_orientations);
    EXPECT_EQ(mine.rebuilds, serial.rebuilds) << "split " << int(split);
    // The first step's energy at the same positions: bit for bit. The later steps' at positions that
    // differ by up to 1e-11 relative (|q| up to 10): the soft forces are at most about 10 per unit
    // length, the energies about 1 or more, so within 1e-9 relative.
    EXPECT_EQ(std::bit_cast<std::uint64_t>(mine.energies[0]), std::bit_cast<std::uint64_t>(serial.energies[0]));
    EXPECT_LE(global_relative_error(mine.energies, serial.energies), 1e-9) << "split " << int(split);
    expect_follows(mine, serial, l, split, 1e-11, world_size() == 1 || split == Split::last_only,
                   "rigid BD with bead forces");
  }
}

// Bead forces in DistributedPseRpy's periodic box against the serial engine with PseRpy, the shells
// of PseInAPeriodicBoxMatchesTheSerialEngine straddling the faces: soft repulsion of range 2.4 reaches
// across the gaps of about 0.4 between neighbouring shells, also through the faces (minimum images).
// The bead forces are the serial ones bit for bit at equal positions (the energies of the first step
// are equal bit for bit); afterwards the positions differ by what that test bounds, so the same bound
// 1e-6 holds (the soft forces are smooth, O(1) per unit length, and change the next steps' loads by
// at most that order times the positions' difference). Measured (AMD EPYC, AVX-512, 2 cores shared,
// 1-4 ranks, two splits): the same iteration counts, positions within 3.0e-16 and orientations
// within 1.4e-15 relative.
TEST(MpiDistributedRigidBd, PseBeadForcesMatchTheSerialEngine) {
  const Bodies b = periodic_shells(8u);
  rpyfmm::bd::ForceField field;
  field.set_pair(0, 0, {.kind = rpyfmm::bd::PairKind::soft, .epsilon = 20.0, .sigma = 2.4});
  rpyfmm::rpy::pse::PseRpy serial_beads(kPeriodic, kViscosity, double_grid_pse_options());
  RigidBodyDynamics serial_sim(serial_beads, b.shape, b.radii, b.offsets, b.positions, b.orientations,
                               pse_dynamics_options(), centre_trap);
  serial_sim.set_bead_forces(field);
  const Trajectory serial = run_steps(serial_sim, &RigidBodyDynamics::positions, &RigidBodyDynamics::orientations);
  EXPECT_GT(serial.energies[0], 0.1);
  RigidBodyDynamics unforced_sim(serial_beads, b.shape, b.radii, b.offsets, b.positions, b.orientations,
                                 pse_dynamics_options(), centre_trap);
  const Trajectory unforced = run_steps(unforced_sim, &RigidBodyDynamics::positions, &RigidBodyDynamics::orientations);
  // The field moves the shells by 50 times the bound below (measured 9.6e-5 after three steps).
  EXPECT_GE(global_relative_error(unforced.positions, serial.positions), 5e-5);
  for (const Split split : {Split::even, Split::geometric}) {
    const LocalBodies l = local_bodies(b, split);
    DistributedPseRpy beads(MPI_COMM_WORLD, kPeriodic, kViscosity, double_grid_pse_options());
    DistributedRigidBodyDynamics sim(beads, l.shape, l.radii, l.offsets, l.positions, l.orientations,
                                     pse_dynamics_options(), centre_trap);
    sim.set_bead_forces(field);
    const Trajectory mine = run_steps(sim, &DistributedRigidBodyDynamics::local_positions,
                                      &DistributedRigidBodyDynamics::local_orientations);
    EXPECT_EQ(std::bit_cast<std::uint64_t>(mine.energies[0]), std::bit_cast<std::uint64_t>(serial.energies[0]));
    expect_follows(mine, serial, l, split, 1e-6, false, "rigid BD with PSE and bead forces");
  }
}

// The serial engine's refusals of a bead force field, on every rank: a bead type beyond the field's
// types on one rank (the last), bead types of the wrong count, fields that differ between the ranks,
// a hard-core overlap in a step, and a periodic box smaller than twice the list radius (all ranks).
TEST(MpiDistributedRigidBd, BadBeadForcesFailEveryRank) {
  const bool last = world_rank() == world_size() - 1;
  const Bodies b = lattice(kBodies, 7u);
  const LocalBodies l = local_bodies(b, Split::even);
  DistributedDirectRpy direct(MPI_COMM_WORLD, kViscosity);
  DistributedRigidBodyDynamics sim(direct, l.shape, l.radii, l.offsets, l.positions, l.orientations, options(), trap);
  std::vector<std::uint32_t> types(l.radii.size(), 0u);
  if (last && !types.empty()) types.back() = 2;
  expect_collective_error([&] { sim.set_bead_forces(pair_field(), types); }, ErrorCode::invalid_input,
                          "has type index 2 but only 2 types");
  std::vector<std::uint32_t> short_types(l.radii.size(), 0u);
  if (last) short_types.push_back(0u);
  expect_collective_error([&] { sim.set_bead_forces(pair_field(), short_types); }, ErrorCode::invalid_input,
                          "bead types have");
  if (world_size() > 1) {
    rpyfmm::bd::ForceField field = pair_field();
    if (last) field.set_trap(0.1);
    expect_collective_error([&] { sim.set_bead_forces(field); }, ErrorCode::invalid_argument,
                            "different bead force fields");
  }
  // A hard core wider than the gaps between the bodies: the first step fails every rank with the
  // serial engine's message (the same pair of beads, by global index, and distance).
  rpyfmm::bd::ForceField hard;
  hard.set_pair(0, 0, {.kind = rpyfmm::bd::PairKind::wca, .epsilon = 1.0, .sigma = 3.0});
  std::string serial_message;
  try {
    rpyfmm::rpy::DirectRpy serial_beads(rpyfmm::rpy::Geometry::open(), kViscosity);
    RigidBodyDynamics serial(serial_beads, b.shape, b.radii, b.offsets, b.positions, b.orientations, options(), trap);
    serial.set_bead_forces(hard);
    serial.step();
  } catch (const rpyfmm::Error& e) {
    serial_message = e.what();
  }
  EXPECT_NE(serial_message.find("overlap at step 0"), std::string::npos) << serial_message;
  DistributedRigidBodyDynamics overlapping(direct, l.shape, l.radii, l.offsets, l.positions, l.orientations, options(),
                                           trap);
  overlapping.set_bead_forces(hard);
  expect_collective_error([&] { overlapping.step(); }, ErrorCode::invalid_input, serial_message);
  EXPECT_EQ(overlapping.step_count(), 0U);

  const Bodies shells = periodic_shells(8u);
  const LocalBodies ls = local_bodies(shells, Split::even);
  DistributedPseRpy beads(MPI_COMM_WORLD, kPeriodic, kViscosity, double_grid_pse_options());
  DistributedRigidBodyDynamics box_sim(beads, ls.shape, ls.radii, ls.offsets, ls.positions, ls.orientations,
                                       pse_dynamics_options(), centre_trap);
  rpyfmm::bd::ForceField wide;
  wide.set_pair(0, 0, {.kind = rpyfmm::bd::PairKind::soft, .epsilon = 1.0, .sigma = 4.5});  // r_L 5.85 > L / 2
  expect_collective_error([&] { box_sim.set_bead_forces(wide); }, ErrorCode::invalid_argument,
                          "exceeds half the box length");
}
