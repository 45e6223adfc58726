// BD step throughput and where the time goes (integrator: docs/theory/bd.md).
//
//   bench_bd steps  --method none|direct|fmm|pse|pse-open --n 1000,3000,10000 [--steps 5] [--tol 1e-3]
//                   [--split-displacements] [--preconditioner automatic|block|none] [--block B]
//                   [--device cpu|cuda]
//       one CSV row per N: seconds per step (median of the per-step times after one
//       warm-up step), Lanczos iterations and mobility products per step, and the
//       time split (neighbours, forces, plan, drift = M F or M [F, z], sqrt, update).
//       System: random cloud at phi = 0.05 (radius 1, WCA, gravity 1, kT 1, dt 0.01);
//       pse: the same particles at phi = 0.05 in a periodic cube; pse-open: PSE in free space on
//       the cloud itself (OpenPseRpy). With pse and pse-open a step is one
//       fused pass (drift and noise share the wave-space FFTs, timed as drift);
//       --split-displacements keeps the drift and Brownian parts apart, which takes the
//       separate M F + split-sampler path. --preconditioner: the Lanczos sampler's block
//       preconditioner (the BD default automatic = block for direct and fmm; none = M^{1/2} z,
//       without the block preconditioner), column `preconditioner`; --block: particles per
//       block (0 = automatic). --device cuda: the mobility on a GPU (pse only; column `device`).
//   bench_bd neighbours --n 20000 [--steps 400]
//       Tran et al. (2015)'s Tables 1-3 (docs/theory/bd.md): dynamic rebuild test (skin/2)
//       against fixed intervals, free draining, WCA at phi = 0.15 in a periodic box: rebuilds,
//       time per step, and
//       for fixed intervals the steps on which some particle had moved more than skin/2
//       since the last build (pairs may have been missed). --skin (default 1.0 a).
//   bench_bd engine --engine cpu|cuda|host --n 1000000 [--steps 50] [--strategies dynamic,fixed-10,every]
//       Tran et al. (2015)'s Tables 1-3 setup on a whole engine: free-draining WCA spheres (radius 1)
//       at phi = 0.15 in a periodic box, dt 0.01 (rms step 0.033 a per axis), skin 1.0 a, stepped by
//       the Integrator on the CPU engine, the device engine on a CUDA device, or the device engine's
//       stages on the host (host launcher). One CSV row per rebuild strategy: the dynamic test
//       (skin/2, Algorithm 1), a fixed interval, or a rebuild every step; milliseconds per step
//       (the mean over --steps steps after 5 warm-up steps, rebuilds included, as the paper's
//       average) and its parts: neighbours (rebuild test and lists), forces, and update, the rest of
//       the step (noise, mobility, the position update and the blow-up guard; Table 2's
//       updatePosition).
//   bench_bd sac-table4 [--steps 20] [--warmup 3] [--scheme sac|naive] [--systems 0,1,2]
//       Tran et al. (2015)'s Table 4 (Sec. 4.3): alumina (a = 200 nm, Langevin) with silica
//       (a = 12.5 nm, Brownian), 200 + 2969, 200 + 29699 and 300 + 44549 particles, dt = 5e-10 s.
//       One CSV row per system: milliseconds per iteration (the mean over --steps steps after
//       --warmup steps, neighbour rebuilds included, as the paper's average) next to the paper's
//       K20m figure for that system. Potentials and units are those of
//       examples/bd/alumina_silica (its README: the Annex's alumina-silica and silica-silica DLVO
//       pairs diverge at contact, so a 36-18 well and WCA stand in for them); surface potentials
//       from Table 5 at R = 0.2 %. Box: periodic cube with alumina volume fraction 0.03 (Annex 2:
//       L^3 = n_A (4/3) pi a_A^3 / phi); random sequential addition, alumina first, then silica,
//       with gaps of 2 % of the contact distance. --systems picks rows by index. Columns: the
//       stages per iteration (neighbours with the SAC membership update, forces with the
//       complex sums, the rest), the list radius (one list for all pairs: the largest cutoff,
//       alumina-alumina, plus its skin) and list entries per particle, rebuilds while timed,
//       complexes and adsorbed particles at the end.
// Threads: OMP_NUM_THREADS.
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/bd/step_engine.hpp"
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
    // max_displacement 10: a cloud of 1e6 spheres settles collectively ~4400 times faster than one
    // sphere (U/U0 = 1 + 1.2 N a/R, examples/bd/sedimenting_cloud), 2 radii per step at dt = 0.01.
    << "[integrator]\ndt = 0.01\nsteps = 1\nseed = 3\nmax_displacement = 10.0\n"
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
    // pse-open: the pse method without a box, i.e. OpenPseRpy on the free-space cloud.
    RunConfig c = cloud_config(n, method == "pse-open" ? "pse" : method, tol, method == "pse", 0.05, split, device);
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
            0;  // displacement since the last build (Tran et al. (2015)'s Algorithm 1, line 15; docs/theory/bd.md)
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
// The device engine's choice by name: "cpu", "cuda" or "host" (the host launcher).
StepEngine engine_named(const std::string& name) {
  if (name == "cpu") return StepEngine::cpu;
  if (name == "cuda") return StepEngine::cuda;
  if (name == "host") return StepEngine::host_launcher;
  throw std::invalid_argument("--engine must be cpu, cuda or host, got '" + name + "'");
}

