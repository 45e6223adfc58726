// rpyfmm — Positively Split Ewald (PSE): options and the parameter choices
// derived from a tolerance.
//
// Fiore, Balboa Usabiaga, Donev & Swan, J. Chem. Phys. 146, 124116 (2017)
// ("[PSE]"), Sec. II.C and eqs. 22-23; Lindbo & Tornberg, J. Comput. Phys. 230 (2011) 8744
// for the Gaussian window; the recipe is derived in docs/theory/pse.md (parameters from the
// tolerance).
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <string_view>

namespace rpyfmm::rpy::pse {

/// Floating-point type of the wave-space grids and spectra (spreading, FFTs, scaling,
/// interpolation). Positions, forces, weights, the real-space part and every sum over a
/// particle's window stay in double precision.
enum class WavePrecision {
  /// single_precision when the tolerance is >= kSingleWaveTolerance, double_precision below.
  automatic,
  double_precision,
  /// float grids and FFTW's single-precision transforms: 1.35-1.8x faster transforms and half the
  /// grid memory; adds ~1e-7 relative error to M F (tests/pse/test_pse_precision.cpp); the wave
  /// noise is then drawn in single precision too (normal6f). CPU and CUDA.
  single_precision,
};

/// "auto", "single" or "double" (the names the CLI, Python and BD configs use); throws
/// rpyfmm::Error (invalid_argument) naming `where` for anything else.
WavePrecision wave_precision_from_name(std::string_view name, const char* where = "PseRpy");

/// Smallest tolerance for which WavePrecision::automatic picks single precision: float round-off
/// in the wave space (~1e-7 relative, measured in tests/pse/test_pse_precision.cpp) stays 100x
/// below it.
inline constexpr double kSingleWaveTolerance = 1e-5;

/// User options of the PSE operator. Every zero means "choose from the tolerance".
struct PseOptions {
  /// Requested relative accuracy of U = M F (relative to M0 = 1/(6 pi eta a)).
  /// Must lie in [1e-8, 0.1) (below 1e-8 the double-precision closed forms
  /// of App. A near r -> 0 (~1e-9, docs/theory/pse.md) no longer leave room in the budget). Each error term (real-space
  /// cutoff, aliasing, window truncation, table) is budgeted below it (docs/theory/pse.md).
  double tolerance = 1e-3;
  /// Ewald splitting parameter xi (1/length). 0 = automatic: minimise the
  /// modelled cost T(xi) of [PSE] eq. 22 over xi a in [0.2, 8] (docs/theory/pse.md).
  /// A fixed xi must satisfy xi a >= 0.05 (the closed forms of App. A lose
  /// digits below; docs/theory/pse.md).
  double xi = 0.0;
  /// Real-space cutoff override (length); 0 = envelope cutoff for tolerance/2.
  double r_cut = 0.0;
  /// Grid override (points per direction); all zero = from the tolerance.
  std::array<int, 3> grid = {0, 0, 0};
  /// Gaussian support override (grid points per direction); 0 = from the tolerance.
  int support = 0;
  /// SE shape parameter eta* in (0, 1): trades grid size against support (docs/theory/pse.md).
  /// 0 = automatic: the cheapest of eta* = 0.4, 0.45, ..., 0.9 by the cost model (for each xi
  /// tried, when xi is automatic too). The error terms meet the tolerance for every eta*.
  double window_eta = 0.0;
  /// Lanczos tolerance of the real-space sample (split sampler); 0 = tolerance.
  double lanczos_tolerance = 0.0;
  /// Evaluate F, G from a linear table (true) or from the closed forms per pair (false).
  bool real_space_table = true;
  /// Keep each real-space pair's block (F, G and the direction) and reuse it in the later products
  /// with the same positions: the split sampler's Lanczos keeps them from its first product (its
  /// later iterations and M F in a BD step reuse them), apply() from the second product after
  /// set_positions (a single M F per positions pays nothing): 1.3-1.6x faster later products
  /// (measured 2026-12-03 on a 2-vCPU Intel Xeon VM, family 6 model 167, AVX-512). Kept in float with single-precision
  /// wave grids (wave_precision), else in double: 20 or 40 bytes per pair within r_cut, kept only while it fits in
  /// max_memory_bytes beside the grids (PseParameters::real_space_cache_bytes). On CPUs without AVX-512 it holds every
  /// entry of the full neighbour rows (twice the pairs).
  bool real_space_cache = true;
  /// FFTW threads: 0 = automatic (all OpenMP threads for grids of >= 2^20 points, one
  /// below, where thread synchronisation costs more than it saves on a loaded machine).
  int fft_threads = 0;
  /// FFTW planning: false = FFTW_ESTIMATE (instant, the same algorithm in every run, so results
  /// are reproducible bit for bit across processes); true = FFTW_MEASURE: the plans are timed on
  /// this machine when the operator is planned (~0.5 s for a 100^3 grid, ~3 s for 200^3; later
  /// plans of the same size in the process reuse FFTW's wisdom), and the transforms then run
  /// 1.1-1.9x faster (2026-12-03, 2-vCPU Intel Xeon VM, family 6 model 167, AVX-512). The algorithm FFTW picks may
  /// differ between processes, so results then agree to round-off, not bit for bit. For long runs.
  bool fft_measure = false;
  /// Precision of the wave-space grids (WavePrecision), on the CPU and the CUDA backend alike.
  /// Single-precision grids also draw their wave-space noise in single precision (normal6f).
  WavePrecision wave_precision = WavePrecision::automatic;
  /// Upper bound on the memory (bytes) of FFT grids, spectra and tables; exceeding
  /// it throws ErrorCode::out_of_memory before anything is allocated. Default 16 GiB.
  std::size_t max_memory_bytes = std::size_t{16} << 30;
  /// Cost-model constants, used to choose xi (when 0), the window shape (when 0) and the grid
  /// lengths: seconds per real-space pair (self term included), per FFT point and log2 of one
  /// transform of 3 components (times the length's factor, fft_length_cost), per grid point and
  /// step (scaling and the wave-space noise), and per support point of spreading or of
  /// interpolation. Measured with bench_pse on the development machine (1 thread, N = 32000 and
  /// 128000; 2026-12-03, 2-vCPU Intel Xeon VM, family 6 model 167, AVX-512); only their ratios matter.
  double cost_real_pair = 6.5e-9;
  double cost_fft_point = 1.09e-9;
  double cost_grid_point = 1.75e-8;
  double cost_support_point = 1.8e-9;
  /// Real-space products per step assumed by the cost model: 1 for M F only,
  /// 1 + Lanczos iterations (~5) when the split sampler is used every step.
  double cost_real_products = 5.0;
  /// Number density of particles around each particle as the cost model counts real-space
  /// pairs; 0 = N / box volume. OpenPseRpy sets it, as its particles fill only part of the box.
  double pair_density = 0.0;
  /// Open boundaries (OpenPseRpy sets it; 0 = periodic): the wave-space part uses the Stokeslet
  /// built from the compactly supported biharmonic kernel of radius R = open_truncation, i.e.
  /// c(k) times q(kR) = 1 + cos(kR)/2 - 3 sin(kR)/(2kR) (docs/theory/pse.md, "Open boundaries").
  double open_truncation = 0.0;
};

/// The choices made for one (radius, box, N) — reported by PseRpy::parameters().
struct PseParameters {
  double radius = 0.0;                        ///< a
  double xi = 0.0;                            ///< Ewald splitting parameter
  bool xi_automatic = false;                  ///< chosen by the cost model
  double tolerance = 0.0;                     ///< requested eps
  double r_cut = 0.0;                         ///< real-space cutoff
  std::array<int, 3> grid = {0, 0, 0};        ///< N_x, N_y, N_z (even products of 2, 3, 5, 7)
  std::array<double, 3> spacing = {0, 0, 0};  ///< h_d = L_d / N_d
  std::array<int, 3> support = {0, 0, 0};     ///< P_d grid points per direction
  double window_eta = 0.0;                    ///< SE eta = 4 xi^2 sigma^2
  bool eta_automatic = false;                 ///< eta chosen by the cost model
  double sigma = 0.0;                         ///< Gaussian standard deviation
  double window_m = 0.0;                      ///< half-width in units of sigma (m)
  double table_dr = 0.0;                      ///< table spacing (0 when evaluated directly)
  std::size_t table_size = 0;                 ///< table entries
  double lanczos_tolerance = 0.0;             ///< real-space sample tolerance
  bool wave_single = false;                   ///< wave-space grids in single precision
  std::size_t memory_bytes = 0;               ///< grids + spectra + tables
  std::size_t real_space_cache_bytes = 0;     ///< pair cache for the current positions (0: none)
  double modelled_cost = 0.0;                 ///< T(xi) of the cost model (s), for reference
  double open_truncation = 0.0;               ///< R of the open-boundary kernel (0: periodic)

