// Rigid bodies of beads (rpyfmm/rpy/rigid_bodies.hpp): the GMRES body mobility against the dense
// N = (K^T M^{-1} K)^{-1} (Eigen, from the bead operator's dense matrix and K written here), its
// symmetry and positive definiteness, frame invariance, the Stokes limit of bead-shell spheres,
// the far-field (Oseen / RPY) coupling of two bodies, FMM and periodic (PSE) bead operators,
// and bad input.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "expect_error.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

using namespace rpyfmm::rpy;

namespace {

constexpr double kPi = std::numbers::pi;

/// Bead-shell sphere of the library (rpyfmm::rpy::icosphere_beads) as points.
std::vector<Eigen::Vector3d> icosphere(int levels) {
  const std::vector<double> flat = icosphere_beads(levels);
  std::vector<Eigen::Vector3d> v;
  for (std::size_t i = 0; i < flat.size(); i += 3) v.emplace_back(flat[i], flat[i + 1], flat[i + 2]);
  return v;
}

double touching_radius(int levels) {
  return icosphere_bead_radius(levels);
}

}  // namespace

// The bead-shell shapes: 10 4^s + 2 beads on the unit sphere, no two closer than twice the
// touching radius and each with a neighbour at exactly that distance (brute force here).
TEST(RigidBodies, IcosphereBeads) {
  for (int levels : {0, 1, 2}) {
    const auto v = icosphere(levels);
    ASSERT_EQ(v.size(), std::size_t(10 * (1 << (2 * levels)) + 2));
    const double a = touching_radius(levels);
    for (std::size_t i = 0; i < v.size(); ++i) {
      EXPECT_NEAR(v[i].norm(), 1.0, 1e-14);
      double nearest = 1e300;
      for (std::size_t j = 0; j < v.size(); ++j)
        if (j != i) nearest = std::min(nearest, (v[i] - v[j]).norm());
      EXPECT_GE(nearest, 2 * a - 1e-14);
      if (i == 0) {
        EXPECT_LE(nearest, 2 * a * 1.3);
      }
    }
  }
  EXPECT_NEAR(touching_radius(0), 0.5 * 1.0514622242382672, 1e-12);  // icosahedron edge / circumradius
  EXPECT_THROW(icosphere_beads(7), rpyfmm::Error);
}

namespace {

/// A system of bodies being assembled: bead positions, radii, offsets.
struct System {
  std::vector<double> x, radii;
  std::vector<std::size_t> offsets{0};
  void add(const std::vector<Eigen::Vector3d>& shape, double scale, double radius, const Eigen::Matrix3d& rotation,
           const Eigen::Vector3d& centre) {
    for (const auto& p : shape) {
      const Eigen::Vector3d q = centre + rotation * (scale * p);
      x.insert(x.end(), {q.x(), q.y(), q.z()});
      radii.push_back(radius);
    }
    offsets.push_back(radii.size());
  }
  [[nodiscard]] std::size_t bodies() const { return offsets.size() - 1; }
};

Eigen::Matrix3d random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> g;
  return Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized().toRotationMatrix();
}

/// Five bodies: three bead-shell spheres (42 beads), a bent rod of 9 beads and a flat triangle of
/// 6, randomly oriented and placed without overlap.
System five_bodies() {
  std::mt19937 rng(11);
  System s;
  const auto shell = icosphere(1);
  const double a = touching_radius(1) * 2.0;
  std::vector<Eigen::Vector3d> rod, triangle;
  for (int i = 0; i < 9; ++i) rod.emplace_back(i < 5 ? 2.0 * i : 8.0, i < 5 ? 0.0 : 2.0 * (i - 4), 0.0);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j <= i; ++j) triangle.emplace_back(2.0 * i - j, 1.7 * j, 0.0);
  s.add(shell, 2.0, a, random_rotation(rng), {0, 0, 0});
  s.add(shell, 2.0, a, random_rotation(rng), {7, 1, 0});
  s.add(shell, 2.0, a, random_rotation(rng), {1, 7, 2});
  s.add(rod, 1.0, 1.0, random_rotation(rng), {-12, 0, 3});
  s.add(triangle, 1.0, 1.0, random_rotation(rng), {2, -3, 9});
  return s;
}