// The fixed interval of a strategy's name: dynamic = 0 (the test), every = 1, fixed-K = K.
int rebuild_interval(const std::string& strategy) {
  if (strategy == "dynamic") return 0;
  if (strategy == "every") return 1;
  if (strategy.rfind("fixed-", 0) == 0) return std::stoi(strategy.substr(6));
  throw std::invalid_argument("strategy must be dynamic, every or fixed-K, got '" + strategy + "'");
}

int bench_engine(int argc, char** argv) {
  const std::string engine_name = arg(argc, argv, "--engine", "cpu");
  const StepEngine engine = engine_named(engine_name);
  const std::size_t n = sizes(arg(argc, argv, "--n", "1000000")).front();
  const int steps = std::stoi(arg(argc, argv, "--steps", "50"));
  std::printf("engine,strategy,N,threads,steps,rebuilds,ms_per_step,neighbours_ms,forces_ms,update_ms\n");
  RunConfig c = cloud_config(n, "none", 1e-3, true, 0.15);
  c.neighbours.skin = 1.0;
  c.external_force = {0, 0, 0};
  c.types[0].external_force = {0, 0, 0};
  c.integrator.engine = engine;
  const ForceField ff = make_force_field(c);
  const InitialState s = make_particles(c, ff);  // once: the same start for every strategy
  std::stringstream list(arg(argc, argv, "--strategies", "dynamic,fixed-10,every"));
  for (std::string strategy; std::getline(list, strategy, ',');) {
    c.neighbours.fixed_interval = rebuild_interval(strategy);
    Integrator bd(engine_mobility(c.mobility, engine, n), ff, c.integrator, s.positions, s.types, c.neighbours);
    bd.run(5);  // warm-up: the first lists, allocations, the device's first launches
    const IntegratorTotals before = bd.totals();
    const std::size_t builds = bd.neighbour_rebuilds();
    rpyfmm::StopWatch w;
    bd.run(static_cast<std::uint64_t>(steps));
    const double ms = 1e3 * w.seconds() / steps;
    auto part = [&](const char* p) { return 1e3 * (bd.totals().seconds.at(p) - before.seconds.at(p)) / steps; };
    const double neighbours = part("neighbours"), forces = part("forces");
    std::printf("%s,%s,%zu,%d,%d,%zu,%.4g,%.4g,%.4g,%.4g\n", engine_name.c_str(), strategy.c_str(), n,
                omp_get_max_threads(), steps, bd.neighbour_rebuilds() - builds, ms, neighbours, forces,
                ms - neighbours - forces);
    std::fflush(stdout);
  }
  return 0;
}
// One row of Tran et al. (2015)'s Table 4: particle counts and the K20m time per iteration.
struct Table4System {
  std::size_t alumina;
  std::size_t silica;
  double k20m_ms;
};
constexpr std::array<Table4System, 3> kTable4{{{200, 2969, 0.85}, {200, 29699, 2.92}, {300, 44549, 3.87}}};
constexpr double kAluminaRadius = 200.0;  // nm
constexpr double kSilicaRadius = 12.5;    // nm
constexpr double kAluminaPhi = 0.03;      // Annex 2's volume fraction

