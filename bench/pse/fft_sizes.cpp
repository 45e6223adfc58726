// rpyfmm — time FFTW's 3D r2c + c2r transforms of three components (the PSE wave-space pass)
// per grid size, to calibrate the per-size FFT cost of the PSE cost model (docs/theory/pse.md).
//
// usage: fft_sizes [--min N] [--max N] [--reps R] [--measure]
// Every even length 2^a 3^b 5^c 7^d in [min, max] (default 8 ... 320), n^3 grids, 1 thread.
// Prints CSV: n, seconds (median of R forward + backward pairs), ns per point and log2(points),
// and the factor the cost model uses now (fft_length_cost). The model's table takes these
// timings below 48 and above 256 (divided by their median over 64 ... 320, medians of 3 runs);
// from 48 to 256 it takes the transforms timed in place, `bench_pse --quick --grid n 32000`,
// where lengths up to 128 ran 1.0-1.5x slower than alone.
#include <fftw3.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

bool smooth7(int n) {
  for (int f : {2, 3, 5, 7})
    while (n % f == 0) n /= f;
  return n == 1;
}

}  // namespace

int main(int argc, char** argv) {
  int lo = 8, hi = 320, reps = 3;
  bool measure = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--min" && i + 1 < argc)
      lo = std::atoi(argv[++i]);
    else if (a == "--max" && i + 1 < argc)
      hi = std::atoi(argv[++i]);
    else if (a == "--reps" && i + 1 < argc)
      reps = std::atoi(argv[++i]);
    else if (a == "--measure")
      measure = true;
    else {
      std::fprintf(stderr, "fft_sizes: unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  std::printf("n,seconds,ns_per_point_log2,model_factor\n");
  for (int n = lo; n <= hi; ++n) {
    if (n % 2 != 0 || !smooth7(n)) continue;
    const std::size_t ng = static_cast<std::size_t>(n) * n * n;
    const std::size_t modes = static_cast<std::size_t>(n) * n * (n / 2 + 1);
    double* grid = fftw_alloc_real(3 * ng);
    fftw_complex* spec = fftw_alloc_complex(3 * modes);
    const int dims[3] = {n, n, n};
    const unsigned flags = measure ? FFTW_MEASURE : FFTW_ESTIMATE;
    fftw_plan fwd = fftw_plan_many_dft_r2c(3, dims, 3, grid, nullptr, 1, static_cast<int>(ng), spec, nullptr, 1,
                                           static_cast<int>(modes), flags);
    fftw_plan bwd = fftw_plan_many_dft_c2r(3, dims, 3, spec, nullptr, 1, static_cast<int>(modes), grid, nullptr, 1,
                                           static_cast<int>(ng), flags);
    for (std::size_t i = 0; i < 3 * ng; ++i) grid[i] = std::sin(0.001 * static_cast<double>(i));
    std::vector<double> t;
    for (int r = 0; r < reps + 1; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      fftw_execute(fwd);
      fftw_execute(bwd);
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (r > 0) t.push_back(s);  // the first pair warms the caches and pages
    }
    const double s = median(t);
    const double pts = static_cast<double>(ng);
    std::printf("%d,%.6g,%.4f,%.2f\n", n, s, 1e9 * s / (pts * std::log2(pts)), rpyfmm::rpy::pse::fft_length_cost(n));
    std::fflush(stdout);
    fftw_destroy_plan(fwd);
    fftw_destroy_plan(bwd);
    fftw_free(grid);
    fftw_free(spec);
  }
  return 0;
}
