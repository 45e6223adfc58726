// Brownian dynamics of rigid bodies (rpyfmm/bd/rigid_dynamics.hpp): the quaternion update against
// Eigen's angle-axis rotations; deterministic motion against the dense body mobility
// (K^T M^{-1} K)^{-1} built here with Eigen; the random-finite-difference drift against its closed
// form for an off-centre reference point (-2 kT mu_r (q - c)) and against the divergence of the
// dense mobility by central differences of configurations rotated and moved here; the
// reproducibility, the blow-up guard and bad input. The Gibbs-Boltzmann equilibrium of trapped
// bodies is test_rigid_equilibrium.cpp.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <iostream>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

#include "expect_error.hpp"
#include "rigid_shapes.hpp"
#include "rpyfmm/bd/rigid_dynamics.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

using namespace rpyfmm;
using namespace rpyfmm::bd;
using rpy::DirectRpy;
using rpy::Geometry;

namespace {

using rpyfmm_test::from_quaternion;
using rpyfmm_test::place;
using rpyfmm_test::random_quaternions;
using rpyfmm_test::Shapes;
using rpyfmm_test::Vec3;
using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Dense body mobility (K^T M^{-1} K)^{-1} of bodies whose beads are `x` (3N) with reference
/// points `ref` (3m), from the direct operator's dense matrix.
Eigen::MatrixXd dense_body_mobility(const std::vector<double>& x, const std::vector<double>& radii,
                                    const std::vector<std::size_t>& offsets, const std::vector<double>& ref) {
  DirectRpy beads(Geometry::open(), 1.0);
  beads.set_positions(x, radii);
  const std::vector<double> dense = beads.assemble_dense();
  const auto n = static_cast<Eigen::Index>(radii.size());
  const auto m = static_cast<Eigen::Index>(offsets.size() - 1);
  const Eigen::MatrixXd M = Eigen::Map<const RowMajor>(dense.data(), 3 * n, 3 * n);
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(3 * n, 6 * m);
  for (Eigen::Index k = 0; k < m; ++k) {
    for (auto i = Eigen::Index(offsets[std::size_t(k)]); i < Eigen::Index(offsets[std::size_t(k) + 1]); ++i) {
      const Vec3 r = Eigen::Map<const Vec3>(&x[3 * std::size_t(i)]) - Eigen::Map<const Vec3>(&ref[3 * std::size_t(k)]);
      K.block<3, 3>(3 * i, 6 * k).setIdentity();
      Eigen::Matrix3d cross;  // Omega x r = -[r]_x Omega
      cross << 0, r.z(), -r.y(), -r.z(), 0, r.x(), r.y(), -r.x(), 0;
      K.block<3, 3>(3 * i, 6 * k + 3) = cross;
    }
  }
  return (K.transpose() * Eigen::LLT<Eigen::MatrixXd>(M).solve(K)).inverse();
}

/// The library's random finite differences summed over the 6m unit directions: d/dQ . N to
/// O(delta^2) (each call must do GMRES work).
Eigen::VectorXd divergence_by_rfd(RigidBodyDynamics& sim) {
  const std::size_t n = 6 * sim.bodies();
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(Eigen::Index(n));
  std::vector<double> e(n, 0.0), estimate(n);
  for (std::size_t k = 0; k < n; ++k) {
    e[k] = 1.0;
    EXPECT_GT(sim.drift_estimate(e, estimate), 0);
    e[k] = 0.0;
    sum += Eigen::Map<const Eigen::VectorXd>(estimate.data(), Eigen::Index(n));
  }
  return sum;
}

}  // namespace

// The exponential map on quaternions: q <- exp(phi) q rotates by |phi| about phi in the lab frame,
// for tiny (series branch) and large angles; rotation_matrix equals Eigen's.
TEST(RigidDynamics, QuaternionRotationMatchesAngleAxis) {
  std::mt19937 rng(4);
  std::normal_distribution<double> g;
  for (double angle : {1e-9, 3e-5, 2e-4, 0.3, 2.5, 6.0}) {
    for (int trial = 0; trial < 5; ++trial) {
      double q[4] = {g(rng), g(rng), g(rng), g(rng)};
      const double norm = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
      for (double& v : q) v /= norm;
      const Eigen::Matrix3d before = from_quaternion(q);
      const auto mine = quaternion::rotation_matrix(std::span<const double, 4>(q, 4));
      EXPECT_LE((Eigen::Map<const RowMajor>(mine.data(), 3, 3) - before).norm(), 1e-14);
      Vec3 axis(g(rng), g(rng), g(rng));
      axis.normalize();
      const Vec3 phi = angle * axis;
      quaternion::rotate(std::span<double, 4>(q, 4), phi.data());
      const Eigen::Matrix3d expected = Eigen::AngleAxisd(angle, axis).toRotationMatrix() * before;
      EXPECT_LE((from_quaternion(q) - expected).norm(), 1e-14) << "angle " << angle;
      EXPECT_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0, 1e-15);
    }
  }
}

