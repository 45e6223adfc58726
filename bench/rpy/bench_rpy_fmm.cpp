// Benchmark of the free-space RPY operator (docs/theory/rpy.md), in the layout of Tables 3.1-3.6
// of W. Guan, "Fast Algorithms for Brownian Dynamics with Hydrodynamic Interactions", PhD
// dissertation, UNC Chapel Hill: for each N and tolerance, one RPY product with FmmRpy, its
// measured error against an exact RPY sum at sampled targets, the time of one Laplace FMM
// evaluation (pot + grad + Hessian, one charge vector)
// on the same points, and the direct O(N^2) time (measured for N <= 20000,
// extrapolated as N^2 above, marked so), and the product with torques [U; W] = M [F; T] (rot_s,
// its ratio to the force-only product, and its error: the larger of U's and W's relative l2
// errors against exact sums at the sampled targets, then each; it runs on the force-only plan).
// Prints one CSV row per case; leaf_capacity is the tree's, leaf_option the capacity asked for
// (0: automatic); l2p_s is the Laplace FMM's L2P stage (with the fold of its combined outputs) in
// the force-only product; setup_s is set_positions (the tree and the Laplace plan), the part of a
// product's cost that a peer code timed with its setup (bench/run.py's fmm3dpy column) also pays.
//
// usage: bench_rpy_fmm [dist=cylinder|eight|suspension|bimodal] [N list] [eps list] [threads list] [repeats]
//                      [points.bin or -] [leaf capacity list, 0 = the operator's default]
//        bench_rpy_fmm cylinder 10000,100000 1e-3,1e-6,1e-9 1,2 3 [points.bin] [0,100,200]
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "configurations.hpp"
#include "fmm_rotation_test_util.hpp"
#include "fmm_rpy_test_util.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace t = rpyfmm::testing;
using rpyfmm::StopWatch;

namespace {

template <class T>
std::vector<T> parse_list(const std::string& s) {
  std::vector<T> v;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) v.push_back(static_cast<T>(std::stod(item)));
  return v;
}

