// rpyfmm::mpi::DistributedRigidBodies (rpyfmm/mpi/rigid_bodies.hpp) against the serial
// rpy::RigidBodies with DirectRpy on the whole set of bodies, with the bodies split over the ranks
// in uneven contiguous shares (some ranks own none): velocities and bead forces, with
// DistributedDirectRpy and DistributedFmmRpy as the bead operator, apply_from, the body mobility
// matrix, and bad input on one rank.
#include <gtest/gtest.h>
#include <mpi.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"
#include "rigid_test_support.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/rigid_bodies.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::DistributedDirectRpy;
using rpyfmm::mpi::DistributedFmmRpy;
using rpyfmm::mpi::DistributedRigidBodies;
using rpyfmm::rpy::RigidBodies;
using rpyfmm::rpy::RigidBodyOptions;
using rpyfmm::rpy::RigidBodyReport;
using namespace rpyfmm_mpi_test;

namespace {

/// m bead-shell spheres (icosphere shells of 12 and 42 beads alternately, radius 1.5, touching
/// beads) at random orientations on a cubic lattice of spacing 3.6 (gaps of 0.6 radius: strong
/// hydrodynamic coupling, so GMRES needs several iterations), random forces and torques.
Bodies shell_lattice(std::size_t m, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  Bodies b;
  for (std::size_t k = 0; k < m; ++k) {
    const int level = k % 2 == 0 ? 1 : 0;
    const std::vector<double> shell = rpyfmm::rpy::icosphere_beads(level);
    const double radius = 1.5 * rpyfmm::rpy::icosphere_bead_radius(level);
    const Eigen::Matrix3d rotation = Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
    const Eigen::Vector3d centre(3.6 * double(k % 3), 3.6 * double(k / 3 % 3), 3.6 * double(k / 9));
    for (std::size_t i = 0; i < shell.size(); i += 3) {
      const Eigen::Vector3d r = centre + 1.5 * rotation * Eigen::Vector3d(shell[i], shell[i + 1], shell[i + 2]);
      b.x.insert(b.x.end(), {r.x(), r.y(), r.z()});
      b.radii.push_back(radius);
    }
    b.offsets.push_back(b.radii.size());
    for (int c = 0; c < 6; ++c) b.forces_torques.push_back(g(rng));
  }
  return b;
}

/// The serial solve on the whole set: velocities (6m), bead forces (3N) and the report.
struct Serial {
  std::vector<double> velocities, bead_forces;
  RigidBodyReport report;
};

Serial serial_solve(const Bodies& b, const RigidBodyOptions& options) {
  rpyfmm::rpy::DirectRpy direct(rpyfmm::rpy::Geometry::open(), kViscosity);
  RigidBodies bodies(direct, options);
  bodies.set_configuration(b.x, b.radii, b.offsets);
  Serial s{std::vector<double>(6 * b.bodies()), std::vector<double>(b.x.size()), {}};
  s.report = bodies.apply(b.forces_torques, s.velocities, s.bead_forces);
  return s;
}

/// This rank's velocities and bead forces from `bodies` (configured for `l`).
Serial distributed_solve(DistributedRigidBodies& bodies, const LocalBodies& l) {
  bodies.set_configuration(l.x, l.radii, l.offsets);
  Serial s{std::vector<double>(6 * l.bodies), std::vector<double>(3 * l.beads), {}};
  s.report = bodies.apply(l.forces_torques, s.velocities, s.bead_forces);
  return s;
}

constexpr std::size_t kBodies = 11;  // 6 shells of 42 beads and 5 of 12: 312 beads

}  // namespace