/// The dense body mobility (K^T M^{-1} K)^{-1} from the operator's dense bead matrix and K built
/// here from the bodies' reference points (centroids unless given).
Eigen::MatrixXd dense_body_mobility(const MobilityOperator& beads, const System& s,
                                    Eigen::MatrixXd* lambda_map = nullptr) {
  const auto n = static_cast<Eigen::Index>(s.radii.size());
  const auto m = static_cast<Eigen::Index>(s.bodies());
  const std::vector<double> dense = beads.assemble_dense();
  const Eigen::MatrixXd M = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
      dense.data(), 3 * n, 3 * n);
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(3 * n, 6 * m);
  for (Eigen::Index k = 0; k < m; ++k) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    const auto first = static_cast<Eigen::Index>(s.offsets[static_cast<std::size_t>(k)]);
    const auto last = static_cast<Eigen::Index>(s.offsets[static_cast<std::size_t>(k) + 1]);
    for (Eigen::Index i = first; i < last; ++i) c += Eigen::Map<const Eigen::Vector3d>(&s.x[3 * std::size_t(i)]);
    c /= double(last - first);
    for (Eigen::Index i = first; i < last; ++i) {
      const Eigen::Vector3d r = Eigen::Map<const Eigen::Vector3d>(&s.x[3 * std::size_t(i)]) - c;
      K.block<3, 3>(3 * i, 6 * k).setIdentity();
      Eigen::Matrix3d cross;  // Omega x r = -[r]_x Omega
      cross << 0, r.z(), -r.y(), -r.z(), 0, r.x(), r.y(), -r.x(), 0;
      K.block<3, 3>(3 * i, 6 * k + 3) = cross;
    }
  }
  const Eigen::LLT<Eigen::MatrixXd> llt(M);
  const Eigen::MatrixXd MinvK = llt.solve(K);
  const Eigen::MatrixXd N = (K.transpose() * MinvK).inverse();
  if (lambda_map) *lambda_map = MinvK * N;  // bead forces = M^{-1} K N W
  return N;
}

Eigen::VectorXd random_vector(Eigen::Index n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  Eigen::VectorXd v(n);
  for (auto& e : v) e = g(rng);
  return v;
}

/// Body velocities from RigidBodies for forces and torques w.
Eigen::VectorXd solve(const RigidBodies& bodies, const Eigen::VectorXd& w, RigidBodyReport* report = nullptr,
                      Eigen::VectorXd* bead_forces = nullptr) {
  Eigen::VectorXd y(w.size());
  std::vector<double> lambda(3 * bodies.beads());
  const RigidBodyReport rep = bodies.apply({w.data(), std::size_t(w.size())}, {y.data(), std::size_t(y.size())},
                                           bead_forces ? std::span<double>(lambda) : std::span<double>());
  if (report) *report = rep;
  if (bead_forces) *bead_forces = Eigen::Map<const Eigen::VectorXd>(lambda.data(), Eigen::Index(lambda.size()));
  return y;
}

/// The dense body mobility from RigidBodies, column by column.
Eigen::MatrixXd body_mobility(const RigidBodies& bodies) {
  const auto n = static_cast<Eigen::Index>(6 * bodies.bodies());
  Eigen::MatrixXd N(n, n);
  for (Eigen::Index c = 0; c < n; ++c) N.col(c) = solve(bodies, Eigen::VectorXd::Unit(n, c));
  return N;
}

double rel(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return (a - b).norm() / b.norm();
}

}  // namespace

// GMRES against the dense saddle-point solution (direct bead operator), with and without the
// body preconditioner. Tolerances: the relative residual is asked at 1e-10 and the velocities
// must agree to 1e-8 (the residual bounds the error times the preconditioned condition number,
// which is small here); the preconditioner must at least halve the iterations.
TEST(RigidBodies, MatchesTheDenseBodyMobility) {
  const System s = five_bodies();
  DirectRpy beads(Geometry::open(), 0.7);
  RigidBodies bodies(beads, {.tolerance = 1e-10});
  bodies.set_configuration(s.x, s.radii, s.offsets);
  ASSERT_EQ(bodies.bodies(), 5u);
  Eigen::MatrixXd lambda_map;
  const Eigen::MatrixXd N = dense_body_mobility(beads, s, &lambda_map);
  const Eigen::VectorXd w = random_vector(30, 3u);
  RigidBodyReport rep;
  Eigen::VectorXd lambda;
  const Eigen::VectorXd y = solve(bodies, w, &rep, &lambda);
  EXPECT_LE(rel(y, N * w), 1e-8);
  EXPECT_LE(rel(lambda, lambda_map * w), 1e-7);
  EXPECT_LE(rep.residual, 1e-10);
  EXPECT_GT(rep.iterations, 1);

  RigidBodies plain(beads, {.tolerance = 1e-10, .max_iterations = 3000, .precondition = false});
  plain.set_configuration(s.x, s.radii, s.offsets);
  RigidBodyReport rep_plain;
  EXPECT_LE(rel(solve(plain, w, &rep_plain), N * w), 1e-7);
  EXPECT_LE(2 * rep.iterations, rep_plain.iterations);
  // Zero forces and torques: zero velocities, no iterations.
  EXPECT_EQ(solve(bodies, Eigen::VectorXd::Zero(30), &rep).norm(), 0.0);
  EXPECT_EQ(rep.iterations, 0);
}