// Every (tolerance, leaf capacity) pair, tolerance-major.
std::vector<std::pair<double, int>> cases(const std::vector<double>& epss, const std::vector<int>& leaves) {
  std::vector<std::pair<double, int>> out;
  for (double eps : epss)
    for (int leaf : leaves) out.emplace_back(eps, leaf);
  return out;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

t::Configuration make(const std::string& dist, std::size_t n) {
  // Radii small against the spacing, as in the dissertation's surface tests.
  if (dist == "cylinder") return t::cylinder_surface(n, 1e-4, 42);
  if (dist == "eight") return t::eight_surface(n, 1e-4, 42);
  // Different radii (the 7-density far field): 2% of the spheres four times larger.
  if (dist == "bimodal") return t::bimodal_suspension(n, 1.0, 4.0, 0.1, 42);
  return t::random_suspension(n, 1.0, 0.1, 42);
}

// Median time of set_positions (the tree and the Laplace plan, rebuilt on every call); op keeps the last.
double median_setup_time(rpyfmm::rpy::FmmRpy& op, const t::Configuration& c, int repeats) {
  std::vector<double> times;
  for (int r = 0; r < repeats; ++r) {
    StopWatch watch;
    op.set_positions(c.x, c.a);
    times.push_back(watch.seconds());
  }
  return median(times);
}

// Median time of the product with torques; u, w hold the last result.
double median_rotation_time(const rpyfmm::rpy::FmmRpy& op, const std::vector<double>& f, const std::vector<double>& tq,
                            std::vector<double>& u, std::vector<double>& w, int repeats) {
  std::vector<double> times;
  for (int r = 0; r < repeats; ++r) {
    StopWatch watch;
    op.apply(f, tq, u, w);
    times.push_back(watch.seconds());
  }
  return median(times);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string dist = argc > 1 ? argv[1] : "cylinder";
  const auto ns = parse_list<std::size_t>(argc > 2 ? argv[2] : "10000,100000");
  const auto epss = parse_list<double>(argc > 3 ? argv[3] : "1e-3,1e-6,1e-9");
  const auto threads = parse_list<int>(argc > 4 ? argv[4] : "1,2");
  const int repeats = argc > 5 ? std::stoi(argv[5]) : 3;
  const std::string dump = argc > 6 && std::string(argv[6]) != "-" ? argv[6] : "";
  const auto leaves = parse_list<int>(argc > 7 ? argv[7] : "0");

  std::printf(
      "dist,N,eps,threads,rpy_s,laplace1_s,ratio_rpy_laplace,direct_s,direct_kind,speedup_vs_direct,"
      "rel_l2_err,levels,leaves,near_s,far_fmm_s,leaf_capacity,rot_s,ratio_rot_forces,rot_rel_l2_err,rot_u_err,"
      "rot_w_err,leaf_option,l2p_s,setup_s\n");
  for (std::size_t n : ns) {
    const auto c = make(dist, n);
    const auto f = t::random_vector(3 * n, 1);
    auto tq = t::random_vector(3 * n, 2);
    for (std::size_t j = 0; j < n; ++j)
      for (int k = 0; k < 3; ++k) tq[3 * j + k] *= c.a[j];  // torques ~ force x radius
    // Positions then forces, float64, (x, y, z) of each particle in turn, for a peer code.
    if (!dump.empty()) {
      std::ofstream out(dump + "." + std::to_string(n), std::ios::binary);
      out.write(reinterpret_cast<const char*>(c.x.data()), static_cast<std::streamsize>(c.x.size() * 8));
      out.write(reinterpret_cast<const char*>(f.data()), static_cast<std::streamsize>(f.size() * 8));
    }
    for (int nt : threads) {
      omp_set_num_threads(nt);
      // Direct time: measured up to 20000 particles, extrapolated from 20000 as N^2 beyond.
      double direct_s = 0;
      std::string direct_kind = "measured";
      {
        const std::size_t nd = std::min<std::size_t>(n, 20000);
        const auto cd = nd == n ? c : make(dist, nd);
        rpyfmm::rpy::DirectRpy direct;
        direct.set_positions(cd.x, cd.a);
        std::vector<double> fd(3 * nd, 1.0), ud(3 * nd);
        StopWatch w;
        direct.apply(fd, ud);
        direct_s = w.seconds() * (static_cast<double>(n) / nd) * (static_cast<double>(n) / nd);
        if (nd != n) direct_kind = "extrapolated";
      }
      for (const auto& [eps, leaf] : cases(epss, leaves)) {
        rpyfmm::rpy::FmmRpy op(rpyfmm::rpy::Geometry::open(), 1.0, {.tolerance = eps, .leaf_capacity = leaf});
        const double setup_s = median_setup_time(op, c, repeats);
        std::vector<double> u(3 * n);
        std::vector<double> times, near_t, far_t, l2p_t;
        for (int r = 0; r < repeats; ++r) {
          StopWatch w;
          op.apply(f, u);
          times.push_back(w.seconds());
          auto tm = op.last_timings();
          near_t.push_back(tm["rpy_near"]);
          far_t.push_back(tm.count("total") ? tm["total"] : 0.0);
          l2p_t.push_back(tm.count("l2p") ? tm["l2p"] : 0.0);
        }
        const double err = t::sampled_error(c, f, u, 200);
        std::vector<double> ur(3 * n), wr(3 * n);
        const double rot_s = median_rotation_time(op, f, tq, ur, wr, repeats);
        const auto [rot_u_err, rot_w_err] = t::sampled_rotation_errors(c, f, tq, ur, wr, 200);

        // One Laplace FMM evaluation, pot + grad + Hessian, one charge vector, same points and eps.
        rpyfmm::fmm::LaplaceFmm lap({.tolerance = eps});
        lap.set_points(c.x);
        std::vector<double> q(n), res(10 * n);
        for (std::size_t j = 0; j < n; ++j) q[j] = f[3 * j];
        std::vector<double> lt;
        for (int r = 0; r < repeats; ++r) {
          StopWatch w;
          lap.evaluate(q, 1, rpyfmm::fmm::all_outputs, res);
          lt.push_back(w.seconds());
        }
        const auto stats = op.laplace_plan()->stats();
        const double rpy_s = median(times), lap_s = median(lt);
        std::printf(
            "%s,%zu,%.0e,%d,%.4f,%.4f,%.2f,%.3f,%s,%.1f,%.2e,%d,%zu,%.4f,%.4f,%d,"
            "%.4f,%.2f,%.2e,%.2e,%.2e,%d,%.4f,%.4f\n",
            dist.c_str(), n, eps, nt, rpy_s, lap_s, rpy_s / lap_s, direct_s, direct_kind.c_str(), direct_s / rpy_s, err,
            stats.levels, stats.leaves, median(near_t), median(far_t), stats.leaf_capacity, rot_s, rot_s / rpy_s,
            std::max(rot_u_err, rot_w_err), rot_u_err, rot_w_err, leaf, median(l2p_t), setup_s);
        std::fflush(stdout);
      }
    }
  }
  return 0;
}
