// Benchmark of the adaptive plane-wave Laplace FMM (docs/theory/fmm.md), in the layout of
// Tables 2.1-2.12 of W. Guan, "Fast Algorithms for Brownian Dynamics with Hydrodynamic
// Interactions", PhD dissertation, UNC Chapel Hill.
//
// usage: bench_fmm --n N --dist cube|sphere|octant --eps E [--nd 1] [--leaf 0] [--reps 3]
//                  [--outputs 7] [--sample 1000] [--npy points.npy] [--direct] [--root-scale 1] [--occupancy T]
// Points come from a fixed seed (or are written to --npy for the fmm3dpy peer of bench/run.py).
// Prints one JSON row: time (median of reps), per-stage breakdown, sampled relative l2 errors of each
// output against a direct sum, levels, boxes, peak RSS, and (with --direct) the direct-sum time.
#include <omp.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/fmm/leaf_grid.hpp"

namespace {
std::vector<double> make_points(std::size_t n, const std::string& dist, unsigned seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> nd(0.0, 1.0);
  std::vector<double> x(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    if (dist == "cube") {
      for (int k = 0; k < 3; ++k) x[3 * i + k] = u(g);
    } else {
      double v[3] = {nd(g), nd(g), nd(g)};
      const double r = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
      for (int k = 0; k < 3; ++k) x[3 * i + k] = (dist == "octant" ? std::abs(v[k]) : v[k]) / r;
    }
  }
  return x;
}

void write_npy(const std::string& path, const std::vector<double>& a, std::size_t rows, std::size_t cols) {
  std::ofstream f(path, std::ios::binary);
  std::string header = "{'descr': '<f8', 'fortran_order': False, 'shape': (" + std::to_string(rows) + ", " +
                       std::to_string(cols) + "), }";
  while ((10 + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  const unsigned short len = static_cast<unsigned short>(header.size());
  f.write("\x93NUMPY\x01\x00", 8);
  f.write(reinterpret_cast<const char*>(&len), 2);
  f.write(header.data(), std::streamsize(header.size()));
  f.write(reinterpret_cast<const char*>(a.data()), std::streamsize(a.size() * sizeof(double)));
}

double peak_rss_mb() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss / 1024.0;
}
}  // namespace

int main(int argc, char** argv) {
  std::size_t n = 100000, nd = 1, sample = 1000;
  std::string dist = "cube", npy;
  double eps = 1e-6;
  int leaf = 0, reps = 3;
  double root_scale = 1.0;
  int occupancy = 0;  // > 0: leaves fitted to ~T points (fit_leaf_grid), overrides --leaf/--root-scale
  unsigned outputs = rpyfmm::fmm::all_outputs;
  bool do_direct = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&] { return std::string(argv[++i]); };
    if (a == "--n")
      n = std::size_t(std::stod(next()));
    else if (a == "--dist")
      dist = next();
    else if (a == "--eps")
      eps = std::stod(next());
    else if (a == "--nd")
      nd = std::stoul(next());
    else if (a == "--leaf")
      leaf = std::stoi(next());
    else if (a == "--occupancy")
      occupancy = std::stoi(next());
    else if (a == "--root-scale")
      root_scale = std::stod(next());
    else if (a == "--reps")
      reps = std::stoi(next());
    else if (a == "--outputs")
      outputs = unsigned(std::stoul(next()));
    else if (a == "--sample")
      sample = std::stoul(next());
    else if (a == "--npy")
      npy = next();
    else if (a == "--direct")
      do_direct = true;
    else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  const auto x = make_points(n, dist, 12345);
  std::vector<double> q(n * nd);
  std::mt19937_64 g(777);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (auto& v : q) v = u(g);
  if (!npy.empty()) {
    write_npy(npy, x, n, 3);
    write_npy(npy + ".charges.npy", q, nd, n);
  }
  rpyfmm::fmm::FmmOptions opt;
  opt.tolerance = eps;
  opt.leaf_capacity = leaf;
  opt.root_scale = root_scale;
  if (occupancy > 0) {
    const auto grid = rpyfmm::fmm::fit_leaf_grid(x, {}, occupancy);
    if (grid.fitted()) {
      opt.leaf_capacity = grid.leaf_capacity;
      opt.root_scale = grid.root_scale;
    }
  }
  rpyfmm::fmm::LaplaceFmm fmm(opt);
  rpyfmm::StopWatch sw;
  fmm.set_points(x);
  const double t_setup = sw.seconds();
  std::vector<double> res(nd * n * 10);
  std::vector<double> times;
  rpyfmm::StageTimes stages;
  for (int r = 0; r < reps; ++r) {
    sw.restart();
    fmm.evaluate(q, nd, outputs, res);
    times.push_back(sw.seconds());
    if (r == 0 || times.back() <= *std::min_element(times.begin(), times.end())) stages = fmm.last_timings();
  }
  std::sort(times.begin(), times.end());
  const double t_eval = times[times.size() / 2];
  // Sampled errors against the direct sum.
  std::vector<std::size_t> idx;
  std::mt19937_64 gs(99);
  std::uniform_int_distribution<std::size_t> ui(0, n - 1);
  for (std::size_t i = 0; i < std::min(sample, n); ++i) idx.push_back(n <= sample ? i : ui(gs));
  std::vector<double> tg(3 * idx.size());
  for (std::size_t i = 0; i < idx.size(); ++i)
    for (int k = 0; k < 3; ++k) tg[3 * i + k] = x[3 * idx[i] + k];
  std::vector<double> ref(nd * idx.size() * 10);
  rpyfmm::fmm::laplace_direct(x, q, nd, tg, outputs, ref);
  double err[3] = {0, 0, 0};
  const int c0[3] = {0, 1, 4}, c1[3] = {1, 4, 10};
  for (int o = 0; o < 3; ++o)
    for (std::size_t d = 0; d < nd; ++d) {
      double num = 0, den = 0;
      for (std::size_t i = 0; i < idx.size(); ++i)
        for (int c = c0[o]; c < c1[o]; ++c) {
          const double a = res[(d * n + idx[i]) * 10 + c], b = ref[(d * idx.size() + i) * 10 + c];
          num += (a - b) * (a - b);
          den += b * b;
        }
      err[o] = std::max(err[o], den > 0 ? std::sqrt(num / den) : 0.0);
    }
  double t_direct = -1;
  if (do_direct) {
    std::vector<double> full(nd * n * 10);
    sw.restart();
    rpyfmm::fmm::laplace_direct(x, q, nd, {}, outputs, full);
    t_direct = sw.seconds();
  }
  const auto st = fmm.stats();
  std::printf(
      "{\"n\": %zu, \"dist\": \"%s\", \"eps\": %.0e, \"nd\": %zu, \"outputs\": %u, \"threads\": %d, "
      "\"p\": %d, \"nlams\": %d, \"leaf\": %d, \"root_scale\": %.4f, \"levels\": %d, \"boxes\": %zu, \"leaves\": %zu, "
      "\"setup_s\": %.4f, \"eval_s\": %.4f, \"err_pot\": %.2e, \"err_grad\": %.2e, \"err_hess\": %.2e, "
      "\"peak_rss_mb\": %.1f, \"bytes_per_particle\": %.0f, \"direct_s\": %.4f, \"stages\": {",
      n, dist.c_str(), eps, nd, outputs, omp_get_max_threads(), st.order, st.nlams, st.leaf_capacity, st.root_scale,
      st.levels, st.boxes, st.leaves, t_setup, t_eval, err[0], err[1], err[2], peak_rss_mb(),
      peak_rss_mb() * 1048576.0 / double(n), t_direct);
  bool first = true;
  for (const auto& [k, v] : stages) {
    std::printf("%s\"%s\": %.4f", first ? "" : ", ", k.c_str(), v);
    first = false;
  }
  std::printf("}}\n");
  return 0;
}