// kT = 0: a bead-shell sphere under a constant force and torque (about its centre) translates at
// mu_t F and turns at mu_r T about a fixed axis (its mobility is isotropic, so both are constant
// and Euler steps are exact), mu from the dense body mobility; the beads follow q + R rho.
TEST(RigidDynamics, DeterministicMotionFollowsTheDenseMobility) {
  Shapes s;
  s.add(rpy::icosphere_beads(1), 2.0, 2.0 * rpy::icosphere_bead_radius(1), Vec3::Zero());
  const std::vector<double> q0{0.5, -1.0, 2.0};
  const std::vector<double> quat0 = random_quaternions(1, 3u);
  DirectRpy beads(Geometry::open(), 1.0);
  const Vec3 force(0.3, -0.2, 0.5), torque(0.1, 0.7, -0.4);
  BodyForceFunction f = [&](const RigidBodyState&, std::span<double> w) {
    for (int c = 0; c < 3; ++c) w[std::size_t(c)] = force[c], w[std::size_t(c) + 3] = torque[c];
  };
  const double dt = 0.05;
  RigidBodyDynamics sim(beads, s.shape, s.radii, s.offsets, q0, quat0,
                        {.dt = dt, .kT = 0.0, .solver = {.tolerance = 1e-11}}, f);
  const int steps = 20;
  sim.run(steps);
  std::vector<double> unit(4);
  for (int c = 0; c < 4; ++c) unit[std::size_t(c)] = quat0[std::size_t(c)];
  const Eigen::MatrixXd N = dense_body_mobility(place(s, q0, unit), s.radii, s.offsets, q0);
  Eigen::VectorXd w(6);
  w << force, torque;
  const Eigen::VectorXd y = N * w;
  const double t = steps * dt;
  const Vec3 q_expected = Eigen::Map<const Vec3>(q0.data()) + t * y.head<3>();
  EXPECT_LE((Eigen::Map<const Vec3>(sim.positions().data()) - q_expected).norm(), 1e-9);
  const Vec3 omega = y.tail<3>();
  const Eigen::Matrix3d R_expected =
      Eigen::AngleAxisd(t * omega.norm(), omega.normalized()).toRotationMatrix() * from_quaternion(quat0);
  EXPECT_LE((from_quaternion(sim.orientations()) - R_expected).norm(), 1e-9);
  const std::vector<double> x = place(s, {sim.positions().begin(), sim.positions().end()},
                                      {sim.orientations().begin(), sim.orientations().end()});
  for (std::size_t i = 0; i < x.size(); ++i) EXPECT_NEAR(sim.bead_positions()[i], x[i], 1e-12);
  EXPECT_EQ(sim.step_count(), std::uint64_t(steps));
  EXPECT_GT(sim.totals().solve_iterations, 0u);
  EXPECT_EQ(sim.totals().drift_iterations, 0u);  // kT = 0: no drift solves
}