// The body mobility in any units: the five bodies scaled to length L in a fluid of viscosity eta
// (water and micrometre bodies, 1e-3 and 1e-6 in SI units, and the ends of the documented ranges).
// N then scales as D^-1 N_1 D^-1 with D = sqrt(eta L) for forces and sqrt(eta L^3) for torques, so
// D y for forces D w is a dimensionless velocity of order 1 in every unit system, compared with
// the dense solution in the same units. The saddle-point system is solved in units of the
// mobility scale (docs/theory/rigid.md, "Units"), so GMRES's relative residual means the same in
// every unit system: the bounds are those of MatchesTheDenseBodyMobility, with and without the
// body preconditioner.
TEST(RigidBodies, AnyUnitsOfLengthAndViscosity) {
  const System unit = five_bodies();
  const Eigen::VectorXd w = random_vector(30, 3u);
  for (const auto& [eta, length] : {std::pair{1.0, 1.0}, std::pair{1e-3, 1e-6}, std::pair{1.0, 1e-30},
                                    std::pair{1.0, 1e30}, std::pair{1e-30, 1.0}, std::pair{1e30, 1e-30}}) {
    SCOPED_TRACE("eta " + std::to_string(eta) + ", length " + std::to_string(length));
    System s = unit;
    for (double& v : s.x) v *= length;
    for (double& v : s.radii) v *= length;
    Eigen::VectorXd d(30);
    for (int k = 0; k < 30; ++k) d(k) = std::sqrt(eta * length) * (k % 6 < 3 ? 1.0 : length);
    DirectRpy beads(Geometry::open(), eta);
    RigidBodies bodies(beads, {.tolerance = 1e-10});
    bodies.set_configuration(s.x, s.radii, s.offsets);
    const Eigen::MatrixXd N = dense_body_mobility(beads, s);
    const Eigen::VectorXd forces = d.asDiagonal() * w;
    const Eigen::VectorXd expected = d.asDiagonal() * (N * forces);
    EXPECT_LE(rel(d.asDiagonal() * solve(bodies, forces), expected), 1e-8);
    RigidBodies plain(beads, {.tolerance = 1e-10, .max_iterations = 3000, .precondition = false});
    plain.set_configuration(s.x, s.radii, s.offsets);
    EXPECT_LE(rel(d.asDiagonal() * solve(plain, forces), expected), 1e-7);
  }
}

// N is symmetric positive definite (it is the inverse of K^T M^{-1} K, M SPD), and a rigid
// rotation Q plus a translation of the whole system maps it to diag(Q, Q) N diag(Q, Q)^T.
TEST(RigidBodies, SymmetricPositiveDefiniteAndFrameInvariant) {
  System s = five_bodies();
  DirectRpy beads(Geometry::open(), 1.0);
  RigidBodies bodies(beads, {.tolerance = 1e-11});
  bodies.set_configuration(s.x, s.radii, s.offsets);
  const Eigen::MatrixXd N = body_mobility(bodies);
  EXPECT_LE((N - N.transpose()).norm(), 1e-9 * N.norm());
  // The library's mobility_matrix: the same columns, symmetrized; too many bodies are refused.
  const std::vector<double> flat = bodies.mobility_matrix();
  const Eigen::MatrixXd Nlib = Eigen::Map<const Eigen::Matrix<double, 30, 30, Eigen::RowMajor>>(flat.data());
  EXPECT_EQ(Nlib, Nlib.transpose());
  EXPECT_LE((Nlib - N).norm(), 1e-9 * N.norm());
  EXPECT_THROW((void)bodies.mobility_matrix(4), rpyfmm::Error);
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(0.5 * (N + N.transpose())).eigenvalues();
  EXPECT_GT(ev(0), 0.0);

  std::mt19937 rng(5);
  const Eigen::Matrix3d Q = random_rotation(rng);
  const Eigen::Vector3d shift(3.0, -40.0, 7.5);
  for (std::size_t i = 0; i < s.radii.size(); ++i) {
    const Eigen::Vector3d p = Q * Eigen::Map<const Eigen::Vector3d>(&s.x[3 * i]) + shift;
    std::copy(p.data(), p.data() + 3, s.x.begin() + static_cast<std::ptrdiff_t>(3 * i));
  }
  bodies.set_configuration(s.x, s.radii, s.offsets);
  Eigen::MatrixXd R = Eigen::MatrixXd::Zero(30, 30);
  for (int b = 0; b < 10; ++b) R.block<3, 3>(3 * b, 3 * b) = Q;
  const Eigen::VectorXd w = random_vector(30, 8u);
  EXPECT_LE(rel(solve(bodies, R * w), R * N * w), 1e-8);
}

