// Benchmark of the rigid-body mobility (rpyfmm/rpy/rigid_bodies.hpp): a suspension of m
// bead-shell spheres (icosphere_beads, touching beads) of radius R = 2 at body volume fraction
// phi, randomly oriented, placed at random without overlap in a cube. For each bead operator
// (direct, or FMM at a tolerance) and body count: the setup (bead plan + body factorizations),
// GMRES iterations and time of one mobility solve N W (random forces and torques), and their
// ratio to one bead product M F; medians of `repeats`. Also one Brownian solve
// (apply_with_noise: block-preconditioned bead noise B z at tolerance 1e-3, then GMRES): its time
// and the bead sampler's iterations. With `plain`, also unpreconditioned
// GMRES (capped at 2000 iterations; small systems only). With the direct operator and at most
// 4000 beads, also the dense reference: M assembled, then its Cholesky and N = (K^T M^{-1} K)^{-1}
// (Eigen; dense_s times these, not the assembly) and the relative difference of the GMRES
// velocities from it. Prints one CSV row per case.
//
// usage: bench_rigid [operator=direct|fmm] [body counts] [subdivisions] [phi] [gmres tol]
//                    [fmm eps] [repeats] [plain|noplain]
//        bench_rigid direct 8,64 2 0.1 1e-6
//        bench_rigid fmm 64,512 2 0.1 1e-6 1e-6 3
#include <omp.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"
#include "shell_suspension.hpp"

using namespace rpyfmm::rpy;
using rpyfmm::StopWatch;

namespace {

std::vector<std::size_t> parse_counts(const std::string& s) {
  std::vector<std::size_t> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) v.push_back(static_cast<std::size_t>(std::stod(item)));
  return v;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

/// The suspension with lab-frame bead positions (shell_suspension.hpp).
struct Suspension {
  std::vector<double> x, radii;
  std::vector<std::size_t> offsets;
};

Suspension suspension(std::size_t m, int subdivisions, double phi, unsigned seed) {
  const rpyfmm_bench::ShellSuspension s = rpyfmm_bench::shell_suspension(m, subdivisions, phi, seed);
  return {s.positions(), s.radii, s.offsets};
}

}  // namespace

int main(int argc, char** argv) {
  const std::string opname = argc > 1 ? argv[1] : "direct";
  const auto counts = parse_counts(argc > 2 ? argv[2] : "8,64");
  const int subdivisions = argc > 3 ? std::stoi(argv[3]) : 2;
  const double phi = argc > 4 ? std::stod(argv[4]) : 0.1;
  const double tol = argc > 5 ? std::stod(argv[5]) : 1e-6;
  const double eps = argc > 6 ? std::stod(argv[6]) : 1e-6;
  const int repeats = argc > 7 ? std::stoi(argv[7]) : 3;
  const bool plain = argc > 8 && std::string(argv[8]) == "plain";
  std::printf(
      "operator,eps,bodies,beads,threads,phi,tol,setup_s,iterations,solve_s,product_s,solve_over_product,"
      "plain_iterations,plain_solve_s,dense_s,dense_rel_diff,noise_solve_s,noise_sqrt_iterations\n");
  for (std::size_t m : counts) {
    const Suspension s = suspension(m, subdivisions, phi, 42u + m);
    std::unique_ptr<MobilityOperator> beads;
    if (opname == "fmm") {
      beads = std::make_unique<FmmRpy>(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = eps});
    } else {
      beads = std::make_unique<DirectRpy>(Geometry::open(), 1.0);
    }
    RigidBodies bodies(*beads, {.tolerance = tol});
    StopWatch setup;
    bodies.set_configuration(s.x, s.radii, s.offsets);
    const double setup_s = setup.seconds();
    std::mt19937_64 rng(7);
    std::normal_distribution<double> g;
    std::vector<double> w(6 * m), y(6 * m), f(s.x.size()), u(s.x.size());
    for (double& v : f) v = g(rng);
    std::vector<double> ts, tp;
    int iterations = 0;
    for (int r = 0; r < repeats; ++r) {
      for (double& v : w) v = g(rng);
      StopWatch product;
      beads->apply(f, u);
      tp.push_back(product.seconds());
      StopWatch solve;
      iterations = bodies.apply(w, y).iterations;
      ts.push_back(solve.seconds());
    }
    std::vector<double> z(s.x.size());
    for (double& v : z) v = g(rng);
    StopWatch noise;
    const RigidBodyReport noisy = bodies.apply_with_noise(
        w, 1.0, z, y, SqrtOptions{.tolerance = 1e-3, .preconditioner = SqrtPreconditioner::automatic});
    const double noise_s = noise.seconds();
    int plain_iterations = 0;
    double plain_s = 0.0;
    if (plain) {
      RigidBodies unpreconditioned(*beads, {.tolerance = tol, .max_iterations = 2000, .precondition = false});
      unpreconditioned.set_configuration(s.x, s.radii, s.offsets);
      StopWatch solve;
      try {
        plain_iterations = unpreconditioned.apply(w, y).iterations;
      } catch (const rpyfmm::Error&) {
        plain_iterations = -2000;  // did not converge within the cap
      }
      plain_s = solve.seconds();
    }
    double dense_s = 0.0, dense_diff = 0.0;
    if (opname == "direct" && s.radii.size() <= 4000) {
      const auto n3 = static_cast<Eigen::Index>(s.x.size());
      const std::vector<double> flat = beads->assemble_dense();
      StopWatch dense;  // the dense solve, after assembling M (3N products here)
      const Eigen::MatrixXd M =
          Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(flat.data(), n3, n3);
      Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n3, static_cast<Eigen::Index>(6 * m));
      const auto q = bodies.reference_points();
      for (std::size_t k = 0; k < m; ++k)
        for (std::size_t i = s.offsets[k]; i < s.offsets[k + 1]; ++i) {
          const auto r = static_cast<Eigen::Index>(3 * i), c = static_cast<Eigen::Index>(6 * k);
          const double ax = s.x[3 * i] - q[3 * k], ay = s.x[3 * i + 1] - q[3 * k + 1],
                       az = s.x[3 * i + 2] - q[3 * k + 2];
          K.block<3, 3>(r, c).setIdentity();
          K(r, c + 4) = az, K(r, c + 5) = -ay, K(r + 1, c + 3) = -az, K(r + 1, c + 5) = ax, K(r + 2, c + 3) = ay,
                   K(r + 2, c + 4) = -ax;
        }
      const Eigen::MatrixXd N = (K.transpose() * Eigen::LLT<Eigen::MatrixXd>(M).solve(K)).inverse();
      const Eigen::VectorXd ref = N * Eigen::Map<const Eigen::VectorXd>(w.data(), static_cast<Eigen::Index>(6 * m));
      dense_s = dense.seconds();
      bodies.apply(w, y);
      dense_diff = (Eigen::Map<const Eigen::VectorXd>(y.data(), ref.size()) - ref).norm() / ref.norm();
    }
    std::printf("%s,%.0e,%zu,%zu,%d,%.2f,%.0e,%.4e,%d,%.4e,%.4e,%.2f,%d,%.4e,%.4e,%.2e,%.4e,%d\n", opname.c_str(),
                opname == "fmm" ? eps : 0.0, m, s.radii.size(), omp_get_max_threads(), phi, tol, setup_s, iterations,
                median(ts), median(tp), median(ts) / median(tp), plain_iterations, plain_s, dense_s, dense_diff,
                noise_s, noisy.sqrt.iterations);
    std::fflush(stdout);
  }
  return 0;
}
