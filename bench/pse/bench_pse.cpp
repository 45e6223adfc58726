// PSE benchmark ([PSE] = Fiore, Balboa Usabiaga, Donev & Swan, "Rapid sampling of stochastic
// displacements in Brownian dynamics simulations", J. Chem. Phys. 146 (2017) 124116; docs/theory/pse.md):
// the setup of [PSE] Table I (random hard spheres, phi = 0.1, a = 1,
// xi a = 0.5, tolerance 1e-3): particle-timesteps per second (PTPS = N / seconds) for
// U = M F and for the split sampler M^{1/2} z, per-stage breakdown, the split sampler
// against generic Lanczos on the full PSE operator ([PSE] Fig. 6), and the real-space
// table against direct evaluation of F, G. CSV rows on stdout.
//
// usage: bench_pse [--quick] [--fft-measure] [--error] [--xi XA] [--eta E] [--support P] [--grid G]
//                  [--precision auto|single|double] [--kernels auto|avx2|portable] [--no-real-cache]
//                  [--cuda [--bin-sweep]] [N ...]
//   (default 8000 16000 32000); threads from 1 to OMP max.
// Also times the free-space FmmRpy (tolerance 1e-3) on the same particles, 1 thread.
// Comment lines (#) add block-preconditioned Lanczos (docs/theory/samplers.md) on the full PSE operator and
// on the free-space FMM operator.
// --quick: only M F and the split sampler with their stage times (no full-operator Lanczos,
// no table-vs-direct real space, no FMM comparison).
// --error: the relative l2 error of M F against the same operator at tolerance 1e-8 (N <= 64000;
// -1 above), column MF_rel_error. --xi: xi a of the M F / sampler rows (default 0.5, Table I;
// 0 = automatic, the cost model's choice). --grid: PseOptions::grid = {G, G, G} (timing of
// the transforms in place, see fft_sizes.cpp). --eta / --support: PseOptions::window_eta / support
// overrides (e.g. --eta 0.8 --support 6 is a wider window than the automatic one at 1e-3).
// --kernels: avx2 / portable turn the AVX-512 kernels off (as on a CPU without them), and for
// portable the AVX2 window kernels too (auto: the widest the CPU has).
// --precision: PseOptions::wave_precision (default auto: single-precision wave grids at the
// tolerance 1e-3 of Table I; column wave_single).
// --no-real-cache: PseOptions::real_space_cache = false (every product evaluates the real-space
// pairs). M F and the sampler are timed as the first after set_positions (as in a time step);
// MF_cached_s is a product repeated with the same positions (the pair cache filled).
// --fft-measure: PseOptions::fft_measure (FFTW_MEASURE plans; the plan column gives the planning
// time of set_positions, which includes the timing of the plans).
// --cuda: the CUDA operator PseRpyCuda instead: host arrays in and out (transfers count) and
// device arrays (apply_device / sample_device), the device's stage times, and its relative
// difference from the CPU operator's M F (double-precision wave grids, as on the GPU) for
// N <= 250000; skips with a message when no device is usable. Rows: the defaults, then each
// default changed alone (double grids, host lists, per-particle windows, pageable transfers);
// --bin-sweep: the defaults with the bin edges -1 (per particle), 6, 8, ..., 16 instead.
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"
#include "rpyfmm/rpy/random.hpp"

#ifdef RPYFMM_HAVE_CUDA_PSE
#include <cuda_runtime.h>  // device arrays for apply_device / sample_device (--cuda)
#endif

using namespace rpyfmm;
using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

