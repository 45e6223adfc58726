// rpyfmm::mpi::DistributedRigidBodies with DistributedPseRpy beads in a periodic box
// (rpyfmm/mpi/rigid_bodies.hpp, docs/mpi.md "Rigid bodies across ranks") against the serial
// rpy::RigidBodies with PseRpy (double-precision wave grids) on the whole set of bodies, split over
// the ranks in uneven contiguous shares (some ranks own none), with bodies straddling the box's
// faces: apply, apply_with_noise, apply_from, the body mobility matrix, and bad input on one rank.
#include <gtest/gtest.h>
#include <mpi.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"
#include "pse_test_support.hpp"
#include "rigid_test_support.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"
#include "rpyfmm/mpi/rigid_bodies.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::DistributedPseRpy;
using rpyfmm::mpi::DistributedRigidBodies;
using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::RigidBodies;
using rpyfmm::rpy::RigidBodyOptions;
using rpyfmm::rpy::RigidBodyReport;
using rpyfmm::rpy::pse::PseRpy;
using namespace rpyfmm_mpi_test;

namespace {

constexpr double kBox = 10.0;
const Geometry kGeometry = Geometry::periodic(kBox);

/// 8 icosahedral shells of 12 touching beads (shell radius 1.5, bead radius 0.79) at random
/// orientations, centred on a 2 x 2 x 2 lattice of spacing 5 in the box of side 10 shifted so that
/// the shells at x = 0.2 straddle the face x = 0 and those at z = 9.6 the face z = L (gaps of about
/// 0.4 between neighbouring shells, across the faces too: strong coupling through the periodic
/// images). Each bead is wrapped into [0, L), so the straddling bodies' beads lie at both ends of
/// the box and only minimum-image lever arms describe them.
Bodies periodic_shells(unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  const std::vector<double> shell = rpyfmm::rpy::icosphere_beads(0);
  const double radius = 1.5 * rpyfmm::rpy::icosphere_bead_radius(0);
  Bodies b;
  for (std::size_t k = 0; k < 8; ++k) {
    const Eigen::Matrix3d rotation = Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
    const Eigen::Vector3d centre(0.2 + 5.0 * double(k % 2), 2.5 + 5.0 * double(k / 2 % 2), 4.6 + 5.0 * double(k / 4));
    for (std::size_t i = 0; i < shell.size(); i += 3) {
      const Eigen::Vector3d r = centre + 1.5 * rotation * Eigen::Vector3d(shell[i], shell[i + 1], shell[i + 2]);
      for (int c = 0; c < 3; ++c) b.x.push_back(r[c] - kBox * std::floor(r[c] / kBox));
      b.radii.push_back(radius);
    }
    b.offsets.push_back(b.radii.size());
    for (int c = 0; c < 6; ++c) b.forces_torques.push_back(g(rng));
  }
  return b;
}

/// Whether some body has beads within 1 of both faces of one axis (it straddles the box).
bool some_body_straddles(const Bodies& b) {
  for (std::size_t k = 0; k < b.bodies(); ++k) {
    for (int c = 0; c < 3; ++c) {
      bool low = false, high = false;
      for (std::size_t i = b.offsets[k]; i < b.offsets[k + 1]; ++i) {
        low = low || b.x[3 * i + c] < 1.0;
        high = high || b.x[3 * i + c] > kBox - 1.0;
      }
      if (low && high) return true;
    }
  }
  return false;
}

/// The serial solver on the whole set with its PseRpy beads.
struct SerialPse {
  PseRpy beads{kGeometry, kViscosity, double_grid_pse_options()};
  RigidBodies bodies;
  SerialPse(const Bodies& b, const RigidBodyOptions& options) : bodies(beads, options) {
    bodies.set_configuration(b.x, b.radii, b.offsets);
  }
};

/// The distributed solver on this rank's share, with its DistributedPseRpy beads.
struct DistributedPse {
  DistributedPseRpy beads{MPI_COMM_WORLD, kGeometry, kViscosity, double_grid_pse_options()};
  DistributedRigidBodies bodies;
  DistributedPse(const LocalBodies& l, const RigidBodyOptions& options) : bodies(beads, options) {
    bodies.set_configuration(l.x, l.radii, l.offsets);
  }
};

// DistributedPseRpy's products equal PseRpy's (double grids) to round-off: docs/mpi.md "Distributed
// PSE" bounds their relative difference by 1e-12 (measured 3e-17 - 3e-16). GMRES to 1e-10 applies
// the same steps to products that differ by that much and to inner products summed in another
// order, so the solutions differ by the products' difference amplified by the conditioning of the
// preconditioned saddle-point system seen by GMRES: the bound 1e-9 allows an amplification of 1000
// over the documented product bound and is still ten times below the GMRES tolerance's own scale
// for two independent solves. Measured (AMD EPYC, AVX-512, 1-4 ranks, every split): 17 iterations
// as the serial solve, at most 2.2e-15 in the velocities and 3.4e-15 in the bead forces; with
// noise 8 Lanczos and 20 GMRES iterations as the serial ones, at most 1.4e-15 and 1.7e-15;
// apply_from 14 iterations against 17 from zero; the mobility matrix at most 7.5e-16. Lever arms
// taken without minimum images (the straddling bodies' beads lie at both ends of the box) change
// the velocities by 0.32 relative and fail it.
constexpr double kBound = 1e-9;
const RigidBodyOptions kOptions{.tolerance = 1e-10};

/// A solve's results: velocities (6 per body), bead forces (3 per bead) and the report.
struct Solution {
  std::vector<double> u, f;
  RigidBodyReport report;
};

/// Collective. Expects this rank's share `mine` of a distributed solve within kBound of the serial
/// solve on the whole set over all ranks (velocities and bead forces), with the same GMRES and
/// sampler iteration counts; rank 0 prints the differences, labelled `what`.
void expect_serial(const LocalBodies& l, const Solution& mine, const Solution& serial, const std::string& what) {
  EXPECT_EQ(mine.report.iterations, serial.report.iterations) << what;
  EXPECT_EQ(mine.report.sqrt.iterations, serial.report.sqrt.iterations) << what;
  const double du = global_relative_error(mine.u, share(serial.u, 6, l.first_body, l.bodies));
  const double df = global_relative_error(mine.f, share(serial.f, 3, l.first_bead, l.beads));
  EXPECT_LE(du, kBound) << what;
  EXPECT_LE(df, kBound) << what;
  if (world_rank() == 0)
    std::printf("[ measured ] %s: %d GMRES, %d sampler iterations; velocities %.2e, bead forces %.2e\n", what.c_str(),
                mine.report.iterations, mine.report.sqrt.iterations, du, df);
}

/// Solution arrays for this rank's share or for the whole set.
Solution sized(const LocalBodies& l) {
  return {std::vector<double>(6 * l.bodies), std::vector<double>(3 * l.beads), {}};
}
Solution sized(const Bodies& b) {
  return {std::vector<double>(6 * b.bodies()), std::vector<double>(b.x.size()), {}};
}

}  // namespace