// The types, pairs and units of examples/bd/alumina_silica/alumina_silica.toml (nm, kT at 293 K,
// water viscosity 1: dt = 2.0226 time units = 5e-10 s, Sec. 4.1) in a periodic box of side L (nm),
// with Table 5's surface potentials at R = 0.2 % (+45 / -20 mV; only the alumina-alumina DLVO
// pair uses them).
RunConfig table4_config(double L, const std::string& scheme) {
  std::ostringstream t;
  t << "[system]\ngeometry = \"periodic\"\nbox = [" << L << ", " << L << ", " << L << "]\n"
    << "viscosity = 1.0\nkT = 1.0\n"
    << "[[types]]\nname = \"alumina\"\nradius = " << kAluminaRadius
    << "\nsurface_potential = 0.045\ndynamics = \"langevin\"\ndensity = 0.01606\n"
    << "[[types]]\nname = \"silica\"\nradius = " << kSilicaRadius << "\nsurface_potential = -0.020\n"
    << "[particles]\nsource = \"random\"\ncount = 1\n"  // replaced by table4_particles
    << "[[pair]]\ntypes = [\"alumina\", \"alumina\"]\nkind = \"dlvo\"\nhamaker = 11.77\npermittivity = 175.0\n"
    << "kappa = 0.1\ncutoff = 500.0\n"
    << "[[pair]]\ntypes = [\"silica\", \"silica\"]\nkind = \"wca\"\n"
    << "[[pair]]\ntypes = [\"alumina\", \"silica\"]\nkind = \"lj36_18\"\nepsilon = 14.0\nsigma = 204.4\n"
    << "[integrator]\ndt = 2.0226\nsteps = 1\nseed = 7\nscheme = \"" << scheme << "\"\n"
    << "[mobility]\nmethod = \"none\"\n";
  return parse_config(t.str(), "bench");
}

// Random sequential addition in the periodic cube [0, L)^3: alumina (type 0) first, then silica
// (type 1), each at least 1.02 x the contact distance from every placed particle (minimum image).
// Silica-silica checks go through a cell grid (cells >= 2.04 a_S wide), silica-alumina checks
// over all alumina (at most 300).
InitialState table4_particles(const Table4System& sys, double L, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, L);
  auto d2 = [L](const double* a, const double* b) {
    double s = 0;
    for (int q = 0; q < 3; ++q) {
      double d = a[q] - b[q];
      d -= L * std::round(d / L);
      s += d * d;
    }
    return s;
  };
  InitialState s;
  auto place = [&](auto&& fits, std::uint32_t type) {
    for (int tries = 0; tries < 1000000; ++tries) {
      const double p[3] = {u(rng), u(rng), u(rng)};
      if (!fits(p)) continue;
      s.positions.insert(s.positions.end(), p, p + 3);
      s.types.push_back(type);
      return;
    }
    throw std::runtime_error("sac-table4: random placement failed");
  };
  const double aa = std::pow(1.02 * 2 * kAluminaRadius, 2);
  const double as = std::pow(1.02 * (kAluminaRadius + kSilicaRadius), 2);
  const double ss = std::pow(1.02 * 2 * kSilicaRadius, 2);
  for (std::size_t i = 0; i < sys.alumina; ++i)
    place(
        [&](const double* p) {
          for (std::size_t j = 0; j < s.types.size(); ++j)
            if (d2(p, &s.positions[3 * j]) < aa) return false;
          return true;
        },
        0);
  const int m = std::max(3, std::min(64, static_cast<int>(L / (1.02 * 2 * kSilicaRadius))));
  std::vector<std::vector<std::size_t>> cells(static_cast<std::size_t>(m) * m * m);
  auto cell_of = [&](double x) { return std::min(m - 1, static_cast<int>(x / L * m)); };
  auto flat = [&](int x, int y, int z) {
    return static_cast<std::size_t>(((x + m) % m) * m * m + ((y + m) % m) * m + (z + m) % m);
  };
  for (std::size_t i = 0; i < sys.silica; ++i) {
    place(
        [&](const double* p) {
          for (std::size_t j = 0; j < sys.alumina; ++j)
            if (d2(p, &s.positions[3 * j]) < as) return false;
          const int cx = cell_of(p[0]), cy = cell_of(p[1]), cz = cell_of(p[2]);
          for (int dx = -1; dx <= 1; ++dx)
            for (int dy = -1; dy <= 1; ++dy)
              for (int dz = -1; dz <= 1; ++dz)
                for (std::size_t j : cells[flat(cx + dx, cy + dy, cz + dz)])
                  if (d2(p, &s.positions[3 * j]) < ss) return false;
          return true;
        },
        1);
    const double* p = &s.positions[s.positions.size() - 3];
    cells[flat(cell_of(p[0]), cell_of(p[1]), cell_of(p[2]))].push_back(s.types.size() - 1);
  }
  return s;
}

