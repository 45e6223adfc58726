// rpyfmm — PSE wave space on the CPU ([PSE] eqs. 19-21; docs/theory/pse.md).
#include "wave_space.hpp"

#include <fftw3.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <numbers>
#include <span>
#include <vector>

#include "open_truncation.hpp"
#include "rotation_modes.hpp"
#include "rpyfmm/core/validate.hpp"
#include "scale_line.hpp"
#include "window_avx2.hpp"
#include "window_avx512.hpp"

namespace rpyfmm::rpy::pse::detail {

namespace {

/// Loops below this much work run serially (a parallel region costs more there).
constexpr std::size_t kParallelWork = 32768;
/// Particles ahead whose forces (outputs) spreading (interpolation) prefetches.
constexpr std::size_t kPrefetchAhead = 8;

/// Adds the seconds since the previous lap (or construction) to times[stage]; null times: none.
class StageLaps {
 public:
  explicit StageLaps(StageTimes* times) : times_(times) {}
  void operator()(const char* stage) {
    if (times_) (*times_)[stage] += watch_.seconds();
    watch_.restart();
  }

 private:
  StageTimes* times_;
  StopWatch watch_;
};

std::mutex& planner_mutex() {
  static std::mutex m;
  return m;
}

/// Tile class along one axis: 0 / 1 by parity, 2 for the last tile of an odd count
/// (it touches tile 0 through the periodic wrap). Same-class tiles are >= 2 apart.
int tile_class(int b, int nb) {
  return (nb % 2 == 1 && nb > 1 && b == nb - 1) ? 2 : b % 2;
}

/// Which window kernels run (the widest the CPU has; P_z <= 8 for the vector ones).
enum class WindowKernels { portable, avx2, avx512 };
WindowKernels window_kernels(int Pz) {
  if (avx512_window_kernels(Pz)) return WindowKernels::avx512;
  if (avx2_window_kernels(Pz)) return WindowKernels::avx2;
  return WindowKernels::portable;
}

/// The z window [z0, z0 + P) of a particle as at most two contiguous runs of the periodic
/// grid: [z0, z0 + len0) and [0, P - len0).
struct ZRuns {
  std::size_t z0;
  int len0;
};
ZRuns z_runs(int z0, int P, int nz) {
  return {static_cast<std::size_t>(z0), std::min(P, nz - z0)};
}

/// g_c[line + z] += wxy * wf_c[l] over one z window (both runs), c = 0, 1, 2.
template <class Real>
[[gnu::always_inline]] inline void spread_line(Real* g0, Real* g1, Real* g2, std::size_t line, ZRuns z, int P, Real wxy,
                                               const Real* wf) {
  Real* p0 = g0 + line + z.z0;
  Real* p1 = g1 + line + z.z0;
  Real* p2 = g2 + line + z.z0;
#pragma omp simd
  for (int l = 0; l < z.len0; ++l) {
    p0[l] += wxy * wf[l];
    p1[l] += wxy * wf[P + l];
    p2[l] += wxy * wf[2 * P + l];
  }
  for (int l = z.len0; l < P; ++l) {
    const std::size_t k = line + static_cast<std::size_t>(l - z.len0);
    g0[k] += wxy * wf[l];
    g1[k] += wxy * wf[P + l];
    g2[k] += wxy * wf[2 * P + l];
  }
}

/// s_c += sum_l wz[l] g_c[line + z_l] over one z window (both runs), c = 0, 1, 2 (sums in double).
template <class Real>
[[gnu::always_inline]] inline void gather_line(const Real* g0, const Real* g1, const Real* g2, std::size_t line,
                                               ZRuns z, int P, const double* wz, double s[3]) {
  const Real* p0 = g0 + line + z.z0;
  const Real* p1 = g1 + line + z.z0;
  const Real* p2 = g2 + line + z.z0;
  double s0 = 0.0, s1 = 0.0, s2 = 0.0;
#pragma omp simd reduction(+ : s0, s1, s2)
  for (int l = 0; l < z.len0; ++l) {
    s0 += wz[l] * p0[l];
    s1 += wz[l] * p1[l];
    s2 += wz[l] * p2[l];
  }
  for (int l = z.len0; l < P; ++l) {
    const std::size_t k = line + static_cast<std::size_t>(l - z.len0);
    s0 += wz[l] * g0[k];
    s1 += wz[l] * g1[k];
    s2 += wz[l] * g2[k];
  }
  s[0] += s0;
  s[1] += s1;
  s[2] += s2;
}

/// A real grid's memory layout: n[d] points along axis d at stride[d] reals, components dist
/// reals apart. Its half spectrum is packed (n_x, n_y, n_z / 2 + 1).
struct RealLayout {
  int n[3];
  std::ptrdiff_t stride[3];
  std::ptrdiff_t dist;
};

/// FFTW's guru description of the transforms of `howmany` components between a real layout and
/// the packed half spectrum (fftw_iodim64 and fftwf_iodim64 are one type).
struct Iodims {
  fftw_iodim64 dims[3];
  fftw_iodim64 howmany;
  Iodims(const RealLayout& r, int count, bool real_to_complex) {
    const std::ptrdiff_t nzh = r.n[2] / 2 + 1;
    const std::ptrdiff_t stride_c[3] = {r.n[1] * nzh, nzh, 1};
    const std::ptrdiff_t dist_c = r.n[0] * stride_c[0];
    for (int k = 0; k < 3; ++k)
      dims[k] = real_to_complex ? fftw_iodim64{r.n[k], r.stride[k], stride_c[k]}
                                : fftw_iodim64{r.n[k], stride_c[k], r.stride[k]};
    howmany = real_to_complex ? fftw_iodim64{count, r.dist, dist_c} : fftw_iodim64{count, dist_c, r.dist};
  }
};

/// plan_fn (fftw(f)_plan_guru64_dft_r2c or _c2r) for those transforms.
template <class PlanFn, class In, class Out>
auto guru_plan(PlanFn plan_fn, const RealLayout& r, int howmany, bool real_to_complex, In in, Out out, unsigned flags) {
  Iodims io(r, howmany, real_to_complex);
  return plan_fn(3, io.dims, 1, &io.howmany, in, out, flags);
}

/// FFTW's double- and single-precision interfaces under one name (fftw_* / fftwf_*).
template <class Real>
struct Fftw;

template <>
struct Fftw<double> {
  using Complex = fftw_complex;
  using Plan = fftw_plan;
  static double* alloc_real(std::size_t n) { return fftw_alloc_real(n); }
  static Complex* alloc_complex(std::size_t n) { return fftw_alloc_complex(n); }
  static void free(void* p) { fftw_free(p); }
  static void init_threads() {
    static std::once_flag once;
    std::call_once(once, [] {
      fftw_init_threads();
      fftw_make_planner_thread_safe();
    });
  }
  static void plan_with_nthreads(int n) { fftw_plan_with_nthreads(n); }
  static Plan r2c(const RealLayout& r, int howmany, double* in, Complex* out, unsigned flags) {
    return guru_plan(fftw_plan_guru64_dft_r2c, r, howmany, true, in, out, flags);
  }
  static Plan c2r(const RealLayout& r, int howmany, Complex* in, double* out, unsigned flags) {
    return guru_plan(fftw_plan_guru64_dft_c2r, r, howmany, false, in, out, flags);
  }
  static void execute_r2c(Plan p, double* in, Complex* out) { fftw_execute_dft_r2c(p, in, out); }
  static void execute_c2r(Plan p, Complex* in, double* out) { fftw_execute_dft_c2r(p, in, out); }
  static void destroy(Plan p) { fftw_destroy_plan(p); }
};

template <>
struct Fftw<float> {
  using Complex = fftwf_complex;
  using Plan = fftwf_plan;
  static float* alloc_real(std::size_t n) { return fftwf_alloc_real(n); }
  static Complex* alloc_complex(std::size_t n) { return fftwf_alloc_complex(n); }
  static void free(void* p) { fftwf_free(p); }
  static void init_threads() {
    static std::once_flag once;
    std::call_once(once, [] {
      fftwf_init_threads();
      fftwf_make_planner_thread_safe();
    });
  }
  static void plan_with_nthreads(int n) { fftwf_plan_with_nthreads(n); }
  static Plan r2c(const RealLayout& r, int howmany, float* in, Complex* out, unsigned flags) {
    return guru_plan(fftwf_plan_guru64_dft_r2c, r, howmany, true, in, out, flags);
  }
  static Plan c2r(const RealLayout& r, int howmany, Complex* in, float* out, unsigned flags) {
    return guru_plan(fftwf_plan_guru64_dft_c2r, r, howmany, false, in, out, flags);
  }
  static void execute_r2c(Plan p, float* in, Complex* out) { fftwf_execute_dft_r2c(p, in, out); }
  static void execute_c2r(Plan p, Complex* in, float* out) { fftwf_execute_dft_c2r(p, in, out); }
  static void destroy(Plan p) { fftwf_destroy_plan(p); }
};

/// WaveSpace on grids and spectra of type Real (double, or float for PseParameters::wave_single).
template <class Real>
class WaveGrid final : public WaveSpace {
 public:
  WaveGrid(const PseParameters& p, const std::array<double, 3>& box, double viscosity, int fft_threads,
           bool fft_measure);
  ~WaveGrid() override;
  WaveGrid(const WaveGrid&) = delete;
  WaveGrid& operator=(const WaveGrid&) = delete;