// A bead-shell sphere (icosphere of radius R, touching beads of radius a) has an isotropic
// body mobility without translation-rotation coupling (icosahedral symmetry, centrosymmetric),
// and its mobilities approach Stokes' 1/(6 pi eta R) and 1/(8 pi eta R^3) as the beads shrink:
// the error falls with a / R, and the linear extrapolation to a / R = 0 of the two finest shells
// (the classical shell-model extrapolation) lands within 1.5% of Stokes.
TEST(RigidBodies, BeadShellSpheresApproachStokes) {
  const double R = 1.0, eta = 1.0;
  std::vector<double> ratio, mu_t, mu_r;
  for (int levels : {1, 2, 3}) {
    const auto shell = icosphere(levels);
    const double a = touching_radius(levels) * R;
    System s;
    s.add(shell, R, a, Eigen::Matrix3d::Identity(), {0.3, -0.2, 0.1});
    DirectRpy beads(Geometry::open(), eta);
    RigidBodies bodies(beads, {.tolerance = 1e-12});
    bodies.set_configuration(s.x, s.radii, s.offsets);
    const Eigen::MatrixXd N = body_mobility(bodies);
    const double t = N(0, 0), r = N(3, 3);
    EXPECT_LE((N.topLeftCorner<3, 3>() - t * Eigen::Matrix3d::Identity()).norm(), 1e-8 * t) << levels;
    EXPECT_LE((N.bottomRightCorner(3, 3) - r * Eigen::Matrix3d::Identity()).norm(), 1e-8 * r) << levels;
    EXPECT_LE(N.topRightCorner(3, 3).norm(), 1e-8 * std::sqrt(t * r)) << levels;
    ratio.push_back(a / R);
    mu_t.push_back(t * 6 * kPi * eta * R);
    mu_r.push_back(r * 8 * kPi * eta * R * R * R);
  }
  for (std::size_t l = 1; l < ratio.size(); ++l) {
    EXPECT_LT(std::abs(mu_t[l] - 1), std::abs(mu_t[l - 1] - 1)) << l;
    EXPECT_LT(std::abs(mu_r[l] - 1), std::abs(mu_r[l - 1] - 1)) << l;
  }
  auto extrapolate = [&](const std::vector<double>& mu) {
    const double slope = (mu[2] - mu[1]) / (ratio[2] - ratio[1]);
    return mu[2] - slope * ratio[2];
  };
  EXPECT_NEAR(extrapolate(mu_t), 1.0, 0.015);
  EXPECT_NEAR(extrapolate(mu_r), 1.0, 0.015);
}

// A prolate spheroid (semi-axes 2, 1, 1) as a bead shell (icosphere stretched along x; beads of
// half the smallest neighbour distance): its orientation-averaged translational mobility
// tr(N_tt) / 3 approaches Perrin's closed form ln((A + sqrt(A^2 - B^2)) / B) /
// (6 pi eta sqrt(A^2 - B^2)) (Perrin, J. Phys. Radium 5, 497 (1934)) as the beads shrink:
// 162 and 642 beads extrapolated linearly in the bead radius land within 1% (0.3% here).
TEST(RigidBodies, ProlateSpheroidMatchesPerrin) {
  const double A = 2.0, B = 1.0, eta = 1.0;
  const double perrin = std::log((A + std::sqrt(A * A - B * B)) / B) / (6 * kPi * eta * std::sqrt(A * A - B * B));
  std::vector<double> radius, mobility;
  for (int levels : {2, 3}) {
    auto shell = icosphere(levels);
    for (auto& p : shell) p.x() *= A / B;
    double nearest = 1e300;
    for (std::size_t i = 0; i < shell.size(); ++i)
      for (std::size_t j = i + 1; j < shell.size(); ++j) nearest = std::min(nearest, (shell[i] - shell[j]).norm());
    System s;
    s.add(shell, B, nearest / 2, Eigen::Matrix3d::Identity(), {0, 0, 0});
    DirectRpy beads(Geometry::open(), eta);
    RigidBodies bodies(beads, {.tolerance = 1e-11});
    bodies.set_configuration(s.x, s.radii, s.offsets);
    double trace = 0.0;
    for (int c = 0; c < 3; ++c) trace += solve(bodies, Eigen::VectorXd::Unit(6, c))(c);
    radius.push_back(nearest / 2);
    mobility.push_back(trace / 3);
  }
  EXPECT_LT(std::abs(mobility[1] / perrin - 1), std::abs(mobility[0] / perrin - 1));
  const double extrapolated = mobility[1] - (mobility[1] - mobility[0]) / (radius[1] - radius[0]) * radius[1];
  EXPECT_NEAR(extrapolated / perrin, 1.0, 0.01);
}