// The drift of a point tracked off the centre c of an isotropic body (a bead-shell sphere, whose
// coupling block vanishes at c) is kT d/dQ . N = -2 kT mu_r (q - c) (the Ito drift of a vector
// turning with rotational diffusion D_r = kT mu_r), with no rotational part. The sum of the
// library's random finite differences over the 6 unit directions must give it, mu_r from the
// dense mobility at the centre.
TEST(RigidDynamics, DriftOfAnOffCentreReferencePoint) {
  const Vec3 d(0.6, 0.2, -0.3);  // reference point - centre, in the body frame
  Shapes s;
  s.add(rpy::icosphere_beads(0), 1.5, 0.7, -d);
  const std::vector<double> q0{1.0, 2.0, -0.5};
  const std::vector<double> quat0 = random_quaternions(1, 8u);
  DirectRpy beads(Geometry::open(), 1.0);
  const double kT = 1.3;
  RigidBodyDynamics sim(beads, s.shape, s.radii, s.offsets, q0, quat0,
                        {.dt = 0.01, .kT = kT, .solver = {.tolerance = 1e-10}});
  EXPECT_DOUBLE_EQ(sim.rfd_tolerance(), 1e-10);
  const Eigen::VectorXd sum = divergence_by_rfd(sim);
  // mu_r from the body mobility about the centre c = q0 - R d.
  const Eigen::Matrix3d R = from_quaternion(quat0);
  const Vec3 arm = R * d;
  std::vector<double> centre(3);
  for (int c = 0; c < 3; ++c) centre[std::size_t(c)] = q0[std::size_t(c)] - arm[c];
  const Eigen::MatrixXd N = dense_body_mobility(place(s, q0, quat0), s.radii, s.offsets, centre);
  const double mu_r = N(3, 3);
  const Eigen::Matrix3d rotation_block = N.bottomRightCorner(3, 3), coupling_block = N.topRightCorner(3, 3);
  EXPECT_LE((rotation_block - mu_r * Eigen::Matrix3d::Identity()).norm(), 1e-12 * mu_r);
  EXPECT_LE(coupling_block.norm(), 1e-12 * mu_r);
  const Vec3 expected = -2.0 * mu_r * arm;
  EXPECT_LE((kT * sum.head<3>() - kT * expected).norm(), 1e-5 * kT * expected.norm());
  EXPECT_LE(kT * sum.tail<3>().norm(), 1e-5 * kT * expected.norm());
}

// Two hydrodynamically coupled, non-spherical bodies tracked at off-centre points: the sum of the
// random finite differences over the 12 unit directions equals the divergence of the dense body
// mobility, d/dQ_k N_ik, by central differences (h = 1e-4) over configurations moved and turned
// here with Eigen (rotations about the reference points).
TEST(RigidDynamics, DriftMatchesTheDivergenceOfTheDenseMobility) {
  Shapes s;
  s.add(rpy::icosphere_beads(0), 1.4, 0.6, Vec3(0.5, -0.3, 0.2));
  s.add({0, 0, 0, 2, 0, 0, 1, 1.7, 0, 1, 0.6, 1.6, 3.5, 0.4, 0.3}, 1.0, 0.8, Vec3(-1.0, -0.5, 0.1));
  const std::vector<double> q0{0.0, 0.0, 0.0, 3.2, 1.1, -0.6};
  const std::vector<double> quat0 = random_quaternions(2, 21u);
  std::vector<double> quat_unit = quat0;
  for (std::size_t k = 0; k < 2; ++k) {
    const Eigen::Quaterniond u =
        Eigen::Quaterniond(quat0[4 * k], quat0[4 * k + 1], quat0[4 * k + 2], quat0[4 * k + 3]).normalized();
    quat_unit[4 * k] = u.w(), quat_unit[4 * k + 1] = u.x(), quat_unit[4 * k + 2] = u.y(), quat_unit[4 * k + 3] = u.z();
  }
  DirectRpy beads(Geometry::open(), 1.0);
  RigidBodyDynamics sim(beads, s.shape, s.radii, s.offsets, q0, quat0,
                        {.dt = 0.01, .kT = 1.0, .solver = {.tolerance = 1e-11}});
  const Eigen::VectorXd rfd = divergence_by_rfd(sim);
  const double h = 1e-4;
  Eigen::VectorXd divergence = Eigen::VectorXd::Zero(12);
  for (int k = 0; k < 12; ++k) {
    Eigen::MatrixXd side[2];
    for (int sign = 0; sign < 2; ++sign) {
      const double step = sign == 0 ? h : -h;
      std::vector<double> q = q0, quat = quat_unit;
      const std::size_t body = std::size_t(k) / 6, axis = std::size_t(k) % 3;
      if (k % 6 < 3) {
        q[3 * body + axis] += step;
      } else {
        Eigen::Quaterniond u(quat[4 * body], quat[4 * body + 1], quat[4 * body + 2], quat[4 * body + 3]);
        u = Eigen::Quaterniond(Eigen::AngleAxisd(step, Vec3::Unit(Eigen::Index(axis)))) * u;
        quat[4 * body] = u.w(), quat[4 * body + 1] = u.x(), quat[4 * body + 2] = u.y(), quat[4 * body + 3] = u.z();
      }
      side[sign] = dense_body_mobility(place(s, q, quat), s.radii, s.offsets, q);
    }
    divergence += (side[0] - side[1]).col(k) / (2 * h);
  }
  EXPECT_GT(divergence.norm(), 1e-3);  // a drift worth testing
  EXPECT_LE((rfd - divergence).norm(), 1e-5 * divergence.norm())
      << "rfd " << rfd.transpose() << "\ndense " << divergence.transpose();
}