  void set_positions(std::span<const double> x) override;
  void apply(const double* forces, double* out, bool accumulate, const NoiseKey* noise, double noise_scale,
             StageTimes* times) override;
  void apply_rotation(const double* forces, const double* torques, double* velocities, double* angular, bool accumulate,
                      const NoiseKey* noise, double noise_scale, StageTimes* times) override;

 private:
  using Plan = typename Fftw<Real>::Plan;
  using Complex = typename Fftw<Real>::Complex;

  /// Spreads three components per particle onto `grid` (grid_ or rotation_grid_).
  void spread(const double* forces, Real* grid);
  /// Interpolates the three components of `grid` (after the transform back) to the particles.
  void interpolate(const Real* grid, double* out, bool accumulate) const;
  /// apply_rotation's per-mode pass on spectrum_ (forces -> U) and rotation_spectrum_ (torques -> W).
  void scale_rotation_modes(bool deterministic, const NoiseKey* noise, double noise_factor);
  /// The second grid and spectrum of apply_rotation (the plans run on them by FFTW's new-array execute).
  void allocate_rotation_buffers();
  /// rotation_factors_ for every mode (once per plan, with the buffers).
  void tabulate_rotation_factors();
  // set_positions stages: window starts and offsets in input order, the tile order and colours,
  // the window weights in tile order.
  void window_starts(std::span<const double> x, std::vector<int>& start, std::vector<double>& offset) const;
  void order_by_tile(const std::vector<int>& start);
  void weights_in_tile_order(const std::vector<int>& start, const std::vector<double>& offset);
  void window_lines(std::size_t q, std::size_t* xline, std::size_t* yline, std::size_t plane) const;
  /// Destroys the plans and frees the grids (idempotent).
  void release() noexcept;