namespace {

/// Random sequential addition of non-overlapping spheres (radius a) at volume fraction phi.
std::vector<double> hard_spheres(std::size_t n, double a, double L, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, L);
  const int nc = std::max(1, static_cast<int>(L / (2 * a)));
  const double cell = L / nc;
  std::vector<std::vector<std::size_t>> cells(static_cast<std::size_t>(nc) * nc * nc);
  std::vector<double> x;
  x.reserve(3 * n);
  auto cid = [&](int i, int j, int k) {
    return (static_cast<std::size_t>((i + nc) % nc) * nc + static_cast<std::size_t>((j + nc) % nc)) * nc +
           static_cast<std::size_t>((k + nc) % nc);
  };
  while (x.size() < 3 * n) {
    const double p[3] = {u(rng), u(rng), u(rng)};
    const int c[3] = {std::min(static_cast<int>(p[0] / cell), nc - 1), std::min(static_cast<int>(p[1] / cell), nc - 1),
                      std::min(static_cast<int>(p[2] / cell), nc - 1)};
    bool ok = true;
    for (int i = -1; i <= 1 && ok; ++i)
      for (int j = -1; j <= 1 && ok; ++j)
        for (int k = -1; k <= 1 && ok; ++k)
          for (std::size_t q : cells[cid(c[0] + i, c[1] + j, c[2] + k)]) {
            double r2 = 0.0;
            for (int d = 0; d < 3; ++d) {
              double dd = p[d] - x[3 * q + d];
              dd -= L * std::nearbyint(dd / L);
              r2 += dd * dd;
            }
            if (r2 < 4 * a * a) {
              ok = false;
              break;
            }
          }
    if (!ok) continue;
    cells[cid(c[0], c[1], c[2])].push_back(x.size() / 3);
    x.insert(x.end(), p, p + 3);
  }
  return x;
}

/// ||a - b|| / ||b|| (l2).
double relative_l2(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    num += (a[i] - b[i]) * (a[i] - b[i]);
    den += b[i] * b[i];
  }
  return std::sqrt(num / den);
}

