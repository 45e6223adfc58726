// Benchmark of the Brownian square roots (docs/theory/samplers.md): iterations and time per
// sample of M^{1/2} z versus N, Lanczos versus Chebyshev, tolerances, the
// ratio (time per sample) / (time per product M F), and the block variant
// (4 noise vectors per operator pass). Each sample is timed right after one
// product M F on the same thread count; ratio = median of sample / product
// over the repeats (side by side, so machine noise largely cancels). Random suspension, volume fraction
// 0.1, radius 1 (overlaps allowed), fixed seed. Prints one CSV row per case.
//
// usage: bench_sqrt [operator=direct|fmm] [N list] [tol list] [threads list] [repeats] [fmm eps]
//                   [all|lanczos|chebyshev|preconditioned|preconditioned-chebyshev] [block|noblock]
//                   [preconditioner blocks]
//        bench_sqrt direct 1000,2000,5000 1e-3,1e-5 1,2 3
//        bench_sqrt fmm 1000,10000,100000 1e-3,1e-5 1,2 3 1e-6
//
// Chebyshev: the eigenvalue bounds are estimated once per configuration
// (estimate_spectrum_bounds, 30 Lanczos steps; column bounds_s) and reused for
// every sample, as a BD code would; its per-sample time excludes them.
// "preconditioned" (also in "all") is Lanczos with the block preconditioner
// (SqrtPreconditioner::block), once per block size of the last argument (default 48; method

// column lanczos+block<size>); its sample time includes building the blocks' factors.
// "preconditioned-chebyshev" (also in "all") is Chebyshev with the block preconditioner (column
// chebyshev+block<size>): bounds of G M G^T estimated once per configuration like Chebyshev's
// (bounds_s includes building the preconditioner for them), the sample time includes the factors.
// To benchmark another operator, add a branch to make_operator().
#include <omp.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

using namespace rpyfmm::rpy;
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

/// CPU time of the whole process (all threads): robust against the machine
/// being shared, where wall-clock time of one product varies several-fold.
double cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

std::unique_ptr<MobilityOperator> make_operator(const std::string& name, double eps) {
  if (name == "direct") return std::make_unique<DirectRpy>(Geometry::open(), 1.0);
  if (name == "fmm") {
    FmmRpyOptions o;
    o.tolerance = eps;
    return std::make_unique<FmmRpy>(Geometry::open(), 1.0, o);
  }
  std::fprintf(stderr, "unknown operator %s\n", name.c_str());
  std::exit(2);
}

