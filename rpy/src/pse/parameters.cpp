// rpyfmm — PSE parameter selection from a tolerance and the cost model for automatic xi
// ([PSE]: Fiore, Balboa Usabiaga, Donev & Swan, J. Chem. Phys. 146, 124116 (2017), eqs. 22-23;
// docs/theory/pse.md section 2).
#include <algorithm>
#include <boost/math/special_functions/erf.hpp>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"
#include "rpyfmm/rpy/pse/real_space.hpp"

namespace rpyfmm::rpy::pse {

namespace {

constexpr const char* kWhere = "PseRpy";

std::string fmt(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

/// Window shape values eta* tried when PseOptions::window_eta = 0 (automatic).
constexpr double kEtaCandidates[] = {0.4, 0.45, 0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85, 0.9};

/// Window truncation: the relative error of M F from cutting the Gaussian at m sigma, measured
/// against a window of 26 points on the same grid (2026-12-03, 2-vCPU Intel Xeon VM, family 6 model 167, AVX-512), is
/// at most kTruncation erfc(m / sqrt 2) for xi a = 0.3 ... 1.5 and eps = 1e-2 ... 1e-5 (2.8-3.8 x the 1.5 erfc(m / sqrt
/// 2) of the usual estimate, which let this term alone exceed eps by up to 1.9x).
constexpr double kTruncation = 6.0;

/// FFT lengths with their measured cost factor: r2c + c2r of three components on an n^3 grid
/// (FFTW_ESTIMATE, 1 thread), seconds per point and log2(points), divided by the median over
/// n = 64 ... 256. From 48 to 256 timed in place, inside the PSE pass (`bench_pse --grid n`,
/// 3 rounds), where lengths up to 128 ran 1.0-1.5x slower than alone; below 48 and above 256
/// timed alone (bench/pse/fft_sizes.cpp, 3 rounds); 2026-12-03, 2-vCPU Intel Xeon VM, family 6 model 167, AVX-512.
/// Every even 2^a 3^b 5^c 7^d from 8 to 320. The factor is not a smooth function of the factorisation: 200 = 2^3 5^2
/// costs 0.88, 210 = 2 3 5 7 1.21 and 256 = 2^8 1.28 (cache-set conflicts of power-of-two strides), 64 0.39, 70 0.80.
struct FftLength {
  int n;
  double factor;
};
constexpr FftLength kFftLengths[] = {
    {8, 0.37},   {10, 0.34},  {12, 0.32},  {14, 0.49},  {16, 0.33},  {18, 1.09},  {20, 0.34},  {24, 0.82},
    {28, 0.72},  {30, 1.57},  {32, 0.32},  {36, 0.94},  {40, 0.92},  {42, 0.72},  {48, 0.71},  {50, 0.82},
    {54, 0.93},  {56, 0.59},  {60, 0.82},  {64, 0.39},  {70, 0.80},  {72, 0.76},  {80, 0.83},  {84, 0.85},
    {90, 1.14},  {96, 0.94},  {98, 0.90},  {100, 0.72}, {108, 1.43}, {112, 0.76}, {120, 0.86}, {126, 1.05},
    {128, 0.69}, {140, 0.83}, {144, 1.30}, {150, 0.87}, {160, 0.94}, {162, 1.37}, {168, 1.19}, {180, 1.21},
    {192, 1.31}, {196, 1.06}, {200, 0.88}, {210, 1.21}, {216, 1.26}, {224, 1.32}, {240, 1.30}, {250, 1.07},
    {252, 1.00}, {256, 1.28}, {270, 1.45}, {280, 1.13}, {288, 1.19}, {294, 1.16}, {300, 1.00}, {320, 1.11}};
constexpr int kLongestTabulated = 320;
/// Factor of lengths beyond the table (next_fast_size lengths): the mean of the table from 250 up.
constexpr double kUntabulatedFactor = 1.15;
/// FFT lengths tried per axis: the first kGridCandidates admissible lengths >= the length the
/// accuracy needs (a longer one can be cheaper per point, and it may shrink the support).
constexpr int kGridCandidates = 4;

/// The first `count` lengths >= n that the grid choice may use: tabulated ones, then next_fast_size.
std::vector<int> fft_lengths_from(int n, int count) {
  std::vector<int> out;
  for (const auto& e : kFftLengths)
    if (e.n >= n && static_cast<int>(out.size()) < count) out.push_back(e.n);
  for (int m = std::max(n, kLongestTabulated + 1); static_cast<int>(out.size()) < count; ++m) {
    m = next_fast_size(m);
    out.push_back(m);
  }
  return out;
}

/// Whether the wave-space grids are single precision (PseOptions::wave_precision).
bool wave_single(const PseOptions& o) {
  return o.wave_precision == WavePrecision::single_precision ||
         (o.wave_precision == WavePrecision::automatic && o.tolerance >= kSingleWaveTolerance);
}

/// Memory of a plan (bytes): 3 real grids (with a 64-byte pad per x plane and component, the
/// spreading layout of wave_space.cpp) + 3 half spectra (4 or 8 bytes a real) + c(k) (double)
/// + the window cache.
double memory_estimate(const std::array<int, 3>& grid, const std::array<int, 3>& support, std::size_t n, bool single) {
  const double ng = static_cast<double>(grid[0]) * grid[1] * grid[2];
  const double modes = static_cast<double>(grid[0]) * grid[1] * (grid[2] / 2 + 1);
  const double real_bytes = single ? 4.0 : 8.0;
  return 3.0 * (real_bytes * ng + 64.0 * (grid[0] + 1)) + (6.0 * real_bytes + 8.0) * modes +
         8.0 * static_cast<double>(n) * (support[0] + support[1] + support[2] + 8);
}

/// The grid-dependent part of the cost model: two transforms of three components (per axis pass
/// the length's factor), the per-grid-point work (scaling, wave-space noise), and spreading plus
/// interpolation over the P_x P_y P_z support.
double grid_cost(const PseOptions& o, const std::array<int, 3>& grid, const std::array<int, 3>& support,
                 std::size_t n) {
  const double ng = static_cast<double>(grid[0]) * grid[1] * grid[2];
  double per_point_log2 = 0.0;
  for (int d = 0; d < 3; ++d) per_point_log2 += fft_length_cost(grid[d]) * std::log2(std::max(grid[d], 2));
  const double support3 = static_cast<double>(support[0]) * support[1] * support[2];
  return 2.0 * o.cost_fft_point * ng * per_point_log2 + o.cost_grid_point * ng +
         2.0 * o.cost_support_point * static_cast<double>(n) * support3;
}

/// Real-space cutoff for xi: the override, or the envelope cutoff for eps / 2 (docs/theory/pse.md).
double cutoff_for_xi(const PseOptions& o, double a, double xi) {
  return o.r_cut > 0.0 ? o.r_cut : real_space_cutoff(0.5 * o.tolerance, xi, a);
}

/// Gaussian support (points) along an axis of length L_d cut into nd points: the override, or
/// +-m sigma covered.
int support_on(const PseOptions& o, const PseParameters& p, double L_d, int nd) {
  return o.support > 0 ? o.support : static_cast<int>(std::ceil(2.0 * p.window_m * p.sigma / (L_d / nd)));
}

/// Per axis the override, or the first admissible FFT lengths >= L_d / h_max.
std::array<std::vector<int>, 3> candidate_lengths(const PseOptions& o, const std::array<double, 3>& L, double h_max) {
  std::array<std::vector<int>, 3> lengths;
  for (int d = 0; d < 3; ++d) {
    if (o.grid[d] > 0) {
      lengths[d] = {o.grid[d]};
      continue;
    }
    const double want = std::ceil(L[d] / h_max);
    require(want < 65536.0, ErrorCode::out_of_memory, kWhere,
            "grid of " + fmt(want) + " points along axis " + std::to_string(d) + " is too large");
    lengths[d] = fft_lengths_from(std::max(static_cast<int>(want), 4), kGridCandidates);
  }
  return lengths;
}

/// The combination of candidate lengths of least modelled cost whose supports fit on it and
/// within the memory limit; the shortest lengths where none does (the fallback, so that an
/// infeasible choice fails with its own message in set_grid).
std::array<int, 3> cheapest_grid(const PseOptions& o, const PseParameters& p, const std::array<double, 3>& L,
                                 std::size_t n, const std::array<std::vector<int>, 3>& lengths) {
  std::array<int, 3> grid = {lengths[0][0], lengths[1][0], lengths[2][0]};
  double best_cost = std::numeric_limits<double>::infinity();
  for (int gx : lengths[0])
    for (int gy : lengths[1])
      for (int gz : lengths[2]) {
        const std::array<int, 3> g = {gx, gy, gz};
        const std::array<int, 3> s = {support_on(o, p, L[0], gx), support_on(o, p, L[1], gy),
                                      support_on(o, p, L[2], gz)};
        if (s[0] > gx || s[1] > gy || s[2] > gz) continue;
        if (memory_estimate(g, s, n, p.wave_single) > static_cast<double>(o.max_memory_bytes)) continue;
        const double c = grid_cost(o, g, s, n);
        if (c < best_cost) {
          best_cost = c;
          grid = g;
        }
      }
  return grid;
}

/// p's grid, spacing, support and memory for `grid`; throws rpyfmm::Error where the window is
/// wider than the grid or the grid exceeds the plan size or the memory limit.
void set_grid(PseParameters& p, const PseOptions& o, const std::array<double, 3>& L, std::size_t n,
              const std::array<int, 3>& grid) {
  double ng = 1.0;
  for (int d = 0; d < 3; ++d) {
    const int nd = grid[d];
    p.grid[d] = nd;
    p.spacing[d] = L[d] / nd;
    p.support[d] = support_on(o, p, L[d], nd);
    require(p.support[d] <= nd, ErrorCode::invalid_argument, kWhere,
            "Gaussian window (" + std::to_string(p.support[d]) + " points) is wider than the grid (" +
                std::to_string(nd) + " points) along axis " + std::to_string(d) +
                "; the box is too small for xi = " + fmt(p.xi) + ": increase xi");
    ng *= nd;
  }
  require(ng < 2147483647.0, ErrorCode::out_of_memory, kWhere,
          "FFT grid of " + fmt(ng) + " points exceeds the 2^31 points FFTW/cuFFT plans accept");
  const double bytes = memory_estimate(p.grid, p.support, n, p.wave_single);
  require(bytes <= static_cast<double>(o.max_memory_bytes), ErrorCode::out_of_memory, kWhere,
          "FFT grid " + std::to_string(p.grid[0]) + " x " + std::to_string(p.grid[1]) + " x " +
              std::to_string(p.grid[2]) + " needs " + fmt(bytes / 1e9) + " GB, over the limit of " +
              fmt(static_cast<double>(o.max_memory_bytes) / 1e9) + " GB (PseOptions::max_memory_bytes)");
  p.memory_bytes = static_cast<std::size_t>(bytes);
}

/// Parameters for one fixed xi, window shape eta and cutoff r_cut; throws rpyfmm::Error when
/// infeasible.
PseParameters parameters_for(const PseOptions& o, double a, const std::array<double, 3>& L, std::size_t n, double xi,
                             double eta, double r_cut) {
  PseParameters p;
  p.radius = a;
  p.xi = xi;
  p.tolerance = o.tolerance;
  p.wave_single = wave_single(o);
  const double eps = o.tolerance;
  const double min_L = std::min({L[0], L[1], L[2]});

  // 1. Real-space cutoff from the envelope of F, G for eps_R = eps / 2 (docs/theory/pse.md).
  p.r_cut = r_cut;
  require(p.r_cut <= 0.5 * min_L, ErrorCode::invalid_argument, kWhere,
          "box length " + fmt(min_L) + " is smaller than 2 r_cut = " + fmt(2.0 * p.r_cut) + " (xi = " + fmt(xi) +
              ", tolerance " + fmt(eps) + "); increase xi or the box");

  // 2. Window half-width m (in sigma) from the truncation term kTruncation erfc(m / sqrt 2) <= eps / 2.
  p.window_m = std::numbers::sqrt2 * boost::math::erfc_inv(eps / (2.0 * kTruncation));
  // 3. Grid spacing: the aliasing exponent pi^2 eta (1 - eta/2) / (2 xi^2 h^2) >= ln(2/eps)
  // (docs/theory/pse.md).
  const double h_max = (std::numbers::pi / xi) * std::sqrt(eta * (1.0 - 0.5 * eta) / (2.0 * std::log(2.0 / eps)));
  p.window_eta = eta;
  p.sigma = std::sqrt(eta) / (2.0 * xi);  // sigma^2 = eta / (4 xi^2)
  // 4. Grid: per axis the override, or among the first admissible FFT lengths >= L_d / h_max the
  // combination of least modelled cost (5. with the support P_d covering +-m sigma on it).
  set_grid(p, o, L, n, cheapest_grid(o, p, L, n, candidate_lengths(o, L, h_max)));
  p.lanczos_tolerance = o.lanczos_tolerance > 0.0 ? o.lanczos_tolerance : eps;
  p.open_truncation = o.open_truncation;

  // Cost model T(xi) ([PSE] eq. 22): real-space pairs (M_r F and the Lanczos iterations of the
  // sampler), plus the grid-dependent part.
  const double density = o.pair_density > 0.0 ? o.pair_density : static_cast<double>(n) / (L[0] * L[1] * L[2]);
  const double neighbours = density * 4.0 / 3.0 * std::numbers::pi * p.r_cut * p.r_cut * p.r_cut;
  p.modelled_cost = o.cost_real_products * o.cost_real_pair * static_cast<double>(n) * (1.0 + neighbours) +
                    grid_cost(o, p.grid, p.support, n);
  return p;
}

}  // namespace

WavePrecision wave_precision_from_name(std::string_view name, const char* where) {
  if (name == "auto") return WavePrecision::automatic;
  if (name == "single") return WavePrecision::single_precision;
  if (name == "double") return WavePrecision::double_precision;
  fail(ErrorCode::invalid_argument, where,
       "wave precision must be auto, single or double, got '" + std::string(name) + "'");
}

double fft_length_cost(int n) {
  for (const auto& e : kFftLengths)
    if (e.n == n) return e.factor;
  return kUntabulatedFactor;
}

int next_fast_size(int n) {
  for (int m = std::max(n, 2) + (std::max(n, 2) % 2);; m += 2) {
    int r = m;
    for (int f : {2, 5, 7})
      while (r % f == 0) r /= f;
    if (r == 1 || r == 3) return m;
  }
}

namespace {

// Every option and the radius and box checked, with the error naming the offending value.
void check_options(const PseOptions& o, double a, const std::array<double, 3>& L) {
  require_positive(a, kWhere, "radius");
  if (!(std::isfinite(o.tolerance) && o.tolerance >= 1e-8 && o.tolerance < 0.1)) {
    fail(ErrorCode::invalid_argument, kWhere, "tolerance must lie in [1e-8, 0.1), got " + fmt(o.tolerance));
  }
  if (!(o.window_eta == 0.0 || (o.window_eta > 0.0 && o.window_eta < 1.0))) {
    fail(ErrorCode::invalid_argument, kWhere,
         "window_eta must lie in (0, 1) (or be 0: automatic), got " + fmt(o.window_eta));
  }
  require(std::isfinite(o.r_cut) && o.r_cut >= 0.0, ErrorCode::invalid_argument, kWhere,
          "r_cut override must be >= 0 (0 = automatic), got " + fmt(o.r_cut));
  require(o.support >= 0, ErrorCode::invalid_argument, kWhere, "support override must be >= 0");
  require(o.wave_precision == WavePrecision::automatic || o.wave_precision == WavePrecision::double_precision ||
              o.wave_precision == WavePrecision::single_precision,
          ErrorCode::invalid_argument, kWhere, "wave_precision is not a WavePrecision value");
  for (int d = 0; d < 3; ++d)
    require(o.grid[d] >= 0, ErrorCode::invalid_argument, kWhere, "grid override must be >= 0");
  require(std::isfinite(o.lanczos_tolerance) && o.lanczos_tolerance >= 0.0 && o.lanczos_tolerance < 1.0,
          ErrorCode::invalid_argument, kWhere, "lanczos_tolerance must lie in [0, 1), got " + fmt(o.lanczos_tolerance));
  require(std::isfinite(o.pair_density) && o.pair_density >= 0.0, ErrorCode::invalid_argument, kWhere,
          "pair_density must be finite and >= 0 (0 = N / box volume), got " + fmt(o.pair_density));
  require(std::isfinite(o.open_truncation) && o.open_truncation >= 0.0, ErrorCode::invalid_argument, kWhere,
          "open_truncation must be finite and >= 0 (0 = periodic), got " + fmt(o.open_truncation));
  for (double c : {o.cost_real_pair, o.cost_fft_point, o.cost_grid_point, o.cost_support_point, o.cost_real_products})
    require(std::isfinite(c) && c >= 0.0, ErrorCode::invalid_argument, kWhere,
            "cost-model constants (PseOptions::cost_*) must be finite and >= 0, got " + fmt(c));
  const double min_L = std::min({L[0], L[1], L[2]});
  require(min_L > 2.0 * a, ErrorCode::invalid_argument, kWhere,
          "box length " + fmt(min_L) + " is not larger than the particle diameter " + fmt(2.0 * a));
}

// Window shapes to try: the given one, or (automatic) the candidates, keeping the cheapest by the
// cost model. eta trades the grid (h_max ~ sqrt(eta (1 - eta/2))) against the support
// (P ~ m / sqrt(1 - eta/2) at h = h_max), and P moves in whole points.
std::vector<double> window_shapes(const PseOptions& o) {
  if (o.window_eta > 0.0) return {o.window_eta};
  return {std::begin(kEtaCandidates), std::end(kEtaCandidates)};
}

// The cheapest feasible window shape for one xi; if none is, the error of the last one tried
// (a fixed eta: its own error), so that its code (out_of_memory, ...) reaches the caller.
PseParameters best_for_xi(const PseOptions& o, double a, const std::array<double, 3>& L, std::size_t n,
                          std::span<const double> etas, double xi) {
  PseParameters best;
  bool found = false;
  std::exception_ptr last;
  const double r_cut = cutoff_for_xi(o, a, xi);
  for (double eta : etas) {
    try {
      PseParameters p = parameters_for(o, a, L, n, xi, eta, r_cut);
      if (!found || p.modelled_cost < best.modelled_cost) best = p;
      found = true;
    } catch (const Error&) {
      last = std::current_exception();
    }
  }
  if (!found) std::rethrow_exception(last);
  best.eta_automatic = etas.size() > 1;
  return best;
}

// Automatic xi: minimise the modelled cost over xi a in [0.2, 8] ([PSE] eq. 22; docs/theory/pse.md section 2).
PseParameters cheapest_xi(const PseOptions& o, double a, const std::array<double, 3>& L, std::size_t n,
                          std::span<const double> etas) {
  PseParameters best;
  bool found = false;
  std::string last_error;
  for (double xa = 0.2; xa <= 8.0 + 1e-12; xa += (xa < 2.5 ? 0.05 : 0.25)) {
    try {
      const PseParameters p = best_for_xi(o, a, L, n, etas, xa / a);
      if (!found || p.modelled_cost < best.modelled_cost) best = p;
      found = true;
    } catch (const Error& e) {
      if (e.code() == ErrorCode::out_of_memory && found) break;  // larger xi only grows the grid
      last_error = e.what();
    }
  }
  require(found, ErrorCode::invalid_argument, kWhere,
          "no Ewald parameter xi a in [0.2, 8] is feasible for this box and tolerance (" + last_error + ")");
  best.xi_automatic = true;
  return best;
}

}  // namespace

PseParameters choose_parameters(const PseOptions& o, double a, const std::array<double, 3>& L,
                                std::size_t n_particles) {
  check_options(o, a, L);
  const std::vector<double> etas = window_shapes(o);
  if (o.xi == 0.0) return cheapest_xi(o, a, L, n_particles, etas);
  require(std::isfinite(o.xi) && o.xi * a >= 0.05, ErrorCode::invalid_argument, kWhere,
          "xi a must be >= 0.05 (closed forms lose accuracy below), got xi = " + fmt(o.xi));
  return best_for_xi(o, a, L, n_particles, etas, o.xi);
}

std::string PseParameters::summary() const {
  return "PSE: xi = " + fmt(xi) + (xi_automatic ? " (auto)" : "") + ", xi a = " + fmt(xi * radius) +
         ", tolerance = " + fmt(tolerance) + ", r_cut = " + fmt(r_cut) + ", grid = " + std::to_string(grid[0]) + "x" +
         std::to_string(grid[1]) + "x" + std::to_string(grid[2]) + ", h = " + fmt(spacing[0]) +
         ", P = " + std::to_string(support[0]) + "/" + std::to_string(support[1]) + "/" + std::to_string(support[2]) +
         ", eta = " + fmt(window_eta) + (eta_automatic ? " (auto)" : "") + ", m = " + fmt(window_m) +
         ", table dr = " + fmt(table_dr) + " (" + std::to_string(table_size) + " entries)" +
         ", lanczos tol = " + fmt(lanczos_tolerance) + ", wave grids " + (wave_single ? "single" : "double") +
         (open_truncation > 0.0 ? ", open boundaries (R = " + fmt(open_truncation) + ")" : std::string()) +
         ", memory = " + fmt(static_cast<double>(memory_bytes) / 1e6) + " MB" +
         (real_space_cache_bytes > 0 ? ", pair cache " + fmt(static_cast<double>(real_space_cache_bytes) / 1e6) + " MB"
                                     : std::string());
}

}  // namespace rpyfmm::rpy::pse