// apply (with bead forces) on every split against the serial solver, the same iteration count, and
// the same bits on a repeated call.
TEST(MpiDistributedRigidPeriodic, PseMatchesTheSerialSolver) {
  const Bodies b = periodic_shells(3u);
  ASSERT_TRUE(some_body_straddles(b));
  SerialPse serial(b, kOptions);
  Solution s = sized(b);
  s.report = serial.bodies.apply(b.forces_torques, s.u, s.f);
  ASSERT_GT(s.report.iterations, 3);
  for (const Split split : kSplits) {
    const LocalBodies l = local_bodies(b, split);
    DistributedPse d(l, kOptions);
    Solution mine = sized(l), again = sized(l);
    mine.report = d.bodies.apply(l.forces_torques, mine.u, mine.f);
    expect_serial(l, mine, s, "apply, split " + std::to_string(int(split)));
    d.bodies.apply(l.forces_torques, again.u, again.f);
    EXPECT_EQ(bitwise_mismatches(again.u, mine.u), 0U) << "split " << int(split);
    EXPECT_EQ(bitwise_mismatches(again.f, mine.f), 0U) << "split " << int(split);
  }
}

// apply_with_noise: the bead noise B z by DistributedPseRpy::apply_sqrt, the split sampler that
// PseRpy::apply_sqrt runs in the serial RigidBodies::apply_with_noise (its z2 keyed by the hash of the
// whole z, the same on every split), equal to PseRpy's to round-off with the same Lanczos
// iterations (docs/mpi.md "Distributed PSE"); the solve then differs as apply's: the bound kBound.
TEST(MpiDistributedRigidPeriodic, NoiseMatchesTheSerialSolver) {
  const Bodies b = periodic_shells(9u);
  std::mt19937 rng(11u);
  std::normal_distribution<double> g;
  std::vector<double> z(b.x.size());
  for (double& v : z) v = g(rng);
  SerialPse serial(b, kOptions);
  Solution s = sized(b);
  s.report = serial.bodies.apply_with_noise(b.forces_torques, 0.7, z, s.u, {}, s.f);
  for (const Split split : {Split::even, Split::first_empty}) {
    const LocalBodies l = local_bodies(b, split);
    DistributedPse d(l, kOptions);
    Solution mine = sized(l);
    mine.report =
        d.bodies.apply_with_noise(l.forces_torques, 0.7, share(z, 3, l.first_bead, l.beads), mine.u, {}, mine.f);
    expect_serial(l, mine, s, "apply_with_noise, split " + std::to_string(int(split)));
  }
}