// Two touching spheres settling along their line of centres fall faster than one, by the exact
// factor 1 / 0.6451 = 1.5502 (Stimson & Jeffery, Proc. R. Soc. A 111, 110 (1926), in the contact
// limit; Cooley & O'Neill 1969). Bead shells of 162 and 642 beads with centres 2R apart,
// extrapolated linearly in the bead radius to a / R = 0 like the Stokes test: within 0.5%.
TEST(RigidBodies, TouchingDoubletSettlesAsStimsonJeffery) {
  std::vector<double> ratio, speedup;
  for (int levels : {2, 3}) {
    const auto shell = icosphere(levels);
    const double a = touching_radius(levels);
    DirectRpy beads(Geometry::open(), 1.0);
    RigidBodies bodies(beads, {.tolerance = 1e-10});
    System one;
    one.add(shell, 1.0, a, Eigen::Matrix3d::Identity(), {0, 0, 0});
    bodies.set_configuration(one.x, one.radii, one.offsets);
    Eigen::VectorXd w = Eigen::VectorXd::Zero(6);
    w(2) = 1.0;
    const double single = solve(bodies, w)(2);
    System two;
    two.add(shell, 1.0, a, Eigen::Matrix3d::Identity(), {0, 0, -1});
    two.add(shell, 1.0, a, Eigen::Matrix3d::Identity(), {0, 0, 1});
    bodies.set_configuration(two.x, two.radii, two.offsets);
    Eigen::VectorXd w2 = Eigen::VectorXd::Zero(12);
    w2(2) = w2(8) = 1.0;
    const Eigen::VectorXd y = solve(bodies, w2);
    EXPECT_NEAR(y(2), y(8), 1e-9 * y(2));  // the doublet moves as one
    ratio.push_back(a);
    speedup.push_back(y(2) / single);
  }
  const double extrapolated = speedup[1] - (speedup[1] - speedup[0]) / (ratio[1] - ratio[0]) * ratio[1];
  EXPECT_NEAR(extrapolated, 1.0 / 0.6451, 0.005 / 0.6451);
}

// Two bead-shell spheres far apart (centre distance d = 25 R) couple like two RPY spheres of
// the shells' own effective radius R_eff = 1 / (6 pi eta mu_self): the cross translational block
// is (1/(8 pi eta d)) [(1 + 2 R_eff^2/(3 d^2)) I + (1 - 2 R_eff^2/d^2) dd] up to O((R/d)^4)
// relative (Batchelor 1976): within 1e-4 here, where the R_eff^2 / d^2 terms alone are 1.2e-3.
TEST(RigidBodies, FarApartBodiesCoupleLikeRpySpheres) {
  const auto shell = icosphere(2);
  const double a = touching_radius(2);
  const double d = 25.0;
  System s;
  std::mt19937 rng(2);
  s.add(shell, 1.0, a, random_rotation(rng), {0, 0, 0});
  const Eigen::Vector3d e = Eigen::Vector3d(1.0, 2.0, -0.5).normalized();
  s.add(shell, 1.0, a, random_rotation(rng), d * e);
  DirectRpy beads(Geometry::open(), 1.0);
  RigidBodies bodies(beads, {.tolerance = 1e-11});
  bodies.set_configuration(s.x, s.radii, s.offsets);
  const Eigen::MatrixXd N = body_mobility(bodies);
  const double r_eff = 1.0 / (6 * kPi * N(0, 0));
  const double s2 = r_eff * r_eff / (d * d);
  const Eigen::Matrix3d expected =
      ((1 + 2 * s2 / 3) * Eigen::Matrix3d::Identity() + (1 - 2 * s2) * e * e.transpose()) / (8 * kPi * d);
  EXPECT_LE((N.block(0, 6, 3, 3) - expected).norm(), 1e-4 * expected.norm());
  EXPECT_LE((N.block(0, 6, 3, 3) - N.block(6, 0, 3, 3).transpose()).norm(), 1e-9 * expected.norm());
}

// The FMM bead operator gives the direct operator's body velocities to about its tolerance
// (27 bead-shell spheres of 162 beads on a lattice: 4374 beads, enough for a tree with far-field
// interactions): within 10 eps at eps 1e-3 and 1e-6, and the error moves with eps (more than
// 100x smaller at 1e-6), so the FMM's far field is really in use.
namespace {

/// Relative error of the body velocities for the load w with `beads` as the bead operator, against
/// exact bead sums (DirectRpy), both solved to 1e-11.
double body_error_against_direct(const System& s, const Eigen::VectorXd& w, MobilityOperator& beads) {
  DirectRpy direct(Geometry::open(), 1.0);
  RigidBodies by_direct(direct, {.tolerance = 1e-11});
  by_direct.set_configuration(s.x, s.radii, s.offsets);
  RigidBodies by_beads(beads, {.tolerance = 1e-11});
  by_beads.set_configuration(s.x, s.radii, s.offsets);
  return rel(solve(by_beads, w), solve(by_direct, w));
}

/// `count` icosphere shells (level 2, radius 2) at random orientations on a cubic lattice of spacing 6.
System shell_lattice(int count, int per_axis, unsigned seed) {
  const auto shell = icosphere(2);
  const double a = touching_radius(2) * 2.0;
  std::mt19937 rng(seed);
  System s;
  for (int i = 0; i < count; ++i)
    s.add(shell, 2.0, a, random_rotation(rng),
          Eigen::Vector3d(6.0 * (i % per_axis), 6.0 * (i / per_axis % per_axis), 6.0 * (i / (per_axis * per_axis))));
  return s;
}

}  // namespace