template <class Fn>
double median_seconds(int reps, Fn&& fn) {
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) {
    StopWatch sw;
    fn();
    t.push_back(sw.seconds());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

/// Median of reps values returned by fn (seconds it timed itself).
template <class Fn>
double median_of(int reps, Fn&& fn) {
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) t.push_back(fn());
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

/// The Table I rows on the GPU: M F and split-sampler PTPS (median of 5 after a warm-up).
/// Relative l2 difference of u (a product already computed) from the CPU operator's M F with
/// options o (the same wave-grid precision) on the same particles.
double difference_from_cpu(const PseOptions& o, double L, const std::vector<double>& x, double a,
                           const std::vector<double>& f, const std::vector<double>& u) {
  PseRpy cpu(Geometry::periodic(L), 1.0, o);
  cpu.set_positions(x, a);
  std::vector<double> uc(u.size());
  cpu.apply(f, uc);
  return relative_l2(u, uc);
}

/// Seconds of `stage` per call in `t` over `calls` calls (0 where it did not run).
double per_call(const StageTimes& t, const char* stage, int calls) {
  const auto it = t.find(stage);
  return it == t.end() ? 0.0 : it->second / calls;
}

int run_cuda(const std::vector<std::size_t>& sizes, bool bin_sweep) {
  if (!PseRpyCuda::device_available()) {
    std::printf("# no usable CUDA device (or a build without CUDA): nothing to benchmark\n");
    return std::getenv("RPYFMM_EXPECT_CUDA") != nullptr ? 1 : 0;  // gpu-check.sh expects a device
  }
  // Same algorithm as the CPU path: the results differ by round-off only (atomic spreading in
  // another order), far below these; a larger difference fails the run (exit status 3). Double
  // grids: round-off of double; single grids: of float (~1e-7 relative on both sides).
  constexpr double kMaxRelDiffCpuDouble = 1e-9, kMaxRelDiffCpuSingle = 1e-5;
  constexpr int kReps = 5;
  int status = 0;
  const double a = 1.0, phi = 0.1;
  // MF / sample: host arrays in and out (transfers count); MF_dev / sample_dev: device arrays
  // (apply_device / sample_device). Stage columns: seconds per host-array M F (transfer = both
  // copies with the gathers and scatters, fft = forward + backward) and per sample (lanczos).
  std::printf(
      "N,backend,wave,lists,bin,transfers,grid,P,r_cut,set_positions_s,MF_s,MF_PTPS,MF_dev_s,MF_dev_PTPS,sample_s,"
      "sample_PTPS,sample_"
      "dev_s,sample_dev_PTPS,"
      "sample_over_MF,split_iters,rel_diff_cpu,MF_transfer_s,MF_real_s,MF_spread_s,MF_fft_s,MF_scale_s,"
      "MF_interp_s,sample_lanczos_s,sample_wave_s,step_s,step_PTPS\n");
  for (std::size_t n : sizes) {
    const double L = std::cbrt(static_cast<double>(n) * 4.0 / 3.0 * std::numbers::pi * a * a * a / phi);
    const auto x = hard_spheres(n, a, L, 7);
    std::vector<double> f(3 * n), u(3 * n), w(3 * n);
    fill_normal(f, 1, 0);
    // The defaults (single-precision wave grids, the automatic choice at tolerance 1e-3 as on the
    // CPU; device cell list; automatic bins; page-locked transfers), then each default changed
    // alone: double grids, the host's neighbour lists, one block per particle for spreading and
    // interpolation (the simpler kernels), pageable transfers. --bin-sweep: the
    // defaults with bin edges -1 (per particle), 6, 8, ..., 16 instead.
    struct Variant {
      WavePrecision precision;
      bool cells;
      int bin;
      bool pinned;
    };
    std::vector<Variant> variants;
    if (bin_sweep) {
      for (const int bin : {-1, 6, 8, 10, 12, 14, 16})
        variants.push_back({WavePrecision::single_precision, true, bin, true});
    } else {
      variants = {{WavePrecision::single_precision, true, 0, true},
                  {WavePrecision::double_precision, true, 0, true},
                  {WavePrecision::single_precision, false, 0, true},
                  {WavePrecision::single_precision, true, -1, true},
                  {WavePrecision::single_precision, true, 0, false}};
    }
    for (const Variant& variant : variants) {
      PseOptions o;
      o.tolerance = 1e-3;
      o.xi = 0.5 / a;
      o.wave_precision = variant.precision;
      const bool single = variant.precision == WavePrecision::single_precision;
      PseRpyCuda op(
          Geometry::periodic(L), 1.0, o,
          PseCudaOptions{
              .device_cell_list = variant.cells, .window_bin = variant.bin, .pinned_transfers = variant.pinned});
      op.set_positions(x, a);  // plans
      const double t_pos = median_seconds(3, [&] { op.set_positions(x, a); });
      op.apply(f, u);  // warm up (plans, first-touch)
      op.reset_stage_times();
      const double t_mf = median_seconds(kReps, [&] { op.apply(f, u); });
      const StageTimes mf = op.stage_times();
      int iters = 0;
      std::uint64_t step = 0;
      op.sample(5, step++, w);
      op.reset_stage_times();
      const double t_s = median_seconds(kReps, [&] { iters = op.sample(5, step++, w).iterations; });
      const StageTimes st = op.stage_times();
      double t_mf_dev = -1.0, t_s_dev = -1.0;
#ifdef RPYFMM_HAVE_CUDA_PSE
      {
        double *df = nullptr, *du = nullptr;
        const std::size_t bytes = f.size() * sizeof(double);
        if (cudaMalloc(reinterpret_cast<void**>(&df), bytes) == cudaSuccess &&
            cudaMalloc(reinterpret_cast<void**>(&du), bytes) == cudaSuccess &&
            cudaMemcpy(df, f.data(), bytes, cudaMemcpyHostToDevice) == cudaSuccess) {
          op.apply_device(df, du);
          t_mf_dev = median_seconds(kReps, [&] { op.apply_device(df, du); });
          t_s_dev = median_seconds(kReps, [&] { op.sample_device(5, step++, du); });
        }
        cudaFree(df);
        cudaFree(du);
      }
#endif
      // One Brownian step's mobility work with host arrays: set_positions, then
      // U = M F + sqrt(2 kT / dt) M^1/2 z (apply_with_noise, the split sampler's real-space Lanczos
      // and its wave noise sharing the product's FFTs).
      const double t_step = median_seconds(kReps, [&] {
        op.set_positions(x, a);
        op.apply_with_noise(f, 1.0, 5, step++, u);
      });
      double diff = -1.0;
      if (n <= 250000) {
        op.apply(f, u);
        diff = difference_from_cpu(o, L, x, a, f, u);
        const double bound = single ? kMaxRelDiffCpuSingle : kMaxRelDiffCpuDouble;
        if (!(diff <= bound)) {
          std::printf("# N = %zu: GPU and CPU differ by %.3g (> %.0e)\n", n, diff, bound);
          status = 3;
        }
      }
      const auto& p = op.parameters();
      const auto ptps = [n](double t) { return t > 0.0 ? static_cast<double>(n) / t : -1.0; };
      std::printf("%zu,cuda,%s,%s,%d,%s,%dx%dx%d,%d,%.3f,%.4g,", n, single ? "single" : "double",
                  op.device_cell_list_active() ? "device" : "host", op.window_bin_edge(),
                  variant.pinned ? "pinned" : "pageable", p.grid[0], p.grid[1], p.grid[2], p.support[0], p.r_cut,
                  t_pos);
      std::printf("%.4g,%.4g,%.4g,%.4g,%.4g,%.4g,%.4g,%.4g,%.2f,%d,%.3g,", t_mf, ptps(t_mf), t_mf_dev, ptps(t_mf_dev),
                  t_s, ptps(t_s), t_s_dev, ptps(t_s_dev), t_s / t_mf, iters, diff);
      std::printf(
          "%.4g,%.4g,%.4g,%.4g,%.4g,%.4g,%.4g,%.4g,", per_call(mf, "transfer", kReps),
          per_call(mf, "real_space", kReps), per_call(mf, "spread", kReps),
          per_call(mf, "fft_forward", kReps) + per_call(mf, "fft_backward", kReps), per_call(mf, "scale", kReps),
          per_call(mf, "interpolate", kReps), per_call(st, "lanczos", kReps),
          per_call(st, "scale", kReps) + per_call(st, "fft_backward", kReps) + per_call(st, "interpolate", kReps));
      std::printf("%.4g,%.4g\n", t_step, ptps(t_step));
      std::fflush(stdout);
    }
  }
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::size_t> sizes;
  bool quick = false;
  bool cuda = false;
  bool bin_sweep = false;
  bool fft_measure = false;
  bool with_error = false;
  double eta = 0.0;
  double xi_a = 0.5;
  int support = 0;
  int grid = 0;
  WavePrecision precision = WavePrecision::automatic;
  bool real_cache = true;
  for (int i = 1; i < argc; ++i) {
    if (std::string(argv[i]) == "--kernels" && i + 1 < argc) {
      const std::string v = argv[++i];
      if (v == "avx2" || v == "portable") {  // as on a CPU without AVX-512 (or AVX2)
        rpyfmm::set_simd_level(v == "avx2" ? rpyfmm::SimdLevel::avx2 : rpyfmm::SimdLevel::scalar);
      } else if (v != "auto") {
        std::fprintf(stderr, "bench_pse: --kernels takes auto, avx2 or portable\n");
        return 2;
      }
      continue;
    }
    if (std::string(argv[i]) == "--precision" && i + 1 < argc) {
      const std::string v = argv[++i];
      if (v == "single") {
        precision = WavePrecision::single_precision;
      } else if (v == "double") {
        precision = WavePrecision::double_precision;
      } else if (v != "auto") {
        std::fprintf(stderr, "bench_pse: --precision takes auto, single or double\n");
        return 2;
      }
      continue;
    }
    if (std::string(argv[i]) == "--grid" && i + 1 < argc) {
      grid = std::atoi(argv[++i]);
      continue;
    }
    if (std::string(argv[i]) == "--xi" && i + 1 < argc) {
      xi_a = std::atof(argv[++i]);
      continue;
    }
    if (std::string(argv[i]) == "--error") {
      with_error = true;
      continue;
    }
    if ((std::string(argv[i]) == "--eta" || std::string(argv[i]) == "--support") && i + 1 < argc) {
      if (std::string(argv[i]) == "--eta") {
        eta = std::atof(argv[++i]);
      } else {
        support = std::atoi(argv[++i]);
      }
      continue;
    }
    if (std::string(argv[i]) == "--fft-measure") {
      fft_measure = true;
      continue;
    }
    if (std::string(argv[i]) == "--no-real-cache") {
      real_cache = false;
      continue;
    }
    if (std::string(argv[i]) == "--quick") {
      quick = true;
      continue;
    }
    if (std::string(argv[i]) == "--cuda") {
      cuda = true;
      continue;
    }
    if (std::string(argv[i]) == "--bin-sweep") {
      bin_sweep = true;
      continue;
    }
    sizes.push_back(static_cast<std::size_t>(std::atoll(argv[i])));
  }
  if (sizes.empty()) sizes = {8000, 16000, 32000};
  for (std::size_t n : sizes) {
    if (n == 0) {
      std::fprintf(stderr, "bench_pse: particle counts must be positive integers\n");
      return 2;
    }
  }
  if (cuda) return run_cuda(sizes, bin_sweep);
  const int max_threads = omp_get_max_threads();
  const double a = 1.0, phi = 0.1;
  std::printf(
      "N,threads,grid,P,r_cut,MF_s,MF_PTPS,sample_s,sample_PTPS,sample_over_MF,split_iters,"
      "lanczos_full_s,lanczos_full_iters,spread,fft,scale,interp,real,lanczos_real,"
      "sample_noise_scale,sample_fft,sample_interp,plan_s,fft_measure,eta,MF_rel_error,xi_a,wave_single,"
      "MF_cached_s,real_cache_MB,MFT_s,torques_over_forces\n");
  for (std::size_t n : sizes) {
    const double L = std::cbrt(static_cast<double>(n) * 4.0 / 3.0 * std::numbers::pi * a * a * a / phi);
    const auto x = hard_spheres(n, a, L, 7);
    std::vector<double> f(3 * n), u(3 * n), w(3 * n), z(3 * n);
    fill_normal(f, 1, 0);
    fill_normal(z, 2, 0);
    for (int threads = 1; threads <= max_threads; ++threads) {
      omp_set_num_threads(threads);
      PseOptions o;
      o.tolerance = 1e-3;
      o.xi = xi_a / a;
      o.fft_threads = threads;
      o.fft_measure = fft_measure;
      o.window_eta = eta;
      o.support = support;
      o.grid = {grid, grid, grid};
      o.wave_precision = precision;
      o.real_space_cache = real_cache;
      PseRpy op(Geometry::periodic(L), 1.0, o);
      StopWatch plan_watch;
      op.set_positions(x, a);
      const double t_plan = plan_watch.seconds();
      op.apply(f, u);  // warm up
      const int reps = 3;
      // As in a time step: every timed product and sample is the first after set_positions (which
      // is not timed), so the real-space pair cache is filled by it, not carried over from the
      // previous repetition. MF_cached_s: a product that finds the cache filled (later products
      // with the same positions, e.g. an iterative solver's).
      auto fresh = [&](auto&& fn) {
        return [&] {
          op.set_positions(x, a);
          StopWatch sw;
          fn();
          return sw.seconds();
        };
      };
      op.reset_stage_times();
      const double t_mf = median_of(reps, fresh([&] { op.apply(f, u); }));
      StageTimes mf = op.stage_times();
      const double t_mf_cached = median_seconds(reps, [&] { op.apply(f, u); });
      // [U; W] = M [F; T] (docs/theory/pse.md section 5), the first product after set_positions too;
      // the warm-up builds the rotational table once per plan.
      std::vector<double> torques(3 * n), angular(3 * n);
      fill_normal(torques, 2, 0);
      op.apply(f, torques, u, angular);
      const double t_mft = median_of(reps, fresh([&] { op.apply(f, torques, u, angular); }));
      op.reset_stage_times();
      int iters = 0;
      std::uint64_t step = 0;
      const double t_s = median_of(reps, fresh([&] { iters = op.sample(5, step++, w).iterations; }));
      StageTimes st = op.stage_times();
      // Generic Lanczos on the full PSE operator, same tolerance ([PSE] Fig. 6).
      SqrtOptions so;
      so.method = SqrtMethod::lanczos;
      so.tolerance = 1e-3;
      int full_iters = 0;
      const double t_full = quick ? 0.0 : median_seconds(1, [&] { full_iters = op.apply_sqrt(z, w, so).iterations; });
      // The same with the block preconditioner (docs/theory/samplers.md; a comment line below the row).
      SqrtOptions sb = so;
      sb.preconditioner = SqrtPreconditioner::block;
      int block_iters = 0;
      const double t_block = quick ? 0.0 : median_seconds(1, [&] { block_iters = op.apply_sqrt(z, w, sb).iterations; });
      const auto& p = op.parameters();
      double rel_error = -1.0;
      if (with_error && n <= 64000) {
        PseOptions ro;
        ro.tolerance = 1e-8;
        op.apply(f, u);
        rel_error = difference_from_cpu(ro, L, x, a, f, u);
      }
      auto per = [&](const StageTimes& s, const char* k) {
        auto it = s.find(k);
        return it == s.end() ? 0.0 : it->second / reps;
      };
      std::printf(
          "%zu,%d,%dx%dx%d,%d,%.3f,%.4g,%.4g,%.4g,%.4g,%.2f,%d,%.4g,%d,%.3g,%.3g,%.3g,%.3g,%.3g,%.3g,%.3g,%.3g,%.3g,"
          "%.3g,%d,%.2f,%.3g,%.3g,%d,%.4g,%.1f,%.4g,%.2f\n",
          n, threads, p.grid[0], p.grid[1], p.grid[2], p.support[0], p.r_cut, t_mf, n / t_mf, t_s, n / t_s, t_s / t_mf,
          iters, t_full, full_iters, per(mf, "spread"), per(mf, "fft_forward") + per(mf, "fft_backward"),
          per(mf, "scale"), per(mf, "interpolate"), per(mf, "real_space"), per(st, "lanczos"), per(st, "scale"),
          per(st, "fft_backward"), per(st, "interpolate"), t_plan, fft_measure ? 1 : 0, p.window_eta, rel_error,
          p.xi * a, p.wave_single ? 1 : 0, t_mf_cached, static_cast<double>(p.real_space_cache_bytes) / 1e6, t_mft,
          t_mft / t_mf);
      if (!quick) {
        std::printf("# N=%zu threads=%d: block-preconditioned Lanczos on the full PSE operator %.4g s (%d its)\n", n,
                    threads, t_block, block_iters);
      }
      std::fflush(stdout);
    }
    if (quick) continue;
    // Real space: table vs direct closed forms (speed and difference), 1 thread.
    omp_set_num_threads(1);
    PseOptions o;
    o.tolerance = 1e-3;
    o.xi = 0.5;
    o.fft_threads = 1;
    o.real_space_cache = false;  // every timed product evaluates the pairs
    PseRpy tab(Geometry::periodic(L), 1.0, o);
    o.real_space_table = false;
    PseRpy dir(Geometry::periodic(L), 1.0, o);
    tab.set_positions(x, a);
    dir.set_positions(x, a);
    std::vector<double> ut(3 * n), ud(3 * n);
    const double tt = median_seconds(3, [&] { tab.apply_real(f, ut); });
    const double td = median_seconds(3, [&] { dir.apply_real(f, ud); });
    std::printf("# N=%zu real space 1 thread: table %.4g s, direct %.4g s (direct/table %.2f), rel diff %.2g\n", n, tt,
                td, td / tt, relative_l2(ut, ud));
    // The same particles in free space with the FMM operator (tolerance 1e-3): M F and a Lanczos
    // sample at the same tolerance, 1 thread, for the "PSE vs free-space FMM path" comparison.
    FmmRpy fmm(Geometry::open(), 1.0, {.tolerance = 1e-3});
    fmm.set_positions(x, a);
    fmm.apply(f, u);  // warm up
    const double t_fmm = median_seconds(3, [&] { fmm.apply(f, u); });
    SqrtOptions fs;
    fs.method = SqrtMethod::lanczos;
    fs.tolerance = 1e-3;
    int fmm_iters = 0;
    const double t_fmm_sample = median_seconds(1, [&] { fmm_iters = fmm.apply_sqrt(z, w, fs).iterations; });
    fs.preconditioner = SqrtPreconditioner::block;  // the BD engine's default sampler
    int fmm_block_iters = 0;
    const double t_fmm_block = median_seconds(1, [&] { fmm_block_iters = fmm.apply_sqrt(z, w, fs).iterations; });
    std::printf(
        "# N=%zu free-space FMM 1 thread: M F %.4g s (%.3g PTPS), Lanczos sample %.4g s (%d its, %.3g PTPS), "
        "block-preconditioned %.4g s (%d its, %.3g PTPS)\n",
        n, t_fmm, n / t_fmm, t_fmm_sample, fmm_iters, n / t_fmm_sample, t_fmm_block, fmm_block_iters, n / t_fmm_block);
    omp_set_num_threads(max_threads);
  }
}