// apply_from with the serial solution of a nearby problem (forces and torques changed by 1%) as the
// guess, and the whole body mobility matrix (48 solves), against the serial solver: each a solve as
// apply's, so the bound kBound and the same iteration count; the matrix exactly symmetric and the
// same bits on every rank.
TEST(MpiDistributedRigidPeriodic, ApplyFromAndMobilityMatrixMatchTheSerialSolver) {
  const Bodies b = periodic_shells(13u);
  SerialPse serial(b, kOptions);
  std::mt19937 rng(17u);
  std::normal_distribution<double> g;
  std::vector<double> nearby = b.forces_torques;
  for (double& w : nearby) w += 0.01 * g(rng);
  Solution guess = sized(b), s = sized(b);
  guess.report = serial.bodies.apply(nearby, guess.u, guess.f);
  s.report = serial.bodies.apply_from(b.forces_torques, guess.u, guess.f, s.u, s.f);
  EXPECT_LT(s.report.iterations, guess.report.iterations);
  const std::vector<double> n_serial = serial.bodies.mobility_matrix();
  const LocalBodies l = local_bodies(b, Split::geometric);
  DistributedPse d(l, kOptions);
  Solution mine = sized(l);
  mine.report = d.bodies.apply_from(l.forces_torques, share(guess.u, 6, l.first_body, l.bodies),
                                    share(guess.f, 3, l.first_bead, l.beads), mine.u, mine.f);
  expect_serial(l, mine, s, "apply_from");
  const std::vector<double> n = d.bodies.mobility_matrix();
  ASSERT_EQ(n.size(), n_serial.size());
  double diff = 0.0, norm = 0.0;
  for (std::size_t i = 0; i < n.size(); ++i) {
    diff += (n[i] - n_serial[i]) * (n[i] - n_serial[i]);
    norm += n_serial[i] * n_serial[i];
  }
  EXPECT_LE(std::sqrt(diff / norm), kBound);
  if (world_rank() == 0) std::printf("[ measured ] mobility matrix %.2e\n", std::sqrt(diff / norm));
  const std::size_t m6 = 6 * b.bodies();
  for (std::size_t i = 0; i < m6; ++i)
    for (std::size_t j = 0; j < i; ++j) EXPECT_EQ(n[i * m6 + j], n[j * m6 + i]);
  std::vector<double> root = n;
  MPI_Bcast(root.data(), static_cast<int>(root.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  EXPECT_EQ(bitwise_mismatches(n, root), 0U);
}

// Bad input fails every rank with one message: different radii on the last rank (PSE needs equal
// radii: the serial RigidBodies with PseRpy refuses them with the same code), and the block
// preconditioner for the bead noise (the split sampler has none; DistributedPseRpy::apply_sqrt
// refuses it).
TEST(MpiDistributedRigidPeriodic, BadInputFailsEveryRank) {
  const Bodies b = periodic_shells(21u);
  Bodies unequal = b;
  unequal.radii.back() *= 1.1;
  SerialPse ok(b, kOptions);
  EXPECT_THROW(
      {
        try {
          ok.bodies.set_configuration(unequal.x, unequal.radii, unequal.offsets);
        } catch (const rpyfmm::Error& e) {
          EXPECT_EQ(e.code(), ErrorCode::not_supported) << e.what();
          throw;
        }
      },
      rpyfmm::Error);
  const LocalBodies l = local_bodies(b, Split::even);
  DistributedPse d(l, kOptions);
  const LocalBodies bad = local_bodies(unequal, Split::even);
  expect_collective_error([&] { d.bodies.set_configuration(bad.x, bad.radii, bad.offsets); }, ErrorCode::not_supported,
                          "equal radii");
  d.bodies.set_configuration(l.x, l.radii, l.offsets);
  std::vector<double> u(6 * l.bodies), z(3 * l.beads, 0.5);
  const rpyfmm::rpy::SqrtOptions block{.preconditioner = rpyfmm::rpy::SqrtPreconditioner::block};
  expect_collective_error([&] { d.bodies.apply_with_noise(l.forces_torques, 1.0, z, u, block); },
                          ErrorCode::not_supported, "block preconditioner");
}
