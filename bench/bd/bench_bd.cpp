// BD step throughput and where the time goes (integrator: docs/theory/bd.md).
//
//   bench_bd steps  --method none|direct|fmm|pse --n 1000,3000,10000 [--steps 5] [--tol 1e-3]
//                   [--split-displacements] [--preconditioner automatic|block|none] [--block B]
//                   [--device cpu|cuda]
//       one CSV row per N: seconds per step (median of the per-step times after one
//       warm-up step), Lanczos iterations and mobility products per step, and the
//       time split (neighbours, forces, plan, drift = M F or M [F, z], sqrt, update).
//       System: random cloud at phi = 0.05 (radius 1, WCA, gravity 1, kT 1, dt 0.01);
//       pse: the same particles at phi = 0.05 in a periodic cube. With pse a step is one
//       fused pass (drift and noise share the wave-space FFTs, timed as drift);
//       --split-displacements keeps the drift and Brownian parts apart, which takes the
//       separate M F + split-sampler path. --preconditioner: the Lanczos sampler's block
//       preconditioner (the BD default automatic = block for direct and fmm; none = M^{1/2} z,
//       without the block preconditioner), column `preconditioner`; --block: particles per
//       block (0 = automatic). --device cuda: the mobility on a GPU (pse only; column `device`).
//   bench_bd neighbours --n 20000 [--steps 400]
//       The GPU BD paper's Tables 1-3 (docs/theory/bd.md): dynamic rebuild test (skin/2)
//       against fixed intervals, free draining, WCA at phi = 0.15 in a periodic box: rebuilds,
//       time per step, and
//       for fixed intervals the steps on which some particle had moved more than skin/2
//       since the last build (pairs may have been missed). --skin (default 1.0 a).
// Threads: OMP_NUM_THREADS.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/core/timer.hpp"

using namespace rpyfmm::bd;