// A periodic box (PSE beads), the body straddling the boundary: for any centrosymmetric body (no
// coupling at its centre c, the image lattice being centrosymmetric about c too) tracked at
// q = c + r, d/dQ . N = -(tr(C) I - C) r, C the rotational block of N about c (-2 mu_r r when
// C = mu_r I), if N turns with the body. In a box it does so only up to the images' effect
// on the body's shape, O((1.5 / L)^3) = 0.7% of C here: hence the tolerance 2e-3 (measured
// differences 1e-4 translational, 4e-4 rotational). C from RigidBodies::mobility_matrix on the
// same operator. A few Brownian steps stay finite and unwrapped across the boundary.
TEST(RigidDynamics, PeriodicDriftAndSteps) {
  const Vec3 d(0.6, 0.2, -0.3);
  Shapes s;
  s.add(rpy::icosphere_beads(0), 1.5, 0.7, -d);
  const std::vector<double> q0{0.2, 7.9, -0.1};  // beads on both sides of the box's faces
  const std::vector<double> quat0 = random_quaternions(1, 8u);
  const double L = 8.0;
  rpy::pse::PseRpy beads(Geometry::periodic(L), 1.0, {.tolerance = 1e-8});
  RigidBodyDynamics sim(beads, s.shape, s.radii, s.offsets, q0, quat0,
                        {.dt = 0.05, .kT = 1.0, .solver = {.tolerance = 1e-10}});
  const Eigen::VectorXd sum = divergence_by_rfd(sim);
  const Vec3 arm = from_quaternion(quat0) * d;
  std::vector<double> centre(3);
  for (int c = 0; c < 3; ++c) centre[std::size_t(c)] = q0[std::size_t(c)] - arm[c];
  rpy::RigidBodies bodies(beads, {.tolerance = 1e-11});
  bodies.set_configuration(place(s, q0, quat0), s.radii, s.offsets, centre);
  const std::vector<double> n = bodies.mobility_matrix();
  Eigen::Matrix3d C;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C(i, j) = n[std::size_t(6 * (3 + i) + 3 + j)];
  const Vec3 expected = -(C.trace() * Eigen::Matrix3d::Identity() - C) * arm;
  EXPECT_LE((sum.head<3>() - expected).norm(), 2e-3 * expected.norm())
      << sum.transpose() << " vs " << expected.transpose();
  EXPECT_LE(sum.tail<3>().norm(), 2e-3 * expected.norm());
  sim.run(10);
  for (double v : sim.positions()) EXPECT_TRUE(std::isfinite(v));
  EXPECT_GT(sim.totals().drift_iterations, 0u);
  EXPECT_LT((Eigen::Map<const Vec3>(sim.positions().data()) - Eigen::Map<const Vec3>(q0.data())).norm(), 3.0);
}