TEST(RigidBodies, FmmBeadsMatchDirectBeads) {
  const System s = shell_lattice(27, 3, 4);
  const Eigen::VectorXd w = random_vector(6 * 27, 4u);
  double errors[2];
  for (int k = 0; k < 2; ++k) {
    FmmRpy fmm(Geometry::open(), 1.0, {.tolerance = k == 0 ? 1e-3 : 1e-6});
    errors[k] = body_error_against_direct(s, w, fmm);
  }
  EXPECT_LE(errors[0], 1e-2);
  EXPECT_GT(errors[0], 0.0);
  EXPECT_LE(errors[1], 1e-5);
  EXPECT_LE(errors[1], 1e-2 * errors[0]);
}

// PSE with open boundaries as the bead operator (equal bead radii): the same bounds as the FMM
// above (the GMRES solve amplifies the operator's error by about the conditioning of the bead
// system, under 10 here).
TEST(RigidBodies, OpenPseBeadsMatchDirectBeads) {
  const System s = shell_lattice(8, 2, 5);
  const Eigen::VectorXd w = random_vector(6 * 8, 5u);
  double errors[2];
  for (int k = 0; k < 2; ++k) {
    rpyfmm::rpy::pse::PseOptions o;
    o.tolerance = k == 0 ? 1e-3 : 1e-6;
    rpyfmm::rpy::pse::OpenPseRpy pse(1.0, o);
    errors[k] = body_error_against_direct(s, w, pse);
  }
  EXPECT_LE(errors[0], 1e-2);
  EXPECT_GT(errors[0], 0.0);
  EXPECT_LE(errors[1], 1e-5);
}

// Periodic bead operator (PSE): a body straddling the box boundary (its beads wrapped to the
// other side) moves like the same body shifted inside the box (the periodic system is
// translation invariant), to the PSE tolerance; and the reference points are minimum-image
// centroids.
TEST(RigidBodies, PeriodicBodiesMayStraddleTheBox) {
  const double L = 30.0;
  const auto shell = icosphere(1);
  const double a = touching_radius(1) * 2.0;
  std::mt19937 rng(9);
  const Eigen::Matrix3d Q1 = random_rotation(rng), Q2 = random_rotation(rng);
  auto build = [&](const Eigen::Vector3d& shift) {
    System s;
    s.add(shell, 2.0, a, Q1, Eigen::Vector3d(1.0, 15.0, 15.0) + shift);  // crosses x = 0 unshifted
    s.add(shell, 2.0, a, Q2, Eigen::Vector3d(9.0, 12.0, 16.0) + shift);
    return s;
  };
  const Eigen::Vector3d shift(5.0, 0.0, 0.0);
  pse::PseRpy beads(Geometry::periodic(L), 1.0, {.tolerance = 1e-7});
  RigidBodies bodies(beads, {.tolerance = 1e-10});
  const Eigen::VectorXd w = random_vector(12, 6u);
  bodies.set_configuration(build(Eigen::Vector3d::Zero()).x, build(Eigen::Vector3d::Zero()).radii,
                           build(Eigen::Vector3d::Zero()).offsets);
  const auto q = bodies.reference_points();
  EXPECT_NEAR(std::remainder(q[0] - 1.0, L), 0.0, 1e-9);  // the centroid, not the wrapped mean
  const Eigen::VectorXd y0 = solve(bodies, w);
  const System shifted = build(shift);
  bodies.set_configuration(shifted.x, shifted.radii, shifted.offsets);
  EXPECT_LE(rel(solve(bodies, w), y0), 1e-6);
}