// DistributedDirectRpy's products are DirectRpy's bit for bit, so the iterates differ from the
// serial solver's only by the order in which each inner product is summed (each rank's share, then
// the ranks' sums in rank order). Measured (AMD EPYC, AVX-512, 1-4 ranks, every split, GMRES to
// 1e-10): 25 iterations as the serial solve, relative differences of at most 3.2e-15 in the
// velocities and 5.6e-15 in the bead forces (a few rounding errors), and zero where one rank holds
// every body. Bound: 1e-12, a hundred times below the GMRES tolerance (two solves that each meet
// it could differ by about that much) and over a hundred times the measured spread, so an inner
// product summed wrongly (a rank's share missing or counted twice: an O(1) change) fails it.
// Where one rank holds every body its share is the serial vector and the other ranks add exact
// zeros, so the result is the serial solver's bit for bit; likewise on one rank.
TEST(MpiDistributedRigid, DirectMatchesTheSerialSolver) {
  const Bodies b = shell_lattice(kBodies, 3u);
  const RigidBodyOptions options{.tolerance = 1e-10};
  const Serial serial = serial_solve(b, options);
  ASSERT_GT(serial.report.iterations, 3);
  for (const Split split : kSplits) {
    const LocalBodies l = local_bodies(b, split);
    DistributedDirectRpy direct(MPI_COMM_WORLD, kViscosity);
    DistributedRigidBodies bodies(direct, options);
    const Serial mine = distributed_solve(bodies, l);
    const std::vector<double> u_ref = share(serial.velocities, 6, l.first_body, l.bodies);
    const std::vector<double> f_ref = share(serial.bead_forces, 3, l.first_bead, l.beads);
    EXPECT_EQ(mine.report.iterations, serial.report.iterations);
    EXPECT_LE(global_relative_error(mine.velocities, u_ref), 1e-12) << "split " << int(split);
    EXPECT_LE(global_relative_error(mine.bead_forces, f_ref), 1e-12) << "split " << int(split);
    const bool one_holds_all = world_size() == 1 || split == Split::last_only;
    if (one_holds_all) {
      EXPECT_EQ(bitwise_mismatches(mine.velocities, u_ref), 0U) << "split " << int(split);
      EXPECT_EQ(bitwise_mismatches(mine.bead_forces, f_ref), 0U) << "split " << int(split);
      EXPECT_EQ(mine.report.residual, serial.report.residual);
    }
    // Repeated calls give the same bits.
    std::vector<double> again(mine.velocities.size());
    bodies.apply(l.forces_torques, again);
    EXPECT_EQ(bitwise_mismatches(again, mine.velocities), 0U);
  }
}

// DistributedFmmRpy at tolerance 1e-8 as the bead operator (leaves of 16 beads: 27 bodies, 744
// beads, with far-field interactions), GMRES to 1e-8, against the serial direct solve to 1e-12, on
// an uneven split (rank 0 holds half the bodies, the last ranks few or none). Measured (AMD EPYC,
// AVX-512, 1 and 3 ranks): relative differences 2.7e-8 in the velocities and 3.5e-7 in the bead
// forces, almost all of it the GMRES tolerance: solved to 1e-12 instead, the FMM's own share is
// 1.1e-10 and 3.0e-9. Bounds: the velocities within 1e-7 (a few times the GMRES tolerance,
// docs/theory/rigid.md, plus the FMM's 1e-8 at most); the bead forces, which the residual weighs
// only through M lambda = K Y, so that their error carries the conditioning of the bead blocks of
// touching beads (13 times the velocities' here), within 2e-6.
TEST(MpiDistributedRigid, FmmMatchesTheSerialDirectSolver) {
  const Bodies b = shell_lattice(27, 5u);
  const Serial serial = serial_solve(b, {.tolerance = 1e-12});
  const LocalBodies l = local_bodies(b, Split::geometric);
  DistributedFmmRpy fmm(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-8, .leaf_capacity = 16});
  DistributedRigidBodies bodies(fmm, {.tolerance = 1e-8});
  const Serial mine = distributed_solve(bodies, l);
  EXPECT_LE(global_relative_error(mine.velocities, share(serial.velocities, 6, l.first_body, l.bodies)), 1e-7);
  EXPECT_LE(global_relative_error(mine.bead_forces, share(serial.bead_forces, 3, l.first_bead, l.beads)), 2e-6);
}