// FMM beads (small leaves, so that most pairs go through the far field): the random finite
// difference for one random w matches the direct operator's. The FMM's error enters divided by
// delta = 1e-3 but is smooth in the positions: measured 1.7e-9 at eps 1e-8 and 2.6e-6 at 1e-6
// here; bounds 1e-6 and 1e-3.
TEST(RigidDynamics, FmmBeadsGiveTheDirectDrift) {
  Shapes s;
  std::vector<double> q;
  for (int k = 0; k < 8; ++k) {
    s.add(rpy::icosphere_beads(1), 1.0, 0.25, Vec3(0.3, -0.1, 0.2));
    for (int c = 0; c < 3; ++c) q.push_back(2.6 * ((k >> c) & 1));
  }
  const std::vector<double> quat = random_quaternions(8, 77u);
  std::vector<double> w(48), direct_drift(48), fmm_drift(48);
  std::mt19937 rng(3);
  std::normal_distribution<double> g;
  for (double& v : w) v = g(rng);
  DirectRpy direct(Geometry::open(), 1.0);
  RigidBodyDynamics reference(direct, s.shape, s.radii, s.offsets, q, quat,
                              {.dt = 0.01, .solver = {.tolerance = 1e-10}});
  reference.drift_estimate(w, direct_drift);
  const Eigen::Map<const Eigen::VectorXd> d(direct_drift.data(), 48);
  for (const auto& [eps, bound] : {std::pair{1e-8, 1e-6}, std::pair{1e-6, 1e-3}}) {
    rpy::FmmRpy fmm(Geometry::open(), 1.0, {.tolerance = eps, .leaf_capacity = 8});
    RigidBodyDynamics sim(fmm, s.shape, s.radii, s.offsets, q, quat, {.dt = 0.01, .solver = {.tolerance = 1e-10}});
    sim.drift_estimate(w, fmm_drift);
    const double diff = (Eigen::Map<const Eigen::VectorXd>(fmm_drift.data(), 48) - d).norm() / d.norm();
    EXPECT_LE(diff, bound) << "eps " << eps;
    std::cout << "FMM eps " << eps << ": drift differs from the direct one by " << diff << "\n";
  }
}

// A bead force field acts between beads of different bodies only: a soft repulsion
// eps (1 - r/s)^2 gives each body the force and torque summed here pair by pair (beads of
// different bodies within s); a hard WCA whose sigma exceeds the beads' spacing inside a body
// does not see those pairs (no overlap error); bad bead types are refused.
TEST(RigidDynamics, BeadForceFieldActsBetweenBodies) {
  Shapes s;
  s.add(rpy::icosphere_beads(0), 1.0, 0.5, Vec3(0.1, 0.0, 0.0));
  s.add(rpy::icosphere_beads(0), 1.0, 0.5, Vec3(0.0, 0.2, 0.0));
  const std::vector<double> q0{0, 0, 0, 2.1, 0.3, -0.2};
  const std::vector<double> quat0 = random_quaternions(2, 31u);
  DirectRpy beads(Geometry::open(), 1.0);
  RigidBodyDynamics sim(beads, s.shape, s.radii, s.offsets, q0, quat0, {.dt = 0.001, .kT = 0.0});
  const double eps = 2.0, sigma = 1.0;
  ForceField field({ParticleType{.radius = 0.5}});
  field.set_pair(0, 0, PairPotential{.kind = PairKind::soft, .epsilon = eps, .sigma = sigma});
  sim.set_bead_forces(field);
  sim.step();
  const std::vector<double> x = place(s, q0, quat0);
  Eigen::VectorXd expected = Eigen::VectorXd::Zero(12);
  int pairs = 0;
  for (std::size_t i = 0; i < 12; ++i) {
    for (std::size_t j = 12; j < 24; ++j) {
      const Vec3 d = Eigen::Map<const Vec3>(&x[3 * i]) - Eigen::Map<const Vec3>(&x[3 * j]);
      const double r = d.norm();
      if (r >= sigma) continue;
      ++pairs;
      const Vec3 f = 2.0 * eps * (1.0 - r / sigma) / sigma * d / r;  // on bead i; -f on bead j
      const Vec3 ri = Eigen::Map<const Vec3>(&x[3 * i]) - Eigen::Map<const Vec3>(&q0[0]);
      const Vec3 rj = Eigen::Map<const Vec3>(&x[3 * j]) - Eigen::Map<const Vec3>(&q0[3]);
      expected.segment<3>(0) += f;
      expected.segment<3>(3) += ri.cross(f);
      expected.segment<3>(6) -= f;
      expected.segment<3>(9) -= rj.cross(f);
    }
  }
  ASSERT_GT(pairs, 2);
  const Eigen::Map<const Eigen::VectorXd> w(sim.last_forces_torques().data(), 12);
  EXPECT_LE((w - expected).norm(), 1e-12 * expected.norm()) << w.transpose() << "\n" << expected.transpose();
  EXPECT_GT(sim.last_report().potential_energy, 0.0);
  // Kept apart by the repulsion: the centres separate.
  sim.run(20);
  EXPECT_GT(sim.positions()[3] - sim.positions()[0], q0[3] - q0[0]);

  // WCA with sigma 1.5 > 0.8 x the beads' spacing inside a body (1.05): only other bodies count.
  ForceField hard({ParticleType{.radius = 0.5}});
  hard.set_pair(0, 0, PairPotential{.kind = PairKind::wca, .epsilon = 1.0, .sigma = 1.5});
  DirectRpy other(Geometry::open(), 1.0);
  const std::vector<double> far{0, 0, 0, 10, 0, 0};
  RigidBodyDynamics apart(other, s.shape, s.radii, s.offsets, far, {}, {.dt = 0.01, .kT = 1.0});
  apart.set_bead_forces(hard);
  apart.run(2);
  EXPECT_EQ(apart.last_report().potential_energy, 0.0);
  using rpyfmm_test::expect_error;
  expect_error([&] { apart.set_bead_forces(hard, {0, 0, 0}); }, ErrorCode::invalid_input, "bead types");
  expect_error([&] { apart.set_bead_forces(hard, std::vector<std::uint32_t>(24, 3u)); }, ErrorCode::invalid_input,
               "type");
}