int bench_sac_table4(int argc, char** argv) {
  const int steps = std::stoi(arg(argc, argv, "--steps", "20"));
  const int warmup = std::stoi(arg(argc, argv, "--warmup", "3"));
  const std::string scheme = arg(argc, argv, "--scheme", "sac");
  std::printf(
      "system,alumina,silica,scheme,threads,box_nm,steps,ms_per_iteration,k20m_ms,neighbours_ms,forces_ms,"
      "other_ms,list_radius_nm,list_entries_per_particle,rebuilds,complexes,adsorbed\n");
  for (std::size_t k : sizes(arg(argc, argv, "--systems", "0,1,2"))) {
    const Table4System& sys = kTable4.at(k);
    const double L =
        std::cbrt(static_cast<double>(sys.alumina) * 4.0 / 3.0 * M_PI * std::pow(kAluminaRadius, 3) / kAluminaPhi);
    const RunConfig c = table4_config(L, scheme);
    const ForceField ff = make_force_field(c);
    InitialState s = table4_particles(sys, L, 11 + k);
    const std::size_t n = s.types.size();
    Integrator bd(make_mobility(c.mobility, n), ff, c.integrator, std::move(s.positions), std::move(s.types),
                  c.neighbours);
    for (int i = 0; i < warmup; ++i) bd.step();  // first neighbour builds, allocations
    const std::size_t rebuilds = bd.neighbour_rebuilds();
    const IntegratorTotals before = bd.totals();
    rpyfmm::StopWatch w;
    bd.run(static_cast<std::uint64_t>(steps));
    const double ms = 1e3 * w.seconds() / steps;
    // Stages per iteration: the neighbour list (with the SAC membership update), the pair forces
    // (with the SAC complex sums), and the rest (displacements, update).
    auto part_ms = [&](const char* p) { return 1e3 * (bd.totals().seconds.at(p) - before.seconds.at(p)) / steps; };
    const double neighbours_ms = part_ms("neighbours"), forces_ms = part_ms("forces");
    // Complexes at the final positions (the SAC scheme's membership; empty with naive).
    std::size_t complexes = 0, adsorbed = 0;
    if (!bd.complexes().empty()) {
      const auto owner = bd.complexes().owner();
      for (std::size_t i = 0; i < n; ++i) {
        if (owner[i] == Complexes::kFree) continue;
        if (owner[i] == i)
          ++complexes;
        else
          ++adsorbed;
      }
    }
    std::printf("%zu,%zu,%zu,%s,%d,%.0f,%d,%.4g,%.2f,%.3g,%.3g,%.3g,%.0f,%.1f,%zu,%zu,%zu\n", k + 1, sys.alumina,
                sys.silica, scheme.c_str(), omp_get_max_threads(), L, steps, ms, sys.k20m_ms, neighbours_ms, forces_ms,
                ms - neighbours_ms - forces_ms, bd.neighbour_list().list_radius(),
                static_cast<double>(bd.neighbour_list().pair_entries()) / static_cast<double>(n),
                bd.neighbour_rebuilds() - rebuilds, complexes, adsorbed);
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
    if (mode == "engine") return bench_engine(argc, argv);
    if (mode == "sac-table4") return bench_sac_table4(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_bd: %s\n", e.what());
    return 2;
  }
  std::fprintf(stderr,
               "usage: bench_bd steps|neighbours|engine|sac-table4 [--method M] [--n N1,N2] [--steps S] [--tol T]\n");
  return 2;
}
