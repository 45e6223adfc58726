// FmmRpy on suspensions of force dipoles against the exact direct operator (DirectRpy): pairs of
// spheres at 2.1 radii with equal and opposite forces along their axis (dumbbells with an internal
// spring). Their far field cancels to a dipole's, which amplifies the Laplace FMM's own error in
// the far-field combination (docs/theory/rpy.md, Sec. 2, "Tolerance"); the contract
// ||U_fmm - U_direct|| <= tolerance ||U_direct|| must hold here too, with no slack, at tolerances
// on the plane-wave tables' steps (the hardest points) and between them, with and without torques.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "configurations.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"

using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::FmmRpy;
using rpyfmm::rpy::FmmRpyOptions;
using rpyfmm::rpy::Geometry;
using rpyfmm::testing::relative_l2;

namespace {

/// `pairs` dumbbells with centres uniform in [0, side)^3 and random axes; the force on the first
/// sphere is g u (g standard normal, u the unit axis), on the second -g u; with torques, t and -t.
struct Dumbbells {
  std::vector<double> x, f, t;
};

Dumbbells dumbbells(std::size_t pairs, double side, unsigned seed) {
  std::mt19937_64 gen(seed);
  std::uniform_real_distribution<double> uniform(0.0, side);
  std::normal_distribution<double> normal;
  Dumbbells d;
  d.x.resize(6 * pairs);
  d.f.resize(6 * pairs);
  d.t.resize(6 * pairs);
  for (std::size_t i = 0; i < pairs; ++i) {
    double u[3], c[3];
    for (double& v : c) v = uniform(gen);
    double norm = 0;
    for (double& v : u) norm += (v = normal(gen)) * v;
    norm = std::sqrt(norm);
    const double g = normal(gen);
    for (int k = 0; k < 3; ++k) {
      const std::size_t first = 3 * i + k, second = 3 * (pairs + i) + k;
      d.x[first] = c[k];
      d.x[second] = c[k] + 2.1 * u[k] / norm;
      d.f[first] = g * u[k] / norm;
      d.f[second] = -d.f[first];
      d.t[first] = normal(gen);
      d.t[second] = -d.t[first];
    }
  }
  return d;
}

// The two sizes of the rule's measurement (fmm_laplace_accuracy.cpp): 4000 spheres in a cube of
// side 40 radii and 16000 in one of side 60.
const Dumbbells& small_set() {
  static const Dumbbells d = dumbbells(2000, 40.0, 1);
  return d;
}
const Dumbbells& large_set() {
  static const Dumbbells d = dumbbells(8000, 60.0, 2);
  return d;
}

struct Direct {
  std::vector<double> u, w, u_forces_only;
};

Direct direct(const Dumbbells& d) {
  DirectRpy op(Geometry::open(), 1.0);
  op.set_positions(d.x, 1.0);
  Direct r;
  r.u.resize(d.x.size());
  r.w.resize(d.x.size());
  r.u_forces_only.resize(d.x.size());
  op.apply(d.f, r.u_forces_only);
  op.apply(d.f, d.t, r.u, r.w);
  return r;
}

void check(const Dumbbells& d, const Direct& ref, double tolerance, bool torques, const char* what) {
  FmmRpy op(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = tolerance});
  op.set_positions(d.x, 1.0);
  std::vector<double> u(d.x.size()), w(d.x.size());
  op.apply(d.f, u);
  const double e = relative_l2(u, ref.u_forces_only);
  EXPECT_LE(e, tolerance) << what << " tolerance " << tolerance;
  std::printf("%-6s tol %.0e: U %.3f tol", what, tolerance, e / tolerance);
  if (torques) {
    op.apply(d.f, d.t, u, w);
    const double eu = relative_l2(u, ref.u), ew = relative_l2(w, ref.w);
    EXPECT_LE(eu, tolerance) << what << " tolerance " << tolerance << " U with torques";
    EXPECT_LE(ew, tolerance) << what << " tolerance " << tolerance << " W";
    std::printf("  with torques: U %.3f tol  W %.3f tol", eu / tolerance, ew / tolerance);
  }
  std::printf("\n");
}

}  // namespace

TEST(FmmRpyForceDipoles, OnTheTablesSteps) {
  const Direct small = direct(small_set()), large = direct(large_set());
  for (double tolerance : {1e-3, 1e-6, 1e-9}) {
    check(small_set(), small, tolerance, tolerance > 1e-9, "small");
    check(large_set(), large, tolerance, tolerance > 1e-9, "large");
  }
}

TEST(FmmRpyForceDipoles, BetweenTheSteps) {
  const Direct large = direct(large_set());
  for (double tolerance : {3e-3, 3e-4, 3e-6, 3e-8}) check(large_set(), large, tolerance, false, "large");
}