// The noise is keyed by (seed, step): equal seeds give equal trajectories, other seeds others. A
// force function's NaN and a step larger than the guard are refused with the state kept; the
// bead-to-body force sum.
TEST(RigidDynamics, ReproducibleAndGuarded) {
  Shapes s;
  s.add(rpy::icosphere_beads(0), 1.0, 0.5, Vec3(0.3, 0.0, 0.0));
  s.add(rpy::icosphere_beads(0), 1.0, 0.5, Vec3(0.0, -0.2, 0.1));
  const std::vector<double> q0{0, 0, 0, 3, 0.5, 0};
  DirectRpy a(Geometry::open(), 1.0), b(Geometry::open(), 1.0);
  const RigidDynamicsOptions options{.dt = 0.01, .kT = 1.0, .seed = 7};
  RigidBodyDynamics one(a, s.shape, s.radii, s.offsets, q0, {}, options);
  RigidBodyDynamics two(b, s.shape, s.radii, s.offsets, q0, {}, options);
  one.run(5);
  two.run(5);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(one.positions()[i], two.positions()[i]);
  for (std::size_t i = 0; i < 8; ++i) EXPECT_EQ(one.orientations()[i], two.orientations()[i]);
  EXPECT_GT(one.last_report().drift_iterations, 0);
  EXPECT_GT(one.last_report().sqrt_iterations, 0);
  RigidDynamicsOptions other = options;
  other.seed = 8;
  DirectRpy c(Geometry::open(), 1.0);
  RigidBodyDynamics three(c, s.shape, s.radii, s.offsets, q0, {}, other);
  three.run(5);
  EXPECT_NE(one.positions()[0], three.positions()[0]);

  // Guards: the state stays at the last good step.
  double scale = 0.0;
  BodyForceFunction push = [&](const RigidBodyState&, std::span<double> w) { w[0] = scale; };
  DirectRpy d(Geometry::open(), 1.0);
  RigidBodyDynamics guarded(d, s.shape, s.radii, s.offsets, q0, {}, {.dt = 0.01, .kT = 0.0}, push);
  guarded.step();
  const std::vector<double> kept(guarded.positions().begin(), guarded.positions().end());
  scale = 1e6;
  rpyfmm_test::expect_error([&] { guarded.step(); }, ErrorCode::numerical_failure, "reduce dt");
  scale = std::nan("");
  rpyfmm_test::expect_error([&] { guarded.step(); }, ErrorCode::invalid_input, "non-finite force on body 0");
  EXPECT_EQ(guarded.step_count(), 1u);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(guarded.positions()[i], kept[i]);
  scale = 0.0;
  guarded.step();
  EXPECT_EQ(guarded.step_count(), 2u);

  // bead_forces_to_bodies: a bead force f at arm r gives (f, r x f).
  std::vector<double> f(s.shape.size(), 0.0), w(12, 0.0);
  f[3] = 2.0;  // bead 1 of body 0, along x
  guarded.bead_forces_to_bodies(f, w);
  const Vec3 arm = Eigen::Map<const Vec3>(&guarded.bead_positions()[3]) - Eigen::Map<const Vec3>(&kept[0]) -
                   (Eigen::Map<const Vec3>(guarded.positions().data()) - Eigen::Map<const Vec3>(&kept[0]));
  const Vec3 torque = arm.cross(Vec3(2.0, 0.0, 0.0));
  EXPECT_DOUBLE_EQ(w[0], 2.0);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(w[std::size_t(3 + i)], torque[i], 1e-14);
  for (std::size_t i = 6; i < 12; ++i) EXPECT_EQ(w[i], 0.0);
}