// apply_with_noise with the Lanczos square root across the ranks (no preconditioner: the bead
// noise B z is the serial sampler's bit for bit, rpyfmm/mpi/sqrt.hpp) against the serial
// RigidBodies::apply_with_noise with DirectRpy and the same sampler: the solves differ only as in
// DirectMatchesTheSerialSolver, so the same bound 1e-12 and the same iteration counts (measured on
// 1-4 ranks: 61 Lanczos and 27 GMRES iterations as the serial solver, relative differences of
// velocities and bead forces at most 2.4e-15).
TEST(MpiDistributedRigid, NoiseMatchesTheSerialSolver) {
  const Bodies b = shell_lattice(kBodies, 9u);
  const RigidBodyOptions options{.tolerance = 1e-10};
  const rpyfmm::rpy::SqrtOptions sqrt{.method = rpyfmm::rpy::SqrtMethod::lanczos, .tolerance = 1e-8};
  std::mt19937 rng(11u);
  std::normal_distribution<double> g;
  std::vector<double> z(b.x.size());
  for (double& v : z) v = g(rng);
  rpyfmm::rpy::DirectRpy serial_beads(rpyfmm::rpy::Geometry::open(), kViscosity);
  RigidBodies serial(serial_beads, options);
  serial.set_configuration(b.x, b.radii, b.offsets);
  std::vector<double> u_serial(6 * b.bodies()), f_serial(b.x.size());
  const RigidBodyReport r_serial = serial.apply_with_noise(b.forces_torques, 0.7, z, u_serial, sqrt, f_serial);
  for (const Split split : {Split::even, Split::first_empty}) {
    const LocalBodies l = local_bodies(b, split);
    DistributedDirectRpy direct(MPI_COMM_WORLD, kViscosity);
    DistributedRigidBodies bodies(direct, options);
    bodies.set_configuration(l.x, l.radii, l.offsets);
    std::vector<double> u(6 * l.bodies), f(3 * l.beads);
    const RigidBodyReport r =
        bodies.apply_with_noise(l.forces_torques, 0.7, share(z, 3, l.first_bead, l.beads), u, sqrt, f);
    EXPECT_EQ(r.sqrt.iterations, r_serial.sqrt.iterations);
    EXPECT_EQ(r.iterations, r_serial.iterations);
    EXPECT_LE(global_relative_error(u, share(u_serial, 6, l.first_body, l.bodies)), 1e-12) << "split " << int(split);
    EXPECT_LE(global_relative_error(f, share(f_serial, 3, l.first_bead, l.beads)), 1e-12) << "split " << int(split);
  }
}

// apply_from across the ranks against the serial RigidBodies::apply_from with DirectRpy and the same
// guesses: the velocities and bead forces of the serial solve under forces and torques changed by
// 1% (a nearby problem). The iterates differ only as in DirectMatchesTheSerialSolver, so the same
// bound 1e-12 (a hundred times below the GMRES tolerance 1e-10, over a hundred times the few
// rounding errors the order of the inner products' sums makes) and the same iteration count, bit
// for bit where one rank holds every body; the guess saves iterations against the solve from zero.
// Measured (AMD EPYC, AVX-512, 1-4 ranks, every split): 21 iterations from the guess against 25
// from zero, as the serial solver, relative differences of at most 1.1e-16 in the velocities and
// 8.5e-17 in the bead forces.
TEST(MpiDistributedRigid, ApplyFromMatchesTheSerialSolver) {
  const Bodies b = shell_lattice(kBodies, 13u);
  const RigidBodyOptions options{.tolerance = 1e-10};
  rpyfmm::rpy::DirectRpy serial_beads(rpyfmm::rpy::Geometry::open(), kViscosity);
  RigidBodies serial(serial_beads, options);
  serial.set_configuration(b.x, b.radii, b.offsets);
  std::mt19937 rng(17u);
  std::normal_distribution<double> g;
  std::vector<double> nearby = b.forces_torques;
  for (double& w : nearby) w += 0.01 * g(rng);
  std::vector<double> u_guess(6 * b.bodies()), f_guess(b.x.size());
  const RigidBodyReport from_zero = serial.apply(nearby, u_guess, f_guess);
  std::vector<double> u_serial(6 * b.bodies()), f_serial(b.x.size());
  const RigidBodyReport r_serial = serial.apply_from(b.forces_torques, u_guess, f_guess, u_serial, f_serial);
  ASSERT_LT(r_serial.iterations, from_zero.iterations);
  for (const Split split : kSplits) {
    const LocalBodies l = local_bodies(b, split);
    DistributedDirectRpy direct(MPI_COMM_WORLD, kViscosity);
    DistributedRigidBodies bodies(direct, options);
    bodies.set_configuration(l.x, l.radii, l.offsets);
    std::vector<double> u(6 * l.bodies), f(3 * l.beads), u_zero(6 * l.bodies);
    const RigidBodyReport r = bodies.apply_from(l.forces_torques, share(u_guess, 6, l.first_body, l.bodies),
                                                share(f_guess, 3, l.first_bead, l.beads), u, f);
    const RigidBodyReport r_zero = bodies.apply(l.forces_torques, u_zero);
    EXPECT_EQ(r.iterations, r_serial.iterations) << "split " << int(split);
    EXPECT_LT(r.iterations, r_zero.iterations) << "split " << int(split);
    const std::vector<double> u_ref = share(u_serial, 6, l.first_body, l.bodies);
    const std::vector<double> f_ref = share(f_serial, 3, l.first_bead, l.beads);
    EXPECT_LE(global_relative_error(u, u_ref), 1e-12) << "split " << int(split);
    EXPECT_LE(global_relative_error(f, f_ref), 1e-12) << "split " << int(split);
    if (world_size() == 1 || split == Split::last_only) {
      EXPECT_EQ(bitwise_mismatches(u, u_ref), 0U) << "split " << int(split);
      EXPECT_EQ(bitwise_mismatches(f, f_ref), 0U) << "split " << int(split);
    }
  }
}