namespace {
std::string arg(int argc, char** argv, const std::string& key, const std::string& fallback) {
  for (int i = 2; i + 1 < argc; ++i)
    if (key == argv[i]) return argv[i + 1];
  return fallback;
}
std::vector<std::size_t> sizes(const std::string& list) {
  std::vector<std::size_t> v;
  std::stringstream s(list);
  for (std::string item; std::getline(s, item, ',');) v.push_back(static_cast<std::size_t>(std::stod(item)));
  return v;
}
double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

RunConfig cloud_config(std::size_t n, const std::string& method, double tol, bool periodic, double phi,
                       bool split_displacements = false, const std::string& device = "cpu") {
  std::ostringstream t;
  t << "[system]\n";
  if (periodic) {
    const double L = std::cbrt(static_cast<double>(n) * 4.0 / 3.0 * M_PI / phi);
    t << "geometry = \"periodic\"\nbox = [" << L << ", " << L << ", " << L << "]\n";
  }
  t << "[[types]]\nname = \"s\"\nradius = 1.0\nexternal_force = [0.0, 0.0, -1.0]\n"
    << "[particles]\nsource = \"random\"\ncount = " << n << "\n"
    << (periodic ? "" : "volume_fraction = " + std::to_string(phi) + "\n")
    << "[[pair]]\ntypes = [\"s\", \"s\"]\nkind = \"wca\"\n"
    << "[integrator]\ndt = 0.01\nsteps = 1\nseed = 3\nmax_displacement = 1.0\n"
    << "split_displacements = " << (split_displacements ? "true" : "false") << "\n"
    << "[mobility]\nmethod = \"" << method << "\"\ntolerance = " << tol << "\ndevice = \"" << device << "\"\n";
  return parse_config(t.str(), "bench");
}

int bench_steps(int argc, char** argv) {
  const std::string method = arg(argc, argv, "--method", "direct");
  const int steps = std::stoi(arg(argc, argv, "--steps", "5"));
  const double tol = std::stod(arg(argc, argv, "--tol", "1e-3"));
  bool split = false;
  for (int i = 2; i < argc; ++i) split = split || std::string(argv[i]) == "--split-displacements";
  const std::string preconditioner = arg(argc, argv, "--preconditioner", "automatic");
  const std::string device = arg(argc, argv, "--device", "cpu");
  std::printf(
      "method,device,preconditioner,N,threads,sec_per_step,steps_per_sec,lanczos_its,products,neighbours,forces,plan,"
      "drift,"
      "sqrt,update\n");
  for (std::size_t n : sizes(arg(argc, argv, "--n", "1000,3000"))) {
    RunConfig c = cloud_config(n, method, tol, method == "pse", 0.05, split, device);
    c.integrator.sqrt.preconditioner = rpyfmm::rpy::sqrt_preconditioner_from_string(preconditioner);
    c.integrator.sqrt.preconditioner_block = std::stoi(arg(argc, argv, "--block", "0"));
    const ForceField ff = make_force_field(c);
    const InitialState s = make_particles(c, ff);
    Integrator bd(make_mobility(c.mobility, n), ff, c.integrator, s.positions, s.types, c.neighbours);
    bd.step();  // warm-up (first neighbour build, allocations)
    const IntegratorTotals before = bd.totals();
    std::vector<double> per_step;
    for (int k = 0; k < steps; ++k) {
      rpyfmm::StopWatch w;
      bd.step();
      per_step.push_back(w.seconds());
    }
    const auto& t = bd.totals();
    const double ns = steps;
    auto part = [&](const char* p) { return (t.seconds.at(p) - before.seconds.at(p)) / ns; };
    const double med = median(per_step);
    std::printf("%s,%s,%s,%zu,%d,%.4g,%.4g,%.1f,%.1f,%.3g,%.3g,%.3g,%.3g,%.3g,%.3g\n", method.c_str(), device.c_str(),
                preconditioner.c_str(), n, omp_get_max_threads(), med, 1.0 / med,
                static_cast<double>(t.sqrt_iterations - before.sqrt_iterations) / ns,
                static_cast<double>(t.mobility_products - before.mobility_products) / ns, part("neighbours"),
                part("forces"), part("plan"), part("drift"), part("sqrt"), part("update"));
    std::fflush(stdout);
  }
  return 0;
}

int bench_neighbours(int argc, char** argv) {
  const std::size_t n = sizes(arg(argc, argv, "--n", "20000")).front();
  const int steps = std::stoi(arg(argc, argv, "--steps", "400"));
  const double skin = std::stod(arg(argc, argv, "--skin", "1.0"));
  std::printf("strategy,N,threads,steps,rebuilds,steps_per_rebuild,sec_per_step,neighbour_sec_per_step,unsafe_steps\n");
  for (int interval : {0, 5, 10, 20, 40, 80}) {
    RunConfig c = cloud_config(n, "none", 1e-3, true, 0.15);
    c.neighbours.skin = skin;
    c.neighbours.fixed_interval = interval;
    c.external_force = {0, 0, 0};
    c.types[0].external_force = {0, 0, 0};
    c.integrator.dt = 0.01;  // rms step 0.033 a per axis
    const ForceField ff = make_force_field(c);
    const InitialState s = make_particles(c, ff);
    Integrator bd(make_mobility(c.mobility, n), ff, c.integrator, s.positions, s.types, c.neighbours);
    std::vector<double> ref(bd.positions().begin(), bd.positions().end());
    std::size_t last_builds = 0;
    int unsafe = 0;
    rpyfmm::StopWatch w;
    std::vector<double> before;
    const std::string name = interval == 0 ? "dynamic(skin/2)" : "fixed-" + std::to_string(interval);
    try {
      for (int k = 0; k < steps; ++k) {
        before.assign(bd.positions().begin(), bd.positions().end());
        bd.step();
        if (bd.neighbour_rebuilds() != last_builds) {  // the list was built from the positions before this step
          last_builds = bd.neighbour_rebuilds();
          ref = before;
        }
        double worst =
            0;  // displacement since the last build (the GPU BD paper's Algorithm 1, line 15; docs/theory/bd.md)
        for (std::size_t i = 0; i < n; ++i) {
          double d2 = 0;
          for (int q = 0; q < 3; ++q) d2 += std::pow(bd.positions()[3 * i + q] - ref[3 * i + q], 2);
          worst = std::max(worst, d2);
        }
        unsafe += std::sqrt(worst) > 0.5 * c.neighbours.skin;
      }
    } catch (const std::exception& e) {  // a missed pair let particles overlap: report and go on
      std::printf("%s,%zu,%d,FAILED at step %llu: %s\n", name.c_str(), n, omp_get_max_threads(),
                  static_cast<unsigned long long>(bd.step_count()), e.what());
      continue;
    }
    const double sec = w.seconds();
    std::printf("%s,%zu,%d,%d,%zu,%.1f,%.4g,%.4g,%d\n", name.c_str(), n, omp_get_max_threads(), steps,
                bd.neighbour_rebuilds(), static_cast<double>(steps) / static_cast<double>(bd.neighbour_rebuilds()),
                sec / steps, bd.totals().seconds.at("neighbours") / steps, interval == 0 ? 0 : unsafe);
    std::fflush(stdout);
  }
  return 0;
}
}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  try {
    if (mode == "steps") return bench_steps(argc, argv);
    if (mode == "neighbours") return bench_neighbours(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_bd: %s\n", e.what());
    return 2;
  }
  std::fprintf(stderr, "usage: bench_bd steps|neighbours [--method M] [--n N1,N2] [--steps S] [--tol T]\n");
  return 2;
}