// Uniform random centres in a cube of volume N (4/3 pi) / phi (radius 1).
std::vector<double> suspension(std::size_t n, double phi, unsigned seed) {
  const double L = std::cbrt(static_cast<double>(n) * 4.0 / 3.0 * std::numbers::pi / phi);
  std::mt19937_64 gen(seed);
  std::uniform_real_distribution<double> u(0.0, L);
  std::vector<double> x(3 * n);
  for (auto& v : x) v = u(gen);
  return x;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string opname = argc > 1 ? argv[1] : "direct";
  const auto Ns = parse_list<std::size_t>(argc > 2 ? argv[2] : "1000,2000");
  const auto tols = parse_list<double>(argc > 3 ? argv[3] : "1e-3,1e-5");
  const auto threads = parse_list<int>(argc > 4 ? argv[4] : "1,2");
  const int repeats = argc > 5 ? std::stoi(argv[5]) : 3;
  const double eps = argc > 6 ? std::stod(argv[6]) : 1e-6;
  // "all" (default) or one method; "noblock" skips the block-of-4 timing (large N).
  const std::string methods = argc > 7 ? argv[7] : "all";
  const bool block = !(argc > 8 && std::string(argv[8]) == "noblock");
  const auto block_sizes = parse_list<int>(argc > 9 ? argv[9] : "48");

  std::printf(
      "operator,N,threads,tol,method,iterations,products,error_estimate,sample_wall_s,sample_cpu_s,"
      "product_cpu_s,ratio_cpu,bounds_wall_s,block4_cpu_per_sample_s\n");
  for (int t : threads) {
    omp_set_num_threads(t);
    for (std::size_t n : Ns) {
      auto op = make_operator(opname, eps);
      op->set_positions(suspension(n, 0.1, 42u), 1.0);
      const std::size_t len = 3 * n;
      std::vector<double> f(len), u(len), z(len), w(len), z4(4 * len), w4(4 * len);
      fill_normal(f, 1u, 0u);
      // One product M F, timed next to every sample (same conditions) for the ratio.
      auto time_product = [&] {
        const double c0 = cpu_seconds();
        op->apply(f, u);
        return cpu_seconds() - c0;
      };
      StopWatch swb;
      SpectrumBounds bounds;
      if (methods == "all" || methods == "chebyshev") bounds = estimate_spectrum_bounds(op->as_linear_operator(), 30);
      const double bounds_s = swb.seconds();

      // Bounds of the preconditioned operators G M G^T, per block size (preconditioned Chebyshev).
      std::vector<SpectrumBounds> preconditioned_bounds(block_sizes.size());
      std::vector<double> preconditioned_bounds_s(block_sizes.size(), 0.0);
      if (methods == "all" || methods == "preconditioned-chebyshev") {
        for (std::size_t k = 0; k < block_sizes.size(); ++k) {
          StopWatch swp;
          const BlockPreconditioner pc(*op, static_cast<std::size_t>(block_sizes[k]));
          preconditioned_bounds[k] = estimate_spectrum_bounds(pc.precondition(op->as_linear_operator()), 30);
          preconditioned_bounds_s[k] = swp.seconds();
        }
      }

      for (double tol : tols) {
        std::vector<std::pair<SqrtMethod, int>> variants{{SqrtMethod::lanczos, 0}, {SqrtMethod::chebyshev, 0}};
        for (int b : block_sizes) variants.emplace_back(SqrtMethod::lanczos, b);
        for (int b : block_sizes) variants.emplace_back(SqrtMethod::chebyshev, b);
        for (std::size_t v = 0; v < variants.size(); ++v) {
          const auto [m, preconditioner_block] = variants[v];
          const std::string variant = preconditioner_block == 0  ? std::string(to_string(m))
                                      : m == SqrtMethod::lanczos ? std::string("preconditioned")
                                                                 : std::string("preconditioned-chebyshev");
          if (methods != "all" && methods != variant) continue;
          SqrtOptions opt;
          opt.method = m;
          opt.tolerance = tol;
          if (preconditioner_block > 0) {
            opt.preconditioner = SqrtPreconditioner::block;
            opt.preconditioner_block = preconditioner_block;
          }
          const std::string label = preconditioner_block > 0
                                        ? std::string(to_string(m)) + "+block" + std::to_string(preconditioner_block)
                                        : std::string(to_string(m));
          double variant_bounds_s = 0.0;
          if (m == SqrtMethod::chebyshev) {
            const std::size_t k = preconditioner_block > 0 ? v - 2 - block_sizes.size() : 0;
            const SpectrumBounds& b = preconditioner_block > 0 ? preconditioned_bounds[k] : bounds;
            opt.lambda_min = b.lambda_min;
            opt.lambda_max = b.lambda_max;
            variant_bounds_s = preconditioner_block > 0 ? preconditioned_bounds_s[k] : bounds_s;
          }
          std::vector<double> ts, tc, tb, its, ratio, tp;
          SqrtReport rep;
          for (int r = 0; r < repeats; ++r) {
            fill_normal(z, 7u, static_cast<std::uint64_t>(r));
            const double tprod = time_product();
            tp.push_back(tprod);
            StopWatch sw;
            const double c0 = cpu_seconds();
            rep = op->apply_sqrt(z, w, opt);
            tc.push_back(cpu_seconds() - c0);
            ts.push_back(sw.seconds());
            its.push_back(rep.iterations);
            ratio.push_back(tc.back() / tprod);
          }
          for (int r = 0; block && r < std::max(1, repeats / 2); ++r) {
            for (int k = 0; k < 4; ++k)
              fill_normal(std::span<double>(&z4[k * len], len), 9u, static_cast<std::uint64_t>(4 * r + k));
            const double c0 = cpu_seconds();
            op->apply_sqrt_block(z4, w4, 4, opt);
            tb.push_back((cpu_seconds() - c0) / 4);
          }
          std::printf("%s,%zu,%d,%.0e,%s,%.0f,%d,%.3e,%.4e,%.4e,%.4e,%.2f,%.4e,%.4e\n", opname.c_str(), n, t, tol,
                      label.c_str(), median(its), rep.operator_applications, rep.error_estimate, median(ts), median(tc),
                      median(tp), median(ratio), variant_bounds_s, block ? median(tb) : 0.0);
          std::fflush(stdout);
        }
      }
    }
  }
  return 0;
}