  /// One-line human-readable summary.
  [[nodiscard]] std::string summary() const;
};

/// Chooses the PSE parameters for N spheres of radius `a` in box `L` (docs/theory/pse.md:
/// parameters from the tolerance, cost model). Throws rpyfmm::Error (naming the offending quantity) for a
/// tolerance out of range, xi a < 0.05, a box smaller than 2 r_cut or than a
/// sphere diameter, a window wider than the box, or a grid over the memory limit.
PseParameters choose_parameters(const PseOptions& options, double radius, const std::array<double, 3>& box,
                                std::size_t n_particles);

/// Relative cost per point and log2 of an FFT of length n along one axis, as the cost model uses it
/// (1 = the median of lengths 64 ... 256): FFTW_ESTIMATE transforms timed per length, in place
/// inside the PSE pass from 48 to 256 and alone (bench/pse/fft_sizes.cpp) otherwise, for the
/// even lengths 2^a 3^b 5^c 7^d up to 320; 1.15 beyond. The grid is chosen among the first
/// admissible lengths at or above what the accuracy needs.
double fft_length_cost(int n);

/// Smallest even n' >= n of the form 2^a 3^b 5^c 7^d with b <= 1: the grid lengths beyond the
/// measured table of fft_length_cost (up to 320 every even 7-smooth length is a candidate). Odd
/// lengths are avoided: FFTW's r2c/c2r transforms of odd length ran 1.5-2.2x slower per point
/// than the even sizes next to them (63 vs 64, 125 vs 128, 147 vs 150, 189 vs 192), and lengths
/// with 3^2 or more mostly did too (2026-12-03, 2-vCPU Intel Xeon VM, family 6 model 167, AVX-512).
int next_fast_size(int n);

}  // namespace rpyfmm::rpy::pse