// mobility_matrix across the ranks against the serial RigidBodies::mobility_matrix with DirectRpy:
// each column is a solve that differs from the serial one only as in DirectMatchesTheSerialSolver,
// and the symmetrization is the same, so the same bound 1e-12 relative (Frobenius norm) with GMRES
// to 1e-10, bit for bit where one rank holds every body; the matrix is exactly symmetric and the
// same bits on every rank. Measured (AMD EPYC, AVX-512, 1-4 ranks, three splits): relative
// differences of at most 5.3e-16, zero where one rank holds every body.
TEST(MpiDistributedRigid, MobilityMatrixMatchesTheSerialMatrix) {
  const Bodies b = shell_lattice(5, 19u);  // 30 solves
  const RigidBodyOptions options{.tolerance = 1e-10};
  rpyfmm::rpy::DirectRpy serial_beads(rpyfmm::rpy::Geometry::open(), kViscosity);
  RigidBodies serial(serial_beads, options);
  serial.set_configuration(b.x, b.radii, b.offsets);
  const std::vector<double> reference = serial.mobility_matrix();
  const std::size_t n = 6 * b.bodies();
  for (const Split split : {Split::even, Split::first_empty, Split::last_only}) {
    const LocalBodies l = local_bodies(b, split);
    DistributedDirectRpy direct(MPI_COMM_WORLD, kViscosity);
    DistributedRigidBodies bodies(direct, options);
    bodies.set_configuration(l.x, l.radii, l.offsets);
    const std::vector<double> matrix = bodies.mobility_matrix(b.bodies());
    ASSERT_EQ(matrix.size(), n * n);
    EXPECT_LE(global_relative_error(matrix, reference), 1e-12) << "split " << int(split);
    if (world_size() == 1 || split == Split::last_only) {
      EXPECT_EQ(bitwise_mismatches(matrix, reference), 0U) << "split " << int(split);
    }
    std::size_t asymmetric = 0;
    for (std::size_t r = 0; r < n; ++r)
      for (std::size_t c = 0; c < n; ++c) asymmetric += matrix[r * n + c] != matrix[c * n + r] ? 1 : 0;
    EXPECT_EQ(asymmetric, 0U);
    std::vector<double> root = matrix;
    MPI_Bcast(root.data(), static_cast<int>(root.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
    EXPECT_EQ(bitwise_mismatches(matrix, root), 0U) << "split " << int(split);
  }
}

// Bad input on one rank (the last) fails every rank with one message naming that rank; so does no
// convergence (GMRES capped at one iteration for a tolerance it cannot reach in one).
TEST(MpiDistributedRigid, BadInputOnOneRankFailsEveryRank) {
  const Bodies b = shell_lattice(kBodies, 7u);
  const bool last = world_rank() == world_size() - 1;
  const std::string who = "rank " + std::to_string(world_size() - 1) + " of " + std::to_string(world_size());
  LocalBodies l = local_bodies(b, Split::even);
  DistributedDirectRpy direct(MPI_COMM_WORLD, kViscosity);
  DistributedRigidBodies bodies(direct);
  std::vector<double> u(6 * l.bodies);
  expect_collective_error([&] { bodies.apply(l.forces_torques, u); }, ErrorCode::invalid_input,
                          "apply before set_configuration");
  expect_collective_error([&] { (void)bodies.mobility_matrix(); }, ErrorCode::invalid_input,
                          "mobility_matrix before set_configuration");

  LocalBodies collinear = l;  // the last rank's last body: its beads moved onto one line
  if (last)
    for (std::size_t i = collinear.offsets[collinear.bodies - 1]; i < collinear.beads; ++i)
      for (int c = 0; c < 3; ++c) collinear.x[3 * i + std::size_t(c)] = 20.0 + double(i) * (c == 0 ? 2.0 : 0.0);
  const std::string message =
      expect_collective_error([&] { bodies.set_configuration(collinear.x, collinear.radii, collinear.offsets); },
                              ErrorCode::invalid_input, "one line");
  EXPECT_NE(message.find(who), std::string::npos) << message;

  LocalBodies short_offsets = l;  // the last rank's offsets end before its last bead
  if (last) short_offsets.offsets.back() -= 1;
  expect_collective_error(
      [&] { bodies.set_configuration(short_offsets.x, short_offsets.radii, short_offsets.offsets); },
      ErrorCode::invalid_input, who);

  bodies.set_configuration(l.x, l.radii, l.offsets);
  std::vector<double> nan_forces = l.forces_torques;
  if (last) nan_forces[0] = std::nan("");
  expect_collective_error([&] { bodies.apply(nan_forces, u); }, ErrorCode::invalid_input, who);
  std::vector<double> too_few(last ? u.size() - 1 : u.size());
  expect_collective_error([&] { bodies.apply(l.forces_torques, too_few); }, ErrorCode::invalid_input, who);

  std::vector<double> z(3 * l.beads, 0.5);
  if (last) z.back() = std::nan("");
  expect_collective_error([&] { bodies.apply_with_noise(l.forces_torques, 1.0, z, u); }, ErrorCode::invalid_input, who);
  z.back() = 0.5;
  if (world_size() > 1)
    expect_collective_error([&] { bodies.apply_with_noise(l.forces_torques, last ? 2.0 : 1.0, z, u); },
                            ErrorCode::invalid_argument, "different noise scales");

  std::vector<double> guess_u(6 * l.bodies, 0.1), guess_f(3 * l.beads, 0.1);
  if (last) guess_u.back() = std::nan("");
  expect_collective_error([&] { bodies.apply_from(l.forces_torques, guess_u, guess_f, u); }, ErrorCode::invalid_input,
                          "guess velocities");
  guess_u.back() = 0.1;
  std::vector<double> short_guess_f(last ? guess_f.size() - 1 : guess_f.size(), 0.1);
  expect_collective_error([&] { bodies.apply_from(l.forces_torques, guess_u, short_guess_f, u); },
                          ErrorCode::invalid_input, "guess bead forces");

  expect_collective_error([&] { (void)bodies.mobility_matrix(b.bodies() - 1); }, ErrorCode::invalid_argument,
                          "raise max_bodies");
  if (world_size() > 1)
    expect_collective_error([&] { (void)bodies.mobility_matrix(last ? 100 : 200); }, ErrorCode::invalid_argument,
                            "different max_bodies");

  DistributedRigidBodies capped(direct, {.tolerance = 1e-12, .max_iterations = 1});
  capped.set_configuration(l.x, l.radii, l.offsets);
  expect_collective_error([&] { capped.apply(l.forces_torques, u); }, ErrorCode::numerical_failure,
                          "GMRES did not reach");

  const RigidBodyOptions differ{.tolerance = last ? 1e-7 : 1e-6};
  if (world_size() > 1)
    expect_collective_error([&] { DistributedRigidBodies d(direct, differ); }, ErrorCode::invalid_argument,
                            "different options");
}