// Brownian velocities: for given bead noise z, apply_with_noise gives N W + c N K^T M^{-1} M^{1/2} z
// (M^{1/2} the principal root, dense eigendecomposition here; sampler at 1e-10), and over many
// noise vectors (block-preconditioned sampler: any B with B B^T = M) the noise part has
// covariance c^2 N: 4000 samples of 12 components, relative Frobenius error <= 0.1 (the
// expected sampling error is sqrt((1 + tr(N)^2 / |N|^2) / 4000) <= sqrt(13 / 4000) = 0.057;
// this seed gives 0.049).
TEST(RigidBodies, BrownianVelocitiesHaveCovarianceN) {
  System s;
  std::mt19937 rng(3);
  s.add(icosphere(0), 1.5, 0.7, random_rotation(rng), {0, 0, 0});
  s.add({{0, 0, 0}, {2, 0, 0}, {1, 1.7, 0}, {1, 0.6, 1.6}}, 1.0, 0.9, random_rotation(rng), {3.5, 1, 0});
  DirectRpy beads(Geometry::open(), 1.0);
  RigidBodies bodies(beads, {.tolerance = 1e-11});
  bodies.set_configuration(s.x, s.radii, s.offsets);
  Eigen::MatrixXd lambda_map;
  const Eigen::MatrixXd N = dense_body_mobility(beads, s, &lambda_map);
  const std::vector<double> dense = beads.assemble_dense();
  const auto n3 = static_cast<Eigen::Index>(s.x.size());
  const Eigen::MatrixXd M =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(dense.data(), n3, n3);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M);
  const Eigen::MatrixXd root =
      es.eigenvectors() * es.eigenvalues().cwiseSqrt().asDiagonal() * es.eigenvectors().transpose();
  // N K^T M^{-1} = lambda_map^T (lambda_map = M^{-1} K N, N symmetric).
  const Eigen::VectorXd w = random_vector(12, 5u), z = random_vector(n3, 6u);
  const double c = 0.8;
  Eigen::VectorXd y(12);
  const RigidBodyReport rep = bodies.apply_with_noise({w.data(), 12}, c, {z.data(), std::size_t(n3)}, {y.data(), 12},
                                                      SqrtOptions{.tolerance = 1e-10});
  EXPECT_LE(rel(y, N * w + c * lambda_map.transpose() * root * z), 1e-7);
  EXPECT_GT(rep.sqrt.iterations, 0);

  const int samples = 4000;
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(12, 12);
  std::vector<double> zs(static_cast<std::size_t>(n3)), zero(12, 0.0), ys(12);
  const SqrtOptions block{.tolerance = 1e-6, .preconditioner = SqrtPreconditioner::block, .preconditioner_block = 8};
  for (int k = 0; k < samples; ++k) {
    fill_normal(zs, 17u, static_cast<std::uint64_t>(k));
    bodies.apply_with_noise(zero, 1.0, zs, ys, block);
    const Eigen::Map<const Eigen::VectorXd> v(ys.data(), 12);
    cov += v * v.transpose();
  }
  cov /= samples;
  EXPECT_LE((cov - N).norm() / N.norm(), 0.1);
}

// Bad input: rpyfmm::Error naming the problem, before any work.
// apply_from: GMRES started from a guess. The exact solution needs no iteration beyond the
// first check; a guess 1e-3 off (a slightly moved configuration's solution, as the RFD of
// RigidBodyDynamics has) needs fewer iterations than a cold start and meets the same tolerance
// against the dense N; bad guesses are refused.
TEST(RigidBodies, WarmStartFromAGuess) {
  const System s = five_bodies();
  DirectRpy beads(Geometry::open(), 1.0);
  RigidBodies bodies(beads, {.tolerance = 1e-8});
  bodies.set_configuration(s.x, s.radii, s.offsets);
  const Eigen::MatrixXd N = dense_body_mobility(beads, s);
  const Eigen::VectorXd w = random_vector(30, 9u);
  Eigen::VectorXd y(30), y_warm(30);
  std::vector<double> lambda(s.x.size());
  const RigidBodyReport cold = bodies.apply({w.data(), 30}, {y.data(), 30}, lambda);
  EXPECT_LE(rel(y, N * w), 1e-7);
  // Start from the other configuration's solution: the same bodies moved by 1e-3 of their size.
  System moved = s;
  for (std::size_t i = 0; i < moved.x.size(); ++i) moved.x[i] += 1e-3 * std::sin(double(i));
  DirectRpy moved_beads(Geometry::open(), 1.0);
  RigidBodies moved_bodies(moved_beads, {.tolerance = 1e-8});
  moved_bodies.set_configuration(moved.x, moved.radii, moved.offsets);
  Eigen::VectorXd y_moved(30);
  std::vector<double> lambda_moved(s.x.size());
  moved_bodies.apply({w.data(), 30}, {y_moved.data(), 30}, lambda_moved);
  const RigidBodyReport warm =
      bodies.apply_from({w.data(), 30}, {y_moved.data(), 30}, lambda_moved, {y_warm.data(), 30});
  EXPECT_LE(rel(y_warm, N * w), 1e-7);
  // The guess's relative residual is 7.6e-4 (as far off as the configuration moved), so GMRES
  // starts about three of its eight orders of magnitude closer; one product forms that residual.
  // Measured 7 products warm and 9 cold.
  EXPECT_LE(warm.iterations, cold.iterations - 2) << warm.iterations << " vs " << cold.iterations;
  const RigidBodyReport exact = bodies.apply_from({w.data(), 30}, {y.data(), 30}, lambda, {y_warm.data(), 30});
  EXPECT_LE(exact.iterations, 1);
  EXPECT_LE(rel(y_warm, y), 1e-9);
  std::vector<double> bad(29, 0.0);
  rpyfmm_test::expect_error(
      [&] {
        bodies.apply_from({w.data(), 30}, bad, lambda, {y_warm.data(), 30});
      },
      rpyfmm::ErrorCode::invalid_input, "guess velocities");
  lambda[0] = std::nan("");
  rpyfmm_test::expect_error(
      [&] {
        bodies.apply_from({w.data(), 30}, {y.data(), 30}, lambda, {y_warm.data(), 30});
      },
      rpyfmm::ErrorCode::invalid_input, "guess bead forces");
}