// Bad input: rpyfmm::Error naming the problem.
TEST(RigidDynamics, BadInput) {
  Shapes s;
  s.add(rpy::icosphere_beads(0), 1.0, 0.5, Vec3::Zero());
  const std::vector<double> q0{0, 0, 0};
  DirectRpy beads(Geometry::open(), 1.0);
  const RigidDynamicsOptions ok{.dt = 0.01};
  using rpyfmm_test::expect_error;
  const auto make = [&](std::vector<double> shape, std::vector<double> radii, std::vector<std::size_t> offsets,
                        std::vector<double> q, std::vector<double> quat, RigidDynamicsOptions o) {
    RigidBodyDynamics sim(beads, std::move(shape), std::move(radii), std::move(offsets), std::move(q), std::move(quat),
                          o);
  };
  expect_error([&] { make(s.shape, s.radii, s.offsets, q0, {}, {}); }, ErrorCode::invalid_argument, "dt");
  expect_error([&] { make(s.shape, s.radii, s.offsets, q0, {}, {.dt = 0.1, .kT = -1}); }, ErrorCode::invalid_argument,
               "kT");
  expect_error([&] { make(s.shape, s.radii, s.offsets, q0, {}, {.dt = 0.1, .rfd_delta = 0.5}); },
               ErrorCode::invalid_argument, "rfd_delta");
  expect_error([&] { make(s.shape, s.radii, s.offsets, q0, {}, {.dt = 0.1, .max_displacement = 0}); },
               ErrorCode::invalid_argument, "max_displacement");
  expect_error([&] { make(s.shape, s.radii, s.offsets, q0, {}, {.dt = 0.1, .solver = {.tolerance = 2}}); },
               ErrorCode::invalid_argument, "tolerance");
  expect_error([&] { make(s.shape, {0.5, 0.5}, s.offsets, q0, {}, ok); }, ErrorCode::invalid_input, "radii");
  expect_error([&] { make(s.shape, s.radii, {0, 5}, q0, {}, ok); }, ErrorCode::invalid_input, "body offsets");
  expect_error([&] { make(s.shape, s.radii, s.offsets, {0, 0}, {}, ok); }, ErrorCode::invalid_input, "positions");
  expect_error(
      [&] {
        make(s.shape, s.radii, s.offsets, {0, std::nan(""), 0}, {}, ok);
      },
      ErrorCode::invalid_input, "positions");
  expect_error([&] { make(s.shape, s.radii, s.offsets, q0, {1, 0, 0}, ok); }, ErrorCode::invalid_input, "orientations");
  expect_error(
      [&] {
        make(s.shape, s.radii, s.offsets, q0, {0, 0, 0, 0}, ok);
      },
      ErrorCode::invalid_input, "zero quaternion");
  expect_error([&] { make({}, {}, {0}, {}, {}, ok); }, ErrorCode::invalid_input, "shape");
  // A body of three beads on one line (RigidBodies' check) and one all at its reference point.
  expect_error([&] { make({0, 0, 0, 1, 0, 0, 2, 0, 0}, {0.3}, {0, 3}, q0, {}, ok); }, ErrorCode::invalid_input, "line");
  expect_error(
      [&] {
        make(std::vector<double>(9, 0.0), {0.3}, {0, 3}, q0, {}, ok);
      },
      ErrorCode::invalid_input, "reference point");
  expect_error(
      [&] { RigidBodyDynamics sim(std::unique_ptr<rpy::MobilityOperator>{}, s.shape, s.radii, s.offsets, q0, {}, ok); },
      ErrorCode::invalid_argument, "no bead mobility operator");
  RigidBodyDynamics sim(beads, s.shape, s.radii, s.offsets, q0, {}, ok);
  std::vector<double> w(6, 0.0), out(6), bad(5);
  expect_error([&] { sim.drift_estimate(bad, out); }, ErrorCode::invalid_input, "RFD direction");
  w[0] = std::nan("");
  expect_error([&] { sim.drift_estimate(w, out); }, ErrorCode::invalid_input, "RFD direction");
  expect_error([&] { sim.bead_forces_to_bodies(bad, out); }, ErrorCode::invalid_input, "bead forces");
}
