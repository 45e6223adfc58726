// bench_direct — throughput of the direct O(N^2) kernels.
//
//   bench_direct [--n N] [--threads T] [--reps R] [--kernel laplace|rpy|all] [--nd D]
//                [--dump FILE] [--results FILE] [--portable]
//
// Laplace: N uniform points in the unit cube (mt19937_64, seed 1), charges in
// [-1, 1], evaluated at the sources; prints the median of R runs for potential
// only and for potential+gradient+Hessian. RPY: DirectRpy::apply on the same
// points, equal radii (a = 0.001) and polydisperse radii, and rpy-rotation: DirectRpy's grand
// mobility with torques, apply(F, T, U, W), on the same inputs. One CSV row per case:
//   kernel,outputs,n,nd,threads,median_s,min_s,cpu_median_s,pairs_per_s,pairs_per_cpu_s
// (CPU time = process CPU time over all threads: on a shared, loaded machine the
// per-CPU-second rate is the steadier figure; wall time shows the parallel speed-up).
// pairs = N * (N - 1) * nd (Laplace; self pair skipped) and N^2 (RPY, self included).
// --dump writes the points (3N doubles, particle-major) then the charges (nd*N) as raw
// float64 so that a peer code (e.g. fmm3dpy's l3ddir) can be timed on exactly the same input;
// --portable disables the hand-written AVX-512 kernels (compiler-vectorized loops only);
// --results writes the pot+grad+Hessian results (nd x N x 10 float64) for its accuracy check.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"

namespace {

struct Timing {
  double median, min, cpu_median;  // wall-clock median and minimum, process CPU-time median
};

double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

Timing time_it(int reps, const std::function<void()>& f) {
  f();  // warm-up
  std::vector<double> t, c;
  for (int r = 0; r < reps; ++r) {
    const double c0 = cpu_seconds();
    const auto t0 = std::chrono::steady_clock::now();
    f();
    t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    c.push_back(cpu_seconds() - c0);
  }
  std::sort(t.begin(), t.end());
  std::sort(c.begin(), c.end());
  return {t[t.size() / 2], t.front(), c[c.size() / 2]};
}

void row(const char* kernel, const char* outputs, std::size_t n, std::size_t nd, int threads, Timing t, double pairs) {
  std::printf("%s,%s,%zu,%zu,%d,%.6g,%.6g,%.6g,%.4g,%.4g\n", kernel, outputs, n, nd, threads, t.median, t.min,
              t.cpu_median, pairs / t.median, pairs / t.cpu_median);
  std::fflush(stdout);
}

// DirectRpy on the points x: U = M F with equal and polydisperse radii, then the grand mobility
// with torques, [U; W] = M [F; T], on the same inputs.
void rpy_rows(const std::vector<double>& x, std::size_t n, int threads, int reps, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0), um(-1.0, 1.0);
  std::vector<double> f(3 * n), uvel(3 * n), a(n);
  for (auto& v : f) v = um(rng);
  for (auto& v : a) v = 0.0005 + 0.001 * u01(rng);
  const double pairs = static_cast<double>(n) * static_cast<double>(n);
  rpyfmm::rpy::DirectRpy op;
  op.set_positions(x, 0.001);
  row("rpy", "equal-radii", n, 1, threads, time_it(reps, [&] { op.apply(f, uvel); }), pairs);
  op.set_positions(x, a);
  row("rpy", "polydisperse", n, 1, threads, time_it(reps, [&] { op.apply(f, uvel); }), pairs);
  // The grand mobility with rotation, [U; W] = M [F; T]: the translational product plus the
  // rotational pair sums (UT, WF, WT blocks).
  std::vector<double> torque(3 * n), wvel(3 * n);
  for (auto& v : torque) v = 0.001 * um(rng);
  op.set_positions(x, 0.001);
  row("rpy-rotation", "equal-radii", n, 1, threads, time_it(reps, [&] { op.apply(f, torque, uvel, wvel); }), pairs);
  op.set_positions(x, a);
  row("rpy-rotation", "polydisperse", n, 1, threads, time_it(reps, [&] { op.apply(f, torque, uvel, wvel); }), pairs);
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t n = 10000, nd = 1;
  int threads = 1, reps = 5;
  std::string kernel = "all", dump, results;
  for (int i = 1; i < argc; i += 2) {
    const std::string k = argv[i];
    if (k == "--portable") {  // flag: compiler-vectorized AVX2 kernels (no hand-written AVX-512)
      rpyfmm::set_simd_level(rpyfmm::SimdLevel::avx2);
      --i;
      continue;
    }
    if (i + 1 >= argc) {
      std::fprintf(stderr, "bench_direct: %s needs a value\n", argv[i]);
      return 2;
    }
    const char* v = argv[i + 1];
    if (k == "--n")
      n = std::strtoul(v, nullptr, 10);
    else if (k == "--threads")
      threads = std::atoi(v);
    else if (k == "--reps")
      reps = std::atoi(v);
    else if (k == "--kernel")
      kernel = v;
    else if (k == "--nd")
      nd = std::strtoul(v, nullptr, 10);
    else if (k == "--dump")
      dump = v;
    else if (k == "--results")
      results = v;
    else {
      std::fprintf(stderr, "bench_direct: unknown option %s\n", argv[i]);
      return 2;
    }
  }
  if (n < 2 || threads < 1 || reps < 1 || nd < 1) {
    std::fprintf(stderr, "bench_direct: need n >= 2, threads >= 1, reps >= 1, nd >= 1\n");
    return 2;
  }
  omp_set_num_threads(threads);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u01(0.0, 1.0), um(-1.0, 1.0);
  std::vector<double> x(3 * n), q(nd * n);
  for (auto& v : x) v = u01(rng);
  for (auto& v : q) v = um(rng);
  if (!dump.empty()) {
    std::ofstream out(dump, std::ios::binary);
    out.write(reinterpret_cast<const char*>(x.data()), static_cast<std::streamsize>(x.size() * 8));
    out.write(reinterpret_cast<const char*>(q.data()), static_cast<std::streamsize>(q.size() * 8));
  }
  std::printf("kernel,outputs,n,nd,threads,median_s,min_s,cpu_median_s,pairs_per_s,pairs_per_cpu_s\n");
  if (kernel == "laplace" || kernel == "all") {
    std::vector<double> res(nd * n * rpyfmm::fmm::result_width);
    const double pairs = static_cast<double>(n) * static_cast<double>(n - 1) * static_cast<double>(nd);
    using rpyfmm::fmm::laplace_direct;
    row("laplace", "pot", n, nd, threads,
        time_it(reps, [&] { laplace_direct(x, q, nd, {}, rpyfmm::fmm::potential, res); }), pairs);
    row("laplace", "pot+grad", n, nd, threads,
        time_it(reps, [&] { laplace_direct(x, q, nd, {}, rpyfmm::fmm::potential | rpyfmm::fmm::gradient, res); }),
        pairs);
    row("laplace", "pot+grad+hess", n, nd, threads,
        time_it(reps, [&] { laplace_direct(x, q, nd, {}, rpyfmm::fmm::all_outputs, res); }), pairs);
    if (!results.empty()) {
      std::ofstream out(results, std::ios::binary);
      out.write(reinterpret_cast<const char*>(res.data()), static_cast<std::streamsize>(res.size() * 8));
    }
  }
  if (kernel == "rpy" || kernel == "all") rpy_rows(x, n, threads, reps, rng);
  return 0;
}