TEST(RigidBodies, BadInput) {
  using rpyfmm::ErrorCode;
  using rpyfmm_test::expect_error;
  DirectRpy beads(Geometry::open(), 1.0);
  expect_error([&] { RigidBodies(beads, {.tolerance = 0.0}); }, ErrorCode::invalid_argument, "tolerance");
  expect_error([&] { RigidBodies(beads, {.max_iterations = 0}); }, ErrorCode::invalid_argument, "max_iterations");
  expect_error([&] { RigidBodies(beads, {.restart = -1}); }, ErrorCode::invalid_argument, "restart");
  RigidBodies bodies(beads);
  const System s = five_bodies();
  std::vector<double> w(30, 1.0), y(30);
  expect_error([&] { bodies.apply(w, y); }, ErrorCode::invalid_input, "before set_configuration");
  const std::vector<std::size_t> bad_end{0, 42, 84, 126, 135, 140};
  expect_error([&] { bodies.set_configuration(s.x, s.radii, bad_end); }, ErrorCode::invalid_input, "end at");
  const std::vector<std::size_t> empty_body{0, 42, 42, 126, 135, 141};
  expect_error([&] { bodies.set_configuration(s.x, s.radii, empty_body); }, ErrorCode::invalid_input,
               "body 1 has no beads");
  const std::vector<std::size_t> two_beads{0, 2, 126, 135, 141};
  expect_error([&] { bodies.set_configuration(s.x, s.radii, two_beads); }, ErrorCode::invalid_input, "at least 3");
  expect_error([&] { bodies.set_configuration(s.x, s.radii, s.offsets, std::vector<double>(5, 0.0)); },
               ErrorCode::invalid_input, "reference points");
  std::vector<double> x = s.x;
  x[7] = std::nan("");
  expect_error([&] { bodies.set_configuration(x, s.radii, s.offsets); }, ErrorCode::invalid_input, "NaN");
  expect_error([&] { bodies.set_configuration(s.x, -1.0, s.offsets); }, ErrorCode::invalid_argument, "radius");
  // A straight rod: its rotation about its axis is undefined.
  std::vector<double> rod;
  for (int i = 0; i < 5; ++i) rod.insert(rod.end(), {2.0 * i, 2.0 * i, 0.0});
  expect_error(
      [&] {
        bodies.set_configuration(rod, 1.0, std::vector<std::size_t>{0, 5});
      },
      ErrorCode::invalid_input, "one line");
  // Coincident beads make the body's bead block singular (the preconditioner's factorization).
  std::vector<double> twin = {0, 0, 0, 0, 0, 0, 2, 0, 0, 0, 2, 0};
  expect_error(
      [&] {
        bodies.set_configuration(twin, 1.0, std::vector<std::size_t>{0, 4});
      },
      ErrorCode::invalid_input, "singular");
  RigidBodies small(beads, {.max_preconditioner_bytes = 1000});
  expect_error([&] { small.set_configuration(s.x, s.radii, s.offsets); }, ErrorCode::out_of_memory, "MiB");
  // A failed configuration leaves the object unconfigured.
  expect_error([&] { bodies.apply(w, y); }, ErrorCode::invalid_input, "before set_configuration");
  bodies.set_configuration(s.x, s.radii, s.offsets);
  expect_error([&] { bodies.apply(std::vector<double>(29, 1.0), y); }, ErrorCode::invalid_input, "forces and torques");
  w[4] = INFINITY;
  expect_error([&] { bodies.apply(w, y); }, ErrorCode::invalid_input, "infinite");
  w[4] = 1.0;
  std::vector<double> lambda(10);
  expect_error([&] { bodies.apply(w, y, lambda); }, ErrorCode::invalid_input, "bead forces");
  beads.set_positions(std::vector<double>(s.x.begin(), s.x.begin() + 30), 1.0);  // behind its back
  expect_error([&] { bodies.apply(w, y); }, ErrorCode::invalid_input, "set elsewhere");
  bodies.set_configuration(s.x, s.radii, s.offsets);
  std::vector<double> z(s.x.size(), 0.5);
  expect_error([&] { bodies.apply_with_noise(w, 1.0, std::vector<double>(5, 0.0), y); }, ErrorCode::invalid_input,
               "bead noise z");
  expect_error([&] { bodies.apply_with_noise(w, -1.0, z, y); }, ErrorCode::invalid_argument, "noise_scale");
  z[3] = std::nan("");
  expect_error([&] { bodies.apply_with_noise(w, 1.0, z, y); }, ErrorCode::invalid_input, "NaN");
  RigidBodies hurried(beads, {.tolerance = 1e-12, .max_iterations = 2});
  hurried.set_configuration(s.x, s.radii, s.offsets);
  expect_error([&] { hurried.apply(w, y); }, ErrorCode::numerical_failure, "did not reach");
}
