// Benchmark of rigid-body Brownian dynamics (rpyfmm/bd/rigid_dynamics.hpp): m bead-shell spheres
// (icosphere_beads, touching beads, radius R = 2) at body volume fraction phi, randomly placed
// without overlap and randomly oriented, settling under a unit force each, kT = 1, dt small
// enough for the blow-up guard. For each bead operator (direct, or FMM at eps) and body count:
// seconds per step with the random-finite-difference drift and without it (drift = none), and
// the per-stage split of the RFD step (plan, bead noise B z, velocity solve, drift: two plans and
// two solves), with the GMRES and sampler iterations per step; medians of `repeats` runs of
// `steps` steps each (after one warm-up step). With the FMM operator and at most 25000 beads,
// also the drift estimate's relative difference from the direct operator's for the same w (how
// far the FMM's error, divided by rfd_delta, moves the drift). One CSV row per case and drift.
//
// usage: bench_rigid_dynamics [direct|fmm] [body counts] [subdivisions] [phi] [steps] [repeats] [fmm eps]
//        bench_rigid_dynamics direct 8,64 1 0.1 5 3
//        bench_rigid_dynamics fmm 64,512 1 0.1 3 3 1e-6
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "rpyfmm/bd/rigid_dynamics.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"
#include "shell_suspension.hpp"

using namespace rpyfmm;

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

std::unique_ptr<rpy::MobilityOperator> make_operator(const std::string& name, double eps) {
  if (name == "fmm")
    return std::make_unique<rpy::FmmRpy>(rpy::Geometry::open(), 1.0, rpy::FmmRpyOptions{.tolerance = eps});
  return std::make_unique<rpy::DirectRpy>(rpy::Geometry::open(), 1.0);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string opname = argc > 1 ? argv[1] : "direct";
  const auto counts = parse_counts(argc > 2 ? argv[2] : "8,64");
  const int subdivisions = argc > 3 ? std::stoi(argv[3]) : 1;
  const double phi = argc > 4 ? std::stod(argv[4]) : 0.1;
  const int steps = argc > 5 ? std::stoi(argv[5]) : 5;
  const int repeats = argc > 6 ? std::stoi(argv[6]) : 3;
  const double eps = argc > 7 ? std::stod(argv[7]) : 1e-6;
  std::printf(
      "operator,eps,bodies,beads,threads,phi,drift,step_s,plan_s,sqrt_s,solve_s,drift_s,solve_iterations,"
      "drift_iterations,sqrt_iterations,drift_rel_diff_vs_direct\n");
  for (std::size_t m : counts) {
    const rpyfmm_bench::ShellSuspension s = rpyfmm_bench::shell_suspension(m, subdivisions, phi, 7u + unsigned(m));
    const std::size_t n = s.radii.size();
    // Settling: a unit force along -z on every body. dt: a tenth of the time to settle 0.05 R
    // (one sphere's Stokes speed ~ 1 / (6 pi R)), well inside the blow-up guard.
    const double dt = 0.1 * 0.05 * 2.0 * 6.0 * std::numbers::pi * 2.0;
    const bd::BodyForceFunction gravity = [](const bd::RigidBodyState&, std::span<double> w) {
      for (std::size_t k = 0; k < w.size(); k += 6) w[k + 2] = -1.0;
    };
    double drift_rel_diff = -1.0;
    if (opname == "fmm" && n <= 25000) {
      // The same w on the FMM and on the direct operator, at the initial state.
      std::vector<double> w(6 * m), fmm_drift(6 * m), direct_drift(6 * m);
      rpy::fill_normal(w, 5u, 0u);
      auto fmm = make_operator("fmm", eps);
      auto direct = make_operator("direct", eps);
      const bd::RigidDynamicsOptions o{.dt = dt};
      bd::RigidBodyDynamics a(*fmm, s.shape, s.radii, s.offsets, s.centres, s.orientations, o);
      bd::RigidBodyDynamics b(*direct, s.shape, s.radii, s.offsets, s.centres, s.orientations, o);
      a.drift_estimate(w, fmm_drift);
      b.drift_estimate(w, direct_drift);
      double diff = 0.0, norm = 0.0;
      for (std::size_t i = 0; i < w.size(); ++i) {
        diff += std::pow(fmm_drift[i] - direct_drift[i], 2);
        norm += direct_drift[i] * direct_drift[i];
      }
      drift_rel_diff = std::sqrt(diff / norm);
    }
    for (const auto drift : {bd::RigidDrift::random_finite_difference, bd::RigidDrift::none}) {
      std::vector<double> step_s, plan_s, sqrt_s, solve_s, drift_s, iters[3];
      for (int r = 0; r < repeats; ++r) {
        auto beads = make_operator(opname, eps);
        bd::RigidBodyDynamics sim(std::move(beads), s.shape, s.radii, s.offsets, s.centres, s.orientations,
                                  {.dt = dt, .kT = 1.0, .seed = 3u + unsigned(r), .drift = drift}, gravity);
        sim.step();  // warm-up (first plans, allocations)
        const auto before = sim.totals();
        StopWatch watch;
        sim.run(static_cast<std::uint64_t>(steps));
        const double seconds = watch.seconds();
        const auto& after = sim.totals();
        const auto stage = [&](const char* key) {
          const auto a = after.seconds.find(key), b = before.seconds.find(key);
          return ((a == after.seconds.end() ? 0.0 : a->second) - (b == before.seconds.end() ? 0.0 : b->second)) / steps;
        };
        step_s.push_back(seconds / steps);
        plan_s.push_back(stage("plan"));
        sqrt_s.push_back(stage("sqrt"));
        solve_s.push_back(stage("solve"));
        drift_s.push_back(stage("drift"));
        iters[0].push_back(double(after.solve_iterations - before.solve_iterations) / steps);
        iters[1].push_back(double(after.drift_iterations - before.drift_iterations) / steps);
        iters[2].push_back(double(after.sqrt_iterations - before.sqrt_iterations) / steps);
      }
      std::printf("%s,%g,%zu,%zu,%d,%g,%s,%.5g,%.4g,%.4g,%.4g,%.4g,%.1f,%.1f,%.1f,%.3g\n", opname.c_str(),
                  opname == "fmm" ? eps : 0.0, m, n, omp_get_max_threads(), phi,
                  drift == bd::RigidDrift::none ? "none" : "rfd", median(step_s), median(plan_s), median(sqrt_s),
                  median(solve_s), median(drift_s), median(iters[0]), median(iters[1]), median(iters[2]),
                  drift == bd::RigidDrift::none ? -1.0 : drift_rel_diff);
      std::fflush(stdout);
    }
  }
  return 0;
}