  PseParameters p_;
  std::array<int, 3> n_{};
  std::array<int, 3> P_{};
  std::size_t ng_ = 0;
  // Real grids as spread: component c at grid_ + c * comp_dist_, point (ix, iy, iz) at
  // ix * plane_ + iy * n_z + iz; as interpolated (after the transform back): packed, c * ng_ and
  // (ix * n_y + iy) * n_z + iz.
  std::size_t plane_ = 0;
  std::size_t comp_dist_ = 0;
  ModeGeometry modes_{};
  double dv_ = 0.0;
  double c3_ = 0.0;
  std::vector<double> ck_;
  Real* grid_ = nullptr;           // 3 x Ng real (fftw_malloc)
  Real* spectrum_ = nullptr;       // 3 x modes complex (fftw_malloc)
  Real* rotation_grid_ = nullptr;  // the same for torques and angular velocities (apply_rotation)
  Real* rotation_spectrum_ = nullptr;
  RotationModeConstants rotation_constants_{};
  std::vector<RotationModeFactors> rotation_factors_;  // per mode, with the rotation buffers
  Plan plan_forward_ = nullptr;
  Plan plan_backward_ = nullptr;
  int fft_threads_ = 1;
  bool parallel_modes_ = false;

  // Per particle, in tile order (slot q holds particle order_[q]): wrapped window starts
  // and cached 1D weights (Px + Py + Pz). The loops over slots then read them in memory order.
  std::size_t np_ = 0;
  std::vector<int> start_;
  std::vector<double> weights_;
  // Tiles for race-free spreading: particles sorted by tile; tiles grouped by colour.
  std::vector<std::size_t> order_;
  std::vector<std::size_t> tile_begin_;              // per tile: range in order_
  std::array<std::vector<int>, 9> tiles_of_colour_;  // tile ids per colour
};

}  // namespace

std::vector<double> wave_scaling_table(const PseParameters& p, const std::array<double, 3>& box, double viscosity,
                                       ModeGeometry& g, int x_begin, int x_end) {
  for (int d = 0; d < 3; ++d) {
    g.n[d] = p.grid[d];
    g.two_pi_L[d] = 2.0 * std::numbers::pi / box[d];
  }
  g.nzh = g.n[2] / 2 + 1;
  g.modes = static_cast<std::size_t>(g.n[0]) * static_cast<std::size_t>(g.n[1]) * static_cast<std::size_t>(g.nzh);
  g.comp_stride = 2 * g.modes;
  const double ng = static_cast<double>(g.n[0]) * g.n[1] * g.n[2];
  const double a = p.radius;
  const double inv_4xi2 = 1.0 / (4.0 * p.xi * p.xi);
  if (x_end < 0) x_end = g.n[0];
  const auto planes = static_cast<std::int64_t>(x_end - x_begin);
  std::vector<double> ck(static_cast<std::size_t>(planes) * static_cast<std::size_t>(g.n[1]) *
                         static_cast<std::size_t>(g.nzh));
#pragma omp parallel for schedule(static) if (ck.size() >= kParallelWork)
  for (std::int64_t lx = 0; lx < planes; ++lx) {
    const std::int64_t ix = x_begin + lx;
    for (int iy = 0; iy < g.n[1]; ++iy) {
      for (int iz = 0; iz < g.nzh; ++iz) {
        const std::size_t idx = (static_cast<std::size_t>(lx) * g.n[1] + iy) * g.nzh + iz;
        const bool nyquist = 2 * ix == g.n[0] || 2 * iy == g.n[1] || 2 * iz == g.n[2];
        if (nyquist || (ix == 0 && iy == 0 && iz == 0)) {
          ck[idx] = 0.0;
          continue;
        }
        const double k0 = g.two_pi_L[0] * signed_index(static_cast<int>(ix), g.n[0]);
        const double k1 = g.two_pi_L[1] * signed_index(iy, g.n[1]);
        const double k2 = g.two_pi_L[2] * iz;
        const double k2sum = k0 * k0 + k1 * k1 + k2 * k2;
        const double k = std::sqrt(k2sum);
        const double sinc = std::sin(k * a) / (k * a);
        const double x = k2sum * inv_4xi2;
        // sg(k) = sinc^2(ka) (1 + k^2/4xi^2) exp(-(1-eta) k^2/4xi^2) / k^2  ([PSE] eqs. 9 and 11)
        double sg = sinc * sinc * (1.0 + x) * std::exp(-(1.0 - p.window_eta) * x) / k2sum;
        // Open boundaries: the compactly supported Stokeslet's factor (open_truncation.hpp).
        if (p.open_truncation > 0.0) sg *= open_truncation_factor(k * p.open_truncation);
        ck[idx] = sg / (viscosity * ng);
      }
    }
  }
  return ck;
}

RotationModeConstants rotation_mode_constants(const PseParameters& p, double viscosity) {
  const double ng = static_cast<double>(p.grid[0]) * p.grid[1] * p.grid[2];
  return {p.radius, 1.0 / (4.0 * p.xi * p.xi), 1.0 - p.window_eta, 1.0 / (viscosity * ng), p.open_truncation};
}

template <class Real>
WaveGrid<Real>::WaveGrid(const PseParameters& p, const std::array<double, 3>& box, double viscosity, int fft_threads,
                         bool fft_measure)
    : p_(p) {
  using F = Fftw<Real>;
  n_ = p.grid;
  P_ = p.support;
  ng_ = static_cast<std::size_t>(n_[0]) * static_cast<std::size_t>(n_[1]) * static_cast<std::size_t>(n_[2]);
  ck_ = wave_scaling_table(p, box, viscosity, modes_);
  rotation_constants_ = rotation_mode_constants(p, viscosity);
  dv_ = p.spacing[0] * p.spacing[1] * p.spacing[2];
  c3_ = std::pow(2.0 * std::numbers::pi * p.sigma * p.sigma, -1.5);
  fft_threads_ = fft_threads > 0 ? fft_threads : (ng_ >= (std::size_t{1} << 20) ? omp_get_max_threads() : 1);
  parallel_modes_ = modes_.modes >= kParallelWork;

  // Spreading's layout: x planes and components one cache line further apart than packed.
  // Packed, for grid sizes with n_y n_z a multiple of 1024 (n = 32, 64, 96, 128, 160, ...), every
  // x plane and component of a window line sits at the same address modulo 4 KiB: they compete
  // for one L1 set, and spreading ran 1.25-1.3x slower (n = 160, P = 7, 128000 particles). The
  // transform back writes the packed layout, which interpolation reads (padded, interpolation
  // ran 1.2-1.5x slower).
  const std::size_t pad = 64 / sizeof(Real);
  plane_ = static_cast<std::size_t>(n_[1]) * static_cast<std::size_t>(n_[2]) + pad;
  comp_dist_ = static_cast<std::size_t>(n_[0]) * plane_ + pad;
  grid_ = F::alloc_real(3 * comp_dist_);
  auto* spec = F::alloc_complex(3 * modes_.modes);
  spectrum_ = reinterpret_cast<Real*>(spec);
  if (grid_ == nullptr || spectrum_ == nullptr) {
    F::free(grid_);
    F::free(spectrum_);
    fail(ErrorCode::out_of_memory, "PseRpy", "could not allocate the FFT grids");
  }
  F::init_threads();
  {
    std::lock_guard<std::mutex> lock(planner_mutex());
    F::plan_with_nthreads(fft_threads_);
    const RealLayout spread_layout{{n_[0], n_[1], n_[2]},
                                   {static_cast<std::ptrdiff_t>(plane_), n_[2], 1},
                                   static_cast<std::ptrdiff_t>(comp_dist_)};
    const RealLayout packed_layout{{n_[0], n_[1], n_[2]},
                                   {static_cast<std::ptrdiff_t>(n_[1]) * n_[2], n_[2], 1},
                                   static_cast<std::ptrdiff_t>(ng_)};
    // FFTW_MEASURE overwrites grid_ and spectrum_ while it times: both are scratch set by apply().
    const unsigned flags = fft_measure ? FFTW_MEASURE : FFTW_ESTIMATE;
    plan_forward_ = F::r2c(spread_layout, 3, grid_, spec, flags);
    plan_backward_ = F::c2r(packed_layout, 3, spec, grid_, flags);
  }
  if (plan_forward_ == nullptr || plan_backward_ == nullptr) {
    release();  // the destructor does not run when the constructor throws
    fail(ErrorCode::numerical_failure, "PseRpy", "FFTW could not create the plans");
  }
}

template <class Real>
void WaveGrid<Real>::release() noexcept {
  using F = Fftw<Real>;
  std::lock_guard<std::mutex> lock(planner_mutex());
  if (plan_forward_) F::destroy(plan_forward_);
  if (plan_backward_) F::destroy(plan_backward_);
  F::free(grid_);
  F::free(spectrum_);
  F::free(rotation_grid_);
  F::free(rotation_spectrum_);
  plan_forward_ = plan_backward_ = nullptr;
  grid_ = spectrum_ = rotation_grid_ = rotation_spectrum_ = nullptr;
}

template <class Real>
WaveGrid<Real>::~WaveGrid() {
  release();
}

template <class Real>
void WaveGrid<Real>::set_positions(std::span<const double> x) {
  np_ = x.size() / 3;
  // Window starts (wrapped) and the offsets d0 = x_s - x of their first points in input order
  // first: they decide the tiles. The weights follow in tile order.
  std::vector<int> start(3 * np_);
  std::vector<double> offset(3 * np_);
  window_starts(x, start, offset);
  order_by_tile(start);
  weights_in_tile_order(start, offset);
}

template <class Real>
void WaveGrid<Real>::window_starts(std::span<const double> x, std::vector<int>& start,
                                   std::vector<double>& offset) const {
  const auto np = static_cast<std::int64_t>(np_);
#pragma omp parallel for schedule(static) if (np_ >= 4096)
  for (std::int64_t i = 0; i < np; ++i)
    for (std::size_t d = 0; d < 3; ++d) {
      const double xd = x[3 * i + d];
      const long s = window_start(xd, p_.spacing[d], P_[d]);
      offset[3 * i + d] = static_cast<double>(s) * p_.spacing[d] - xd;
      start[3 * i + d] = wrap_index(s, n_[d]);
    }
}

template <class Real>
void WaveGrid<Real>::order_by_tile(const std::vector<int>& start) {
  const auto np = static_cast<std::int64_t>(np_);
  // Tiles of B_d >= P_d - 1 grid points in x and y (by window start): a tile's
  // particles write only into itself and the next tile, so tiles of one colour
  // (class per axis, tile_class) never touch the same grid point.
  std::array<int, 2> nb{};
  for (int d = 0; d < 2; ++d) nb[d] = std::max(1, n_[d] / std::max(P_[d] - 1, 1));
  const auto tile_of = [&](std::size_t i) {
    const int bx = std::min(start[3 * i] / std::max(P_[0] - 1, 1), nb[0] - 1);
    const int by = std::min(start[3 * i + 1] / std::max(P_[1] - 1, 1), nb[1] - 1);
    return bx * nb[1] + by;
  };
  const std::size_t ntiles = static_cast<std::size_t>(nb[0]) * static_cast<std::size_t>(nb[1]);
  // Particles by tile, within a tile by window start in z, then in input order (consecutive
  // particles then touch overlapping stretches of the same grid lines, which stay in cache and
  // stream in memory order): two stable counting sorts, by z start and then by tile.
  std::vector<std::size_t> by_z(np_);
  {
    std::vector<std::size_t> z_begin(static_cast<std::size_t>(n_[2]) + 1, 0);
    for (std::size_t i = 0; i < np_; ++i) ++z_begin[static_cast<std::size_t>(start[3 * i + 2]) + 1];
    for (std::size_t z = 0; z + 1 < z_begin.size(); ++z) z_begin[z + 1] += z_begin[z];
    for (std::size_t i = 0; i < np_; ++i) by_z[z_begin[static_cast<std::size_t>(start[3 * i + 2])]++] = i;
  }
  tile_begin_.assign(ntiles + 1, 0);
  std::vector<int> tile(np_);
#pragma omp parallel for schedule(static) if (np_ >= 16384)
  for (std::int64_t i = 0; i < np; ++i) tile[static_cast<std::size_t>(i)] = tile_of(static_cast<std::size_t>(i));
  for (std::size_t i = 0; i < np_; ++i) ++tile_begin_[static_cast<std::size_t>(tile[i]) + 1];
  for (std::size_t t = 0; t < ntiles; ++t) tile_begin_[t + 1] += tile_begin_[t];
  order_.resize(np_);
  std::vector<std::size_t> fill(tile_begin_.begin(), tile_begin_.end() - 1);
  for (const std::size_t i : by_z) order_[fill[static_cast<std::size_t>(tile[i])]++] = i;
  for (auto& c : tiles_of_colour_) c.clear();
  for (int bx = 0; bx < nb[0]; ++bx)
    for (int by = 0; by < nb[1]; ++by) {
      const int t = bx * nb[1] + by;
      if (tile_begin_[static_cast<std::size_t>(t)] == tile_begin_[static_cast<std::size_t>(t) + 1]) continue;
      tiles_of_colour_[static_cast<std::size_t>(3 * tile_class(bx, nb[0]) + tile_class(by, nb[1]))].push_back(t);
    }
}

template <class Real>
void WaveGrid<Real>::weights_in_tile_order(const std::vector<int>& start, const std::vector<double>& offset) {
  const int pw = P_[0] + P_[1] + P_[2];
  const auto np = static_cast<std::int64_t>(np_);
  // The Gaussian window's 1D weights (docs/theory/pse.md) and starts, in tile order.
  start_.resize(3 * np_);
  weights_.resize(static_cast<std::size_t>(pw) * np_);
  const double inv_2s2 = 1.0 / (2.0 * p_.sigma * p_.sigma);
  std::array<std::vector<double>, 3> tail;  // exp(-l^2 h_d^2 / (2 sigma^2)), l < P_d
  for (std::size_t d = 0; d < 3; ++d) tail[d] = window_tail(p_.spacing[d], P_[d], inv_2s2);
#pragma omp parallel for schedule(static) if (np_ >= 1024)
  for (std::int64_t q = 0; q < np; ++q) {
    const std::size_t i = order_[static_cast<std::size_t>(q)];
    if (static_cast<std::size_t>(q) + kPrefetchAhead < np_) {  // read at random: fetch ahead
      const std::size_t ahead = 3 * order_[static_cast<std::size_t>(q) + kPrefetchAhead];
      __builtin_prefetch(&offset[ahead]);
      __builtin_prefetch(&start[ahead]);
    }
    double* w = &weights_[static_cast<std::size_t>(q) * pw];
    for (std::size_t d = 0; d < 3; ++d) {
      start_[3 * q + d] = start[3 * i + d];
      window_weights_from_offset(offset[3 * i + d], p_.spacing[d], P_[d], inv_2s2, tail[d].data(), w);
      w += P_[d];
    }
  }
}

template <class Real>
void WaveGrid<Real>::window_lines(std::size_t q, std::size_t* xline, std::size_t* yline, std::size_t plane) const {
  // Offsets of the grid lines (x, y) of slot q's window: line = xline[a] + yline[b],
  // wrapped without a division per point.
  const auto nz = static_cast<std::size_t>(n_[2]);
  int ix = start_[3 * q];
  for (int a = 0; a < P_[0]; ++a, ++ix) {
    if (ix == n_[0]) ix = 0;
    xline[a] = static_cast<std::size_t>(ix) * plane;
  }
  int iy = start_[3 * q + 1];
  for (int b = 0; b < P_[1]; ++b, ++iy) {
    if (iy == n_[1]) iy = 0;
    yline[b] = static_cast<std::size_t>(iy) * nz;
  }
}

template <class Real>
void WaveGrid<Real>::spread(const double* forces, Real* grid) {
  // f_n = sum_j F_j g(x_n - x_j)  (spreading, D in [PSE] eq. 19), race-free and in a fixed
  // order: the result does not depend on the number of threads.
  const int pw = P_[0] + P_[1] + P_[2];
  Real* g0 = grid;
  Real* g1 = grid + comp_dist_;
  Real* g2 = grid + 2 * comp_dist_;
  const auto total = static_cast<std::int64_t>(3 * comp_dist_);
  const std::size_t p3 = static_cast<std::size_t>(P_[0]) * P_[1] * P_[2];
  const bool par = np_ * p3 >= kParallelWork || ng_ >= 4 * kParallelWork;
  const WindowKernels kernels = window_kernels(P_[2]);
#pragma omp parallel if (par)
  {
#pragma omp for schedule(static)
    for (std::int64_t q = 0; q < total; ++q) grid[q] = Real(0);
    std::vector<Real> wf(3 * static_cast<std::size_t>(P_[2]));  // wz * f, per component
    std::vector<std::size_t> xline(static_cast<std::size_t>(P_[0])), yline(static_cast<std::size_t>(P_[1]));
    for (const auto& colour : tiles_of_colour_) {
      const auto nt = static_cast<std::int64_t>(colour.size());
#pragma omp for schedule(dynamic, 1)
      for (std::int64_t t = 0; t < nt; ++t) {
        const auto tile = static_cast<std::size_t>(colour[static_cast<std::size_t>(t)]);
        const std::size_t end = tile_begin_[tile + 1];
        for (std::size_t q = tile_begin_[tile]; q < end; ++q) {
          const std::size_t i = order_[q];
          // The forces are read in tile order, i.e. at random: fetch a few particles ahead.
          if (q + kPrefetchAhead < end) __builtin_prefetch(&forces[3 * order_[q + kPrefetchAhead]]);
          const double* wx = &weights_[q * static_cast<std::size_t>(pw)];
          const double* wy = wx + P_[0];
          const double* wz = wy + P_[1];
          const double fc[3] = {c3_ * forces[3 * i], c3_ * forces[3 * i + 1], c3_ * forces[3 * i + 2]};
          const ZRuns z = z_runs(start_[3 * q + 2], P_[2], n_[2]);
          window_lines(q, xline.data(), yline.data(), plane_);
          if (kernels == WindowKernels::avx512) {
            spread_window_avx512(g0, g1, g2, xline.data(), yline.data(), P_[0], P_[1], {z.z0, z.len0, P_[2]}, wx, wy,
                                 wz, fc);
          } else if (kernels == WindowKernels::avx2) {
            spread_window_avx2(g0, g1, g2, xline.data(), yline.data(), P_[0], P_[1], {z.z0, z.len0, P_[2]}, wx, wy, wz,
                               fc);
          } else {
            for (int l = 0; l < P_[2]; ++l)
              for (int c = 0; c < 3; ++c)
                wf[static_cast<std::size_t>(c * P_[2] + l)] = static_cast<Real>(wz[l] * fc[c]);
            for (int a = 0; a < P_[0]; ++a)
              for (int b = 0; b < P_[1]; ++b)
                spread_line(g0, g1, g2, xline[static_cast<std::size_t>(a)] + yline[static_cast<std::size_t>(b)], z,
                            P_[2], static_cast<Real>(wx[a] * wy[b]), wf.data());
          }
        }
      }  // implicit barrier: colours run one after another
    }
  }
}

template <class Real>
void WaveGrid<Real>::interpolate(const Real* grid, double* out, bool accumulate) const {
  // U_j = dV sum_n g(x_n - x_j) u_n  (interpolation, D^-1 in [PSE] eq. 19).
  const int pw = P_[0] + P_[1] + P_[2];
  const Real* g0 = grid;
  const Real* g1 = grid + ng_;
  const Real* g2 = grid + 2 * ng_;
  const double scale = c3_ * dv_;
  const auto np = static_cast<std::int64_t>(np_);
  const bool par = np_ * static_cast<std::size_t>(P_[0]) * P_[1] * P_[2] >= kParallelWork;
  const WindowKernels kernels = window_kernels(P_[2]);
#pragma omp parallel if (par)
  {
    std::vector<std::size_t> xline(static_cast<std::size_t>(P_[0])), yline(static_cast<std::size_t>(P_[1]));
    // Particles in tile order (order_, as in spread): neighbours in the loop read neighbouring
    // grid points, so the gathers hit cache instead of the whole grid at random.
#pragma omp for schedule(static)
    for (std::int64_t qq = 0; qq < np; ++qq) {
      const auto q = static_cast<std::size_t>(qq);
      const std::size_t i = order_[q];
      // The outputs are written in tile order, i.e. at random: fetch a few particles ahead.
      if (q + kPrefetchAhead < np_) __builtin_prefetch(&out[3 * order_[q + kPrefetchAhead]], 1);
      const double* wx = &weights_[q * static_cast<std::size_t>(pw)];
      const double* wy = wx + P_[0];
      const double* wz = wy + P_[1];
      const ZRuns z = z_runs(start_[3 * q + 2], P_[2], n_[2]);
      window_lines(q, xline.data(), yline.data(), static_cast<std::size_t>(n_[1]) * static_cast<std::size_t>(n_[2]));
      double u[3] = {0.0, 0.0, 0.0};
      if (kernels == WindowKernels::avx512) {
        gather_window_avx512(g0, g1, g2, xline.data(), yline.data(), P_[0], P_[1], {z.z0, z.len0, P_[2]}, wx, wy, wz,
                             u);
      } else if (kernels == WindowKernels::avx2) {
        gather_window_avx2(g0, g1, g2, xline.data(), yline.data(), P_[0], P_[1], {z.z0, z.len0, P_[2]}, wx, wy, wz, u);
      } else {
        for (int a = 0; a < P_[0]; ++a) {
          for (int b = 0; b < P_[1]; ++b) {
            double sz[3] = {0.0, 0.0, 0.0};
            gather_line(g0, g1, g2, xline[static_cast<std::size_t>(a)] + yline[static_cast<std::size_t>(b)], z, P_[2],
                        wz, sz);
            const double wxy = wx[a] * wy[b];
            for (int c = 0; c < 3; ++c) u[c] += wxy * sz[c];
          }
        }
      }
      for (int c = 0; c < 3; ++c) {
        double& o = out[3 * i + static_cast<std::size_t>(c)];
        o = accumulate ? o + scale * u[c] : scale * u[c];
      }
    }
  }
}

template <class Real>
void WaveGrid<Real>::apply(const double* forces, double* out, bool accumulate, const NoiseKey* noise,
                           double noise_scale, StageTimes* times) {
  StageLaps lap(times);
  const bool deterministic = forces != nullptr;
  if (deterministic) {
    spread(forces, grid_);
    lap("spread");
    Fftw<Real>::execute_r2c(plan_forward_, grid_, reinterpret_cast<Complex*>(spectrum_));
    lap("fft_forward");
  }
  const bool with_noise = noise != nullptr && noise_scale != 0.0;
  const std::uint64_t seed = with_noise ? noise->seed : 0;
  const std::uint64_t step = with_noise ? noise->step : 0;
  const double factor = noise_scale / std::sqrt(dv_);
  // Lines of constant (ix, iy): no index decoding per mode. The noise of a group of lines is
  // drawn at once by the vectorized fill_normal6 (the same values as the GPU's per-mode
  // normal6 / normal6f): groups of at least kNoiseBatch modes keep its vectors full (a line of
  // 33 modes alone would leave a third of the lanes idle). Single-precision grids draw the
  // noise in single precision (normal6f), as their spectrum is float.
  constexpr int kNoiseBatch = 256;
  const int ny = modes_.n[1];
  const int nzh = modes_.nzh;
  const auto lines = static_cast<std::int64_t>(modes_.n[0]) * ny;
  const std::int64_t group = with_noise ? std::max<std::int64_t>(1, (kNoiseBatch + nzh - 1) / nzh) : 1;
  const std::int64_t groups = (lines + group - 1) / group;
#pragma omp parallel if (parallel_modes_)
  {
    const std::size_t batch = with_noise ? static_cast<std::size_t>(group * nzh) : 0;
    std::vector<std::uint64_t> rep(batch);
    std::vector<Real> sign(batch);  // +1: the pair's representative, -1: the conjugate
    std::vector<Real> z(6 * batch);
#pragma omp for schedule(static)
    for (std::int64_t gr = 0; gr < groups; ++gr) {
      const std::int64_t first = gr * group;
      const std::int64_t last = std::min(lines, first + group);
      if (with_noise) {
        std::size_t q = 0;
        for (std::int64_t line = first; line < last; ++line, q += static_cast<std::size_t>(nzh)) {
          line_noise_keys(modes_, static_cast<int>(line / ny), static_cast<int>(line % ny), rep.data() + q,
                          sign.data() + q);
        }
        // Planar values: value c of the group's mode q at z[c * group_modes + q] (scale_line).
        random_detail::fill_normal6_planar(std::span<const std::uint64_t>(rep.data(), q), seed, step, kStreamWave,
                                           std::span<Real>(z.data(), 6 * q));
      }
      ModeLine<Real> ml;
      ml.ck = ck_.data();
      ml.spec = spectrum_;
      ml.deterministic = deterministic;
      ml.z_stride = static_cast<std::size_t>(last - first) * static_cast<std::size_t>(nzh);
      ml.noise_factor = factor;
      for (std::int64_t line = first; line < last; ++line) {
        ml.ix = static_cast<int>(line / ny);
        ml.iy = static_cast<int>(line % ny);
        if (with_noise) {
          const auto q0 = static_cast<std::size_t>(line - first) * static_cast<std::size_t>(nzh);
          ml.z = z.data() + q0;
          ml.sign = sign.data() + q0;
        }
        scale_line(modes_, ml);
      }
    }
  }
  lap("scale");
  Fftw<Real>::execute_c2r(plan_backward_, reinterpret_cast<Complex*>(spectrum_), grid_);
  lap("fft_backward");
  interpolate(grid_, out, accumulate);
  lap("interpolate");
}

template <class Real>
void WaveGrid<Real>::allocate_rotation_buffers() {
  if (rotation_grid_ != nullptr) return;
  using F = Fftw<Real>;
  rotation_grid_ = F::alloc_real(3 * comp_dist_);
  rotation_spectrum_ = reinterpret_cast<Real*>(F::alloc_complex(3 * modes_.modes));
  if (rotation_grid_ == nullptr || rotation_spectrum_ == nullptr) {
    F::free(rotation_grid_);
    F::free(rotation_spectrum_);
    rotation_grid_ = rotation_spectrum_ = nullptr;
    fail(ErrorCode::out_of_memory, "PseRpy", "could not allocate the FFT grids of the rotational wave space");
  }
  tabulate_rotation_factors();
}

template <class Real>
void WaveGrid<Real>::tabulate_rotation_factors() {
  const int ny = modes_.n[1];
  const int nzh = modes_.nzh;
  const auto lines = static_cast<std::int64_t>(modes_.n[0]) * ny;
  rotation_factors_.assign(static_cast<std::size_t>(lines) * static_cast<std::size_t>(nzh), RotationModeFactors{});
#pragma omp parallel for schedule(static) if (parallel_modes_)
  for (std::int64_t line = 0; line < lines; ++line) {
    const int ix = static_cast<int>(line / ny);
    const int iy = static_cast<int>(line % ny);
    for (int iz = 0; iz < nzh; ++iz)
      rotation_factors_[static_cast<std::size_t>(line) * static_cast<std::size_t>(nzh) + static_cast<std::size_t>(iz)] =
          rotation_mode_factors(ix, iy, iz, modes_, rotation_constants_);
  }
}

template <class Real>
void WaveGrid<Real>::scale_rotation_modes(bool deterministic, const NoiseKey* noise, double noise_factor) {
  // One (ix, iy) line per iteration, every mode on its own: the result does not depend on the
  // thread count. The noise of a mode is the translational sampler's (normal6 / normal6f of its
  // pair's representative, as scale_mode draws it).
  const int ny = modes_.n[1];
  const int nzh = modes_.nzh;
  const auto lines = static_cast<std::int64_t>(modes_.n[0]) * ny;
#pragma omp parallel for schedule(static) if (parallel_modes_)
  for (std::int64_t line = 0; line < lines; ++line) {
    const int ix = static_cast<int>(line / ny);
    const int iy = static_cast<int>(line % ny);
    for (int iz = 0; iz < nzh; ++iz) {
      const std::size_t idx =
          static_cast<std::size_t>(line) * static_cast<std::size_t>(nzh) + static_cast<std::size_t>(iz);
      Real z[6];
      bool representative = true;
      if (noise != nullptr) {
        std::uint64_t lin, rep;
        mode_pair(ix, iy, iz, modes_, lin, rep);
        if constexpr (sizeof(Real) == sizeof(float)) {
          normal6f(noise->seed, noise->step, kStreamWave, rep, z);
        } else {
          normal6(noise->seed, noise->step, kStreamWave, rep, z);
        }
        representative = lin == rep;
      }
      scale_rotation_mode(ix, iy, iz, idx, modes_, ck_.data(), rotation_factors_[idx], spectrum_, rotation_spectrum_,
                          deterministic, noise != nullptr ? z : static_cast<const Real*>(nullptr), representative,
                          noise_factor);
    }
  }
}

template <class Real>
void WaveGrid<Real>::apply_rotation(const double* forces, const double* torques, double* velocities, double* angular,
                                    bool accumulate, const NoiseKey* noise, double noise_scale, StageTimes* times) {
  allocate_rotation_buffers();
  StageLaps lap(times);
  const bool deterministic = forces != nullptr;
  if (deterministic) {
    spread(forces, grid_);
    spread(torques, rotation_grid_);
    lap("spread");
    Fftw<Real>::execute_r2c(plan_forward_, grid_, reinterpret_cast<Complex*>(spectrum_));
    Fftw<Real>::execute_r2c(plan_forward_, rotation_grid_, reinterpret_cast<Complex*>(rotation_spectrum_));
    lap("fft_forward");
  }
  const bool with_noise = noise != nullptr && noise_scale != 0.0;
  scale_rotation_modes(deterministic, with_noise ? noise : nullptr, noise_scale / std::sqrt(dv_));
  lap("scale");
  Fftw<Real>::execute_c2r(plan_backward_, reinterpret_cast<Complex*>(spectrum_), grid_);
  Fftw<Real>::execute_c2r(plan_backward_, reinterpret_cast<Complex*>(rotation_spectrum_), rotation_grid_);
  lap("fft_backward");
  interpolate(grid_, velocities, accumulate);
  interpolate(rotation_grid_, angular, accumulate);
  lap("interpolate");
}

std::unique_ptr<WaveSpace> make_wave_space(const PseParameters& p, const std::array<double, 3>& box, double viscosity,
                                           int fft_threads, bool fft_measure) {
  if (p.wave_single) return std::make_unique<WaveGrid<float>>(p, box, viscosity, fft_threads, fft_measure);
  return std::make_unique<WaveGrid<double>>(p, box, viscosity, fft_threads, fft_measure);
}

}  // namespace rpyfmm::rpy::pse::detail
