// rpyfmm — PseRpyCuda: the host orchestration of the PSE stages on a CUDA device
// (docs/theory/pse.md; kernels in cuda_real_space.cuh, cuda_wave_space.cuh, cuda_window.cuh and
// cuda_krylov.cuh).
// The particles live on the device in slot order (the CPU cell list's order, so that neighbours
// in space are neighbours in memory: the spreading atomics and the neighbour reads stay in L2);
// a product uploads its forces once and downloads its velocities once, gathered and scattered
// between input and slot order on the device.
//   spread:      by bins of grid points in shared memory, or one thread block per particle,
//                summed in 64-bit fixed point so that every product is the same bit for bit
//                (cuda_window.cuh);
//   FFT:         cuFFT D2Z / Z2D (R2C / C2R for single-precision grids, PseParameters::wave_single,
//                as the CPU chooses them), batch of 3 components (same layout as FFTW);
//   scale+noise: one thread per half-spectrum mode, the same scale_mode() as the CPU;
//   interpolate: the same two forms, added to the real-space part;
//   real space:  one thread per particle over its neighbour list (built on the host with the
//                CPU cell list), table lookup, no atomics;
//   Lanczos:     the real-space square root of the split sampler iterates on device vectors
//                (sqrt_detail::lanczos_sqrt_in_space, the host's iteration and stopping test;
//                deterministic block sums for the inner products).
// Parameters, tables and neighbour lists come from the CPU code, so both back ends use
// identical inputs.
#include <cuda_runtime.h>
#include <cufft.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdlib>
#include <cub/device/device_radix_sort.cuh>
#include <memory>
#include <numbers>
#include <string>
#include <type_traits>
#include <vector>

#include "../sqrt/krylov_space.hpp"
#include "../wrap_into_box.hpp"
#include "cuda_device.cuh"
#include "cuda_krylov.cuh"
#include "cuda_real_space.cuh"
#include "cuda_rotation.cuh"
#include "cuda_wave_space.cuh"
#include "cuda_window.cuh"
#include "host_copy.hpp"
#include "kernels_common.hpp"
#include "real_space_sqrt.hpp"
#include "real_space_sum.hpp"
#include "rotation_real_space_sum.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "wave_space.hpp"

namespace rpyfmm::rpy::pse {

// The device helpers and kernels (cuda_*.cuh) are this file's own: each header is included here only.
using namespace cuda_detail;
using cuda_window::BinGrid;
using cuda_window::kMaxSupport;
using cuda_window::WindowParams;

namespace {
/// out = x (3N, input order) with every coordinate wrapped into [0, L) as
/// MobilityOperator::set_positions wraps the host's (detail::wrap_into_box, bit for bit).
__global__ void wrap_positions_kernel(int n, const double* x, double lx, double ly, double lz, double* out) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  if (i >= n) return;
  const double box[3] = {lx, ly, lz};
  for (int d = 0; d < 3; ++d) out[3 * i + d] = rpy::detail::wrap_into_box(x[3 * i + d], box[d]);
}
}  // namespace

struct PseRpyCuda::Impl {
  PseOptions options;
  PseCudaOptions cuda_options;
  // Device cell list (PseCudaOptions::device_cell_list): active for the current positions,
  // its grid, the sorted cell keys by slot and the slot ranges per cell; the radix sort's
  // input keys and values and its work area.
  bool cells_active = false;
  CellGrid cell_grid{};
  DeviceArray<unsigned> keys_in, keys_sorted;
  DeviceArray<int> values_in, cell_begin, cell_end;
  DeviceArray<unsigned char> sort_work;
  // Spreading and interpolation by bins (cuda_window.cuh) for the current positions: the bin
  // edge (0: one block per particle), the bin grid, the slots in bin order and each bin's range
  // (with the radix sort's input keys and values).
  int bin_edge = 0;
  BinGrid bin_grid{};
  DeviceArray<unsigned> bin_keys_in, bin_keys_sorted;
  DeviceArray<int> bin_values, bin_slots, bin_begin, bin_end;
  int multiprocessors = 1;
  std::size_t max_shared = 48 * 1024;  // dynamic shared memory per block (opt-in maximum)
  PinnedBuffer pinned;                 // PseCudaOptions::pinned_transfers
  PseParameters params;
  bool planned = false;
  std::size_t planned_n = 0;
  std::unique_ptr<detail::RealSpaceSum> real;  // host: table + neighbour lists
  detail::ModeGeometry modes{};
  WindowParams window{};
  double dv = 0.0;
  std::array<double, 3> box{};
  cufftHandle plan_fwd = 0, plan_bwd = 0;
  bool have_fwd = false, have_bwd = false;
  // Device arrays; particle vectors (3 per particle) in slot order unless named otherwise.
  DeviceArray<double> ck, table;
  // Wave grids and their half spectra: double, or float where params.wave_single.
  DeviceArray<unsigned char> grid, spectrum;
  // The fixed-point sums of spreading on float grids (3 ng; double grids sum in place) and the
  // bits of max |f| of the product being spread (cuda_window.cuh).
  DeviceArray<unsigned long long> accumulator, max_force_bits;
  DeviceArray<double> x;                // positions
  DeviceArray<double> xin;              // set_positions_device: the positions in input order, wrapped
  DeviceArray<double> io;               // one vector in input order: the transfers
  DeviceArray<double> f, u, z;          // forces, velocities, the real-space noise
  DeviceArray<double> noise;            // apply_with_noise: M_r^{1/2} z1
  DeviceArray<unsigned char> fft_work;  // one cuFFT work area, shared by the two plans (run in turn)
  DeviceArray<unsigned long long> begin;
  DeviceArray<int> list, order;
  DeviceKrylovSpace krylov;
  // Rotation (products with torques, the 6N split sampler), set up by the first such call of a
  // plan: the rotational real-space table (host, and its nodes on the device), the per-mode
  // factors, the second grid and spectrum (torques -> angular velocities), torques and angular
  // velocities in slot order, the sampler's 6N vectors.
  std::unique_ptr<detail::RotationRealSpaceSum> rotation;
  DeviceArray<double> rotation_table;
  DeviceArray<detail::RotationModeFactors> rotation_factors;
  DeviceArray<unsigned char> rotation_grid, rotation_spectrum;
  DeviceArray<double> torque, angular, z6, w6;
  double mu = 1.0;  // the plan's viscosity
  StageEvents events;
  StageTimes times;
  std::size_t np = 0;

  ~Impl() { destroy_plans(); }
  void destroy_plans() {
    if (have_fwd) cufftDestroy(plan_fwd);
    if (have_bwd) cufftDestroy(plan_bwd);
    have_fwd = have_bwd = false;
  }

  [[nodiscard]] std::size_t n3() const { return 3 * np; }

  /// dst (slot order) = src (input order), both on the device.
  void gather(const double* src, DeviceArray<double>& dst) {
    dst.resize(n3());
    gather_into(src, dst.get());
  }
  /// dst[0 .. 3N) (slot order) = src (input order), both on the device.
  void gather_into(const double* src, double* dst) {
    gather3_kernel<<<blocks_for(np, kThreads), kThreads>>>(static_cast<int>(np), order.get(), src, dst);
    check_kernel("gather kernel");
  }
  /// dst (input order) = src (slot order), both on the device.
  void scatter(const DeviceArray<double>& src, double* dst) { scatter(src.get(), dst); }
  void scatter(const double* src, double* dst) {
    scatter3_kernel<<<blocks_for(np, kThreads), kThreads>>>(static_cast<int>(np), order.get(), src, dst);
    check_kernel("scatter kernel");
  }

  /// io = host (3N doubles, input order), through the page-locked buffer where
  /// PseCudaOptions::pinned_transfers.
  void upload_input(const double* host) {
    if (cuda_options.pinned_transfers) {
      double* staging = pinned.reserve(n3());
      detail::parallel_copy(staging, host, n3());
      io.upload(staging, n3());
    } else {
      io.upload(host, n3());
    }
  }

  /// dst (slot order, device) = host (input order).
  void upload_to_slots(const double* host, DeviceArray<double>& dst) {
    dst.resize(n3());
    upload_to_slots(host, dst.get());
  }
  /// dst[0 .. 3N) (slot order, device) = host (input order).
  void upload_to_slots(const double* host, double* dst) {
    events.begin("transfer");
    upload_input(host);
    gather_into(io.get(), dst);
    events.end();
  }

  /// host (input order) = src (slot order, device); then the stage times of the work so far.
  void download_from_slots(const DeviceArray<double>& src, double* host) { download_from_slots(src.get(), host); }
  /// host (input order) = src[0 .. 3N) (slot order, device); then the stage times of the work so far.
  void download_from_slots(const double* src, double* host) {
    events.begin("transfer");
    io.resize(n3());
    scatter(src, io.get());
    if (cuda_options.pinned_transfers) {
      double* staging = pinned.reserve(n3());
      io.download(staging, n3());
      detail::parallel_copy(host, staging, n3());
    } else {
      io.download(host, n3());
    }
    events.end();
    events.collect(times);
  }

  /// dst (slot order) = the real-space noise z1 keyed by (seed, step): fill_normal's values in
  /// input order, drawn on the device.
  void draw_real_noise(std::uint64_t seed, std::uint64_t step, DeviceArray<double>& dst) {
    dst.resize(n3());
    normal_slots_kernel<<<blocks_for(np, kThreads), kThreads>>>(static_cast<int>(np), order.get(), seed, step,
                                                                detail::kStreamReal, dst.get());
    check_kernel("noise kernel");
  }

  /// out (slot order) = M f for f in slot order on the device.
  void product(const DeviceArray<double>& f_dev, DeviceArray<double>& out) {
    out.resize(n3());
    real_space(f_dev.get(), out.get());
    wave(f_dev.get(), out.get(), true, nullptr, 0.0);
  }

  /// out (slot order) = M_r^{1/2} z1 + M_w^{1/2} z2 keyed by (seed, step).
  SqrtReport split_sample(std::uint64_t seed, std::uint64_t step, DeviceArray<double>& out) {
    draw_real_noise(seed, step, z);
    SqrtReport rep = real_sqrt(z, out);
    const detail::NoiseKey key{seed, step};
    wave(nullptr, out.get(), true, &key, 1.0);
    rep.method = SqrtMethod::split;
    rep.operator_applications += 1;
    return rep;
  }

  /// keys_out / values_out (np entries) = keys_in / values_in sorted by key (the low `bits` bits).
  void radix_sort(DeviceArray<unsigned>& keys_in, DeviceArray<unsigned>& keys_out, DeviceArray<int>& values_in,
                  DeviceArray<int>& values_out, int bits) {
    std::size_t work_bytes = 0;
    check(cub::DeviceRadixSort::SortPairs(nullptr, work_bytes, keys_in.get(), keys_out.get(), values_in.get(),
                                          values_out.get(), static_cast<int>(np), 0, bits),
          "radix sort (size)");
    work_bytes = std::max<std::size_t>(work_bytes, 1);  // a null work area would mean "size query" again
    if (sort_work.size() < work_bytes) sort_work.resize(work_bytes);
    check(cub::DeviceRadixSort::SortPairs(sort_work.get(), work_bytes, keys_in.get(), keys_out.get(), values_in.get(),
                                          values_out.get(), static_cast<int>(np), 0, bits),
          "radix sort");
  }

  /// range_begin[k] / range_end[k] (k < count): the slot range of key k in sorted_keys (empty
  /// for absent keys).
  void key_ranges(const DeviceArray<unsigned>& sorted_keys, std::size_t count, DeviceArray<int>& range_begin,
                  DeviceArray<int>& range_end) {
    range_begin.resize(count);
    range_end.resize(count);
    check(cudaMemset(range_begin.get(), 0, count * sizeof(int)), "cudaMemset");
    check(cudaMemset(range_end.get(), 0, count * sizeof(int)), "cudaMemset");
    cuda_window::key_range_kernel<<<blocks_for(np, kThreads), kThreads>>>(static_cast<int>(np), sorted_keys.get(),
                                                                          range_begin.get(), range_end.get());
    check_kernel("key range kernel");
  }

  /// The bins of spreading and interpolation for the positions x (slot order, on the device):
  /// the edge from PseCudaOptions::window_bin, the slots sorted by the bin of their window's
  /// first point, each bin's slot range.
  void build_bins() {
    bin_edge = cuda_window::choose_bin_edge(window, np, cuda_options.window_bin, multiprocessors, max_shared);
    if (cuda_options.window_bin > 0 && bin_edge == 0) {
      fail(ErrorCode::invalid_argument, kWhere,
           "window_bin " + std::to_string(cuda_options.window_bin) +
               " needs more shared memory per block than the device's " + std::to_string(max_shared) +
               " bytes; use a smaller edge, 0 (automatic) or -1 (per particle)");
    }
    if (bin_edge == 0) return;
    bin_grid = cuda_window::make_bin_grid(window, bin_edge);
    const std::size_t bins = bin_grid.bins();
    bin_keys_in.resize(np);
    bin_keys_sorted.resize(np);
    bin_values.resize(np);
    bin_slots.resize(np);
    cuda_window::bin_key_kernel<<<blocks_for(np, kThreads), kThreads>>>(static_cast<int>(np), x.get(), window, bin_grid,
                                                                        bin_keys_in.get(), bin_values.get());
    check_kernel("bin key kernel");
    radix_sort(bin_keys_in, bin_keys_sorted, bin_values, bin_slots, key_bits(bins));
    key_ranges(bin_keys_sorted, bins, bin_begin, bin_end);
    const auto bytes = static_cast<int>(bin_grid.shared_bytes());
    check(cudaFuncSetAttribute(cuda_window::spread_bins_kernel, cudaFuncAttributeMaxDynamicSharedMemorySize, bytes),
          "shared memory of the bin kernels");
    if (params.wave_single) {
      allow_interpolation_shared_memory<float>(bytes);
    } else {
      allow_interpolation_shared_memory<double>(bytes);
    }
  }

  /// Lets the interpolation by bins on Real grids use `bytes` of dynamic shared memory (above
  /// 48 KiB needs the opt-in).
  template <class Real>
  static void allow_interpolation_shared_memory(int bytes) {
    check(cudaFuncSetAttribute(cuda_window::interpolate_bins_kernel<Real>, cudaFuncAttributeMaxDynamicSharedMemorySize,
                               bytes),
          "shared memory of the bin kernels");
  }

  /// The slot order and cell ranges of the device cell list for the positions at xin_dev (input
  /// order, wrapped into the box); false (nothing built) where a box side holds < 3 cells.
  bool build_device_cells(const double* xin_dev) {
    std::size_t total = 1;
    for (int d = 0; d < 3; ++d) {
      const int nc = static_cast<int>(box[d] / params.r_cut);  // cells of edge >= r_cut
      if (nc < 3) return false;
      cell_grid.nc[d] = nc;
      total *= static_cast<std::size_t>(nc);
    }
    // Sparse systems: no more cells than ~2 per particle (larger cells stay valid).
    const double limit = std::max(27.0, 2.0 * static_cast<double>(np));
    if (static_cast<double>(total) > limit) {
      const double shrink = std::cbrt(static_cast<double>(total) / limit);
      total = 1;
      for (int d = 0; d < 3; ++d) {
        cell_grid.nc[d] = std::max(3, static_cast<int>(cell_grid.nc[d] / shrink));
        total *= static_cast<std::size_t>(cell_grid.nc[d]);
      }
    }
    for (int d = 0; d < 3; ++d) cell_grid.inv_cell[d] = cell_grid.nc[d] / box[d];
    keys_in.resize(np);
    keys_sorted.resize(np);
    values_in.resize(np);
    order.resize(np);
    cell_key_kernel<<<blocks_for(np, kThreads), kThreads>>>(static_cast<int>(np), xin_dev, cell_grid, keys_in.get(),
                                                            values_in.get());
    check_kernel("cell key kernel");
    radix_sort(keys_in, keys_sorted, values_in, order, key_bits(total));
    key_ranges(keys_sorted, total, cell_begin, cell_end);
    return true;
  }

  /// out = M_r in (device vectors, slot order).
  void real_space(const double* in, double* out) {
    events.begin("real_space");
    if (cells_active) {
      const double rc = params.r_cut;
      real_space_cells_kernel<<<blocks_for(np, 128), 128>>>(
          static_cast<int>(np), x.get(), in, out, keys_sorted.get(), cell_begin.get(), cell_end.get(), cell_grid,
          rc * rc, table.get(), 1.0 / real->table().dr(), real->self(), real->mobility_unit(),
          make_double3(box[0], box[1], box[2]), make_double3(1.0 / box[0], 1.0 / box[1], 1.0 / box[2]));
      check_kernel("real-space kernel (cells)");
      events.end();
      return;
    }
    real_space_kernel<<<blocks_for(np, 128), 128>>>(static_cast<int>(np), x.get(), in, out, begin.get(), list.get(),
                                                    table.get(), 1.0 / real->table().dr(), real->self(),
                                                    real->mobility_unit(), make_double3(box[0], box[1], box[2]),
                                                    make_double3(1.0 / box[0], 1.0 / box[1], 1.0 / box[2]));
    check_kernel("real-space kernel");
    events.end();
  }

  /// out (+)= M_w f + noise_scale M_w^{1/2} z2(key) (device vectors, slot order); f null: the
  /// noise only.
  void wave(const double* f_dev, double* out, bool accumulate, const detail::NoiseKey* key, double noise_scale) {
    if (params.wave_single) {
      wave_in<float>(f_dev, out, accumulate, key, noise_scale);
    } else {
      wave_in<double>(f_dev, out, accumulate, key, noise_scale);
    }
  }

  /// grid_c = c3 sum_i w f_ic (device forces, slot order) in 64-bit fixed point
  /// (cuda_window.cuh): the integer sums do not depend on the order of the atomics, so a product
  /// is the same bit for bit on every call. Double grids accumulate in their own storage, float
  /// grids in `accumulator`.
  template <class Real>
  void spread(const double* f_dev, Real* g) {
    auto* acc = std::is_same_v<Real, double> ? reinterpret_cast<unsigned long long*>(g) : accumulator.get();
    check(cudaMemset(acc, 0, 3 * window.ng * sizeof(unsigned long long)), "cudaMemset");
    check(cudaMemset(max_force_bits.get(), 0, sizeof(unsigned long long)), "cudaMemset");
    cuda_window::max_abs_kernel<<<blocks_for(std::clamp<std::size_t>(n3(), 1, 256 * 1024), kThreads), kThreads>>>(
        n3(), f_dev, max_force_bits.get());
    check_kernel("max |f| kernel");
    const cuda_window::FixedPointBound bound{max_force_bits.get(), cuda_window::contributions_per_point(window, np)};
    if (bin_edge > 0) {
      cuda_window::spread_bins_kernel<<<static_cast<unsigned>(bin_grid.bins()), cuda_window::kBinThreads,
                                        bin_grid.shared_bytes()>>>(bin_slots.get(), bin_begin.get(), bin_end.get(),
                                                                   x.get(), f_dev, acc, window, bin_grid, bound);
    } else {
      cuda_window::spread_particles_kernel<<<static_cast<unsigned>(np), cuda_window::kParticleThreads>>>(
          static_cast<int>(np), x.get(), f_dev, acc, window, bound);
    }
    check_kernel("spread kernel");
    cuda_window::fixed_to_grid_kernel<Real>
        <<<blocks_for(std::min<std::size_t>(3 * window.ng, 1024 * 1024), kThreads), kThreads>>>(3 * window.ng, acc, g,
                                                                                                window, bound);
    check_kernel("fixed-point conversion kernel");
  }

  /// wave() on Real grids: cuFFT R2C / C2R for float, D2Z / Z2D for double.
  template <class Real>
  void wave_in(const double* f_dev, double* out, bool accumulate, const detail::NoiseKey* key, double noise_scale) {
    auto* g = reinterpret_cast<Real*>(grid.get());
    auto* spec = reinterpret_cast<Real*>(spectrum.get());
    const bool deterministic = f_dev != nullptr;
    if (deterministic) {
      events.begin("spread");
      spread(f_dev, g);
      events.end();
      events.begin("fft_forward");
      forward_fft(g, spec);
      events.end();
    }
    const bool with_noise = key != nullptr && noise_scale != 0.0;
    events.begin("scale");
    scale_kernel<Real><<<blocks_for(modes.modes, 256), 256>>>(modes, ck.get(), spec, deterministic, with_noise,
                                                              with_noise ? key->seed : 0, with_noise ? key->step : 0,
                                                              noise_scale / std::sqrt(dv));
    check_kernel("scale kernel");
    events.end();
    events.begin("fft_backward");
    backward_fft(spec, g);
    events.end();
    events.begin("interpolate");
    interpolate(g, out, accumulate);
    events.end();
  }

  /// w = M_r^{1/2} z by Lanczos on device vectors (slot order; the operator in slot order is
  /// P M_r P^T, whose square root is P M_r^{1/2} P^T).
  SqrtReport real_sqrt(const DeviceArray<double>& zin, DeviceArray<double>& w) {
    const auto t0 = std::chrono::steady_clock::now();
    w.resize(n3());
    krylov.set_size(n3());
    const SqrtReport rep = sqrt_detail::lanczos_sqrt_in_space(
        krylov, [this](const double* in, double* out) { real_space(in, out); }, zin.get(), w.get(),
        detail::real_space_sqrt_options(params.lanczos_tolerance));
    check(cudaDeviceSynchronize(), "Lanczos");
    times["lanczos"] += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return rep;
  }

  // ---- Rotation (docs/theory/pse.md Sec. 5; Fiore & Swan 2018) ----

  /// Frees the rotation state of the current plan (a new plan builds its own on first use).
  void release_rotation() {
    rotation.reset();
    rotation_table.resize(0);
    rotation_factors.resize(0);
    rotation_grid.resize(0);
    rotation_spectrum.resize(0);
  }

  /// The rotation state of the current plan: the CPU's rotational table (RotationRealSpaceSum's,
  /// the same nodes), its nodes on the device, the second grid and spectrum (refused, before any
  /// allocation, where they do not fit) and the per-mode factors.
  void prepare_rotation() {
    if (rotation) return;
    const auto t0 = std::chrono::steady_clock::now();
    auto sum = std::make_unique<detail::RotationRealSpaceSum>(params, box, mu);
    const PseRotationTable& tab = sum->table();
    const std::size_t real_bytes = params.wave_single ? sizeof(float) : sizeof(double);
    const std::size_t need =
        (3 * window.ng + 2 * 3 * modes.modes) * real_bytes + modes.modes * sizeof(detail::RotationModeFactors);
    std::size_t free_bytes = 0, total_bytes = 0;
    check(cudaMemGetInfo(&free_bytes, &total_bytes), "cudaMemGetInfo");
    require(need <= free_bytes, ErrorCode::out_of_memory, kWhere,
            "the rotational wave space needs " + std::to_string(need >> 20) + " MiB more on the device, " +
                std::to_string(free_bytes >> 20) + " MiB are free; raise the tolerance or lower xi");
    rotation_table.upload(tab.data(), 3 * (tab.size() + 1));
    rotation_grid.resize(3 * window.ng * real_bytes);
    rotation_spectrum.resize(2 * 3 * modes.modes * real_bytes);
    rotation_factors.resize(modes.modes);
    const detail::RotationModeConstants rc{params.radius, 1.0 / (4.0 * params.xi * params.xi), 1.0 - params.window_eta,
                                           1.0 / (mu * static_cast<double>(window.ng)), params.open_truncation};
    rotation_factors_kernel<<<blocks_for(modes.modes, 256), 256>>>(modes, rc, rotation_factors.get());
    check_kernel("rotation factors kernel");
    rotation = std::move(sum);
    times["plan"] += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  /// u += M_r^{UT} (s t), w = s (M_r^{WF} f + M_r^{WT} (s t)) (device vectors, slot order; s = 1 for
  /// a product, a for the sampler's S M_r S): detail::RotationRows.
  void rotation_real_space(const double* f_dev, const double* t_dev, double* u_dev, double* w_dev, double s) {
    events.begin("real_space");
    const PseRotationTable& tab = rotation->table();
    const detail::RotationRows rows{x.get(),
                                    f_dev,
                                    t_dev,
                                    u_dev,
                                    w_dev,
                                    {rotation_table.get(), tab.inv_dr(), tab.unit_c(), tab.unit_hk()},
                                    tab.self(),
                                    1.0 / mu,
                                    s,
                                    s,
                                    {box[0], box[1], box[2]},
                                    {1.0 / box[0], 1.0 / box[1], 1.0 / box[2]}};
    if (cells_active) {
      rotation_real_space_cells_kernel<<<blocks_for(np, 128), 128>>>(static_cast<int>(np), rows, keys_sorted.get(),
                                                                     cell_begin.get(), cell_end.get(), cell_grid,
                                                                     params.r_cut * params.r_cut);
    } else {
      rotation_real_space_kernel<<<blocks_for(np, 128), 128>>>(static_cast<int>(np), rows, begin.get(), list.get());
    }
    check_kernel("rotational real-space kernel");
    events.end();
  }

  /// [u; angular] = M [f; torque] (the members, device vectors in slot order).
  void product_rotation() {
    u.resize(n3());
    angular.resize(n3());
    real_space(f.get(), u.get());
    rotation_real_space(f.get(), torque.get(), u.get(), angular.get(), 1.0);
    wave_rotation(f.get(), torque.get(), u.get(), angular.get(), nullptr, 0.0);
  }

  /// u += M_w^{UF} f + M_w^{UT} t + noise_scale (M_w^{1/2} z2(key))_U, w likewise (device vectors,
  /// slot order); f and t null: the noise only (the translational field z2, rotation_modes.hpp).
  void wave_rotation(const double* f_dev, const double* t_dev, double* u_dev, double* w_dev,
                     const detail::NoiseKey* key, double noise_scale) {
    if (params.wave_single) {
      wave_rotation_in<float>(f_dev, t_dev, u_dev, w_dev, key, noise_scale);
    } else {
      wave_rotation_in<double>(f_dev, t_dev, u_dev, w_dev, key, noise_scale);
    }
  }

  /// grid -> spectrum (cuFFT R2C for float grids, D2Z for double).
  template <class Real>
  void forward_fft(Real* g, Real* spec) {
    if constexpr (std::is_same_v<Real, float>) {
      check_fft(cufftExecR2C(plan_fwd, g, reinterpret_cast<cufftComplex*>(spec)), "R2C");
    } else {
      check_fft(cufftExecD2Z(plan_fwd, g, reinterpret_cast<cufftDoubleComplex*>(spec)), "D2Z");
    }
    check_kernel("forward FFT");  // cuFFT faults are asynchronous: name them here, not at the next kernel
  }

  /// spectrum -> grid (cuFFT C2R for float grids, Z2D for double).
  template <class Real>
  void backward_fft(Real* spec, Real* g) {
    if constexpr (std::is_same_v<Real, float>) {
      check_fft(cufftExecC2R(plan_bwd, reinterpret_cast<cufftComplex*>(spec), g), "C2R");
    } else {
      check_fft(cufftExecZ2D(plan_bwd, reinterpret_cast<cufftDoubleComplex*>(spec), g), "Z2D");
    }
    check_kernel("backward FFT");
  }

  /// out (+)= the interpolation of grid g at the particles (slot order).
  template <class Real>
  void interpolate(const Real* g, double* out, bool accumulate) {
    if (bin_edge > 0) {
      cuda_window::interpolate_bins_kernel<Real>
          <<<static_cast<unsigned>(bin_grid.bins()), cuda_window::kBinThreads, bin_grid.shared_bytes()>>>(
              bin_slots.get(), bin_begin.get(), bin_end.get(), x.get(), g, out, window, bin_grid, dv, accumulate);
    } else {
      cuda_window::interpolate_particles_kernel<Real><<<static_cast<unsigned>(np), cuda_window::kParticleThreads>>>(
          static_cast<int>(np), x.get(), g, out, window, dv, accumulate);
    }
    check_kernel("interpolate kernel");
  }

  /// wave_rotation() on Real grids: the CPU's WaveGrid::apply_rotation, stage by stage.
  template <class Real>
  void wave_rotation_in(const double* f_dev, const double* t_dev, double* u_dev, double* w_dev,
                        const detail::NoiseKey* key, double noise_scale) {
    auto* g = reinterpret_cast<Real*>(grid.get());
    auto* spec = reinterpret_cast<Real*>(spectrum.get());
    auto* rg = reinterpret_cast<Real*>(rotation_grid.get());
    auto* rspec = reinterpret_cast<Real*>(rotation_spectrum.get());
    const bool deterministic = f_dev != nullptr;
    if (deterministic) {
      events.begin("spread");
      spread(f_dev, g);
      spread(t_dev, rg);
      events.end();
      events.begin("fft_forward");
      forward_fft(g, spec);
      forward_fft(rg, rspec);
      events.end();
    }
    const bool with_noise = key != nullptr && noise_scale != 0.0;
    events.begin("scale");
    scale_rotation_kernel<Real><<<blocks_for(modes.modes, 256), 256>>>(
        modes, ck.get(), rotation_factors.get(), spec, rspec, deterministic, with_noise, with_noise ? key->seed : 0,
        with_noise ? key->step : 0, noise_scale / std::sqrt(dv));
    check_kernel("rotation scale kernel");
    events.end();
    events.begin("fft_backward");
    backward_fft(spec, g);
    backward_fft(rspec, rg);
    events.end();
    events.begin("interpolate");
    interpolate(g, u_dev, true);
    interpolate(rg, w_dev, true);
    events.end();
  }

  /// [w_t; w_r] = S^-1 (S M_r S)^{1/2} z6 by Lanczos on device vectors (6N, slot order, translation
  /// then rotation; S = diag(I, a I)): PseRpy::do_apply_sqrt_rotation's real part. w6 holds the
  /// result, unscaled rotation included.
  SqrtReport real_sqrt_rotation(const DeviceArray<double>& zin, DeviceArray<double>& wout) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::size_t n3 = this->n3();
    const double a = params.radius;
    wout.resize(2 * n3);
    krylov.set_size(2 * n3);
    const SqrtReport rep = sqrt_detail::lanczos_sqrt_in_space(
        krylov,
        [this, n3, a](const double* in, double* out) {
          real_space(in, out);
          rotation_real_space(in, in + n3, out, out + n3, a);
        },
        zin.get(), wout.get(), detail::real_space_sqrt_options(params.lanczos_tolerance));
    scale_into_kernel<<<blocks_for(n3, kThreads), kThreads>>>(n3, 1.0 / a, wout.get() + n3, wout.get() + n3);
    check_kernel("scale kernel (rotation)");
    check(cudaDeviceSynchronize(), "Lanczos");
    times["lanczos"] += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return rep;
  }

  /// Parameters, tables, window, FFT plans and the wave grids for radius a, box L and n
  /// particles (PseOptions; the parameters as the CPU chooses them).
  void plan(double a, const std::array<double, 3>& L, std::size_t n, double viscosity) {
    const auto t0 = std::chrono::steady_clock::now();
    planned = false;
    destroy_plans();
    release_rotation();
    grid.resize(0);  // the old plan's big arrays do not count against the new one's memory check
    accumulator.resize(0);
    spectrum.resize(0);
    fft_work.resize(0);
    PseParameters p = choose_parameters(options, a, L, n);
    for (int d = 0; d < 3; ++d)
      require(p.support[d] <= kMaxSupport, ErrorCode::not_supported, kWhere,
              "Gaussian support of " + std::to_string(p.support[d]) + " points exceeds the device limit 64");
    real = std::make_unique<detail::RealSpaceSum>(p, L, viscosity, true, detail::PairCache::off, 0,
                                                  /*full_lists=*/true);  // as the kernels read them
    p.table_dr = real->table().dr();
    p.table_size = real->table().size();
    const std::vector<double> ck_host = detail::wave_scaling_table(p, L, viscosity, modes);
    ck.upload(ck_host.data(), ck_host.size());
    table.upload(real->table().data().data(), real->table().data().size());
    set_window(p);
    allocate_wave(p, make_fft_plans(p));
    params = p;
    box = L;
    mu = viscosity;
    planned = true;
    planned_n = n;
    times["plan"] += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  /// The Gaussian window on the grid of p.
  void set_window(const PseParameters& p) {
    for (int d = 0; d < 3; ++d) {
      window.n[d] = p.grid[d];
      window.P[d] = p.support[d];
      window.h[d] = p.spacing[d];
    }
    window.inv_2s2 = 1.0 / (2.0 * p.sigma * p.sigma);
    window.c3 = std::pow(2.0 * std::numbers::pi * p.sigma * p.sigma, -1.5);
    window.ng = static_cast<std::size_t>(p.grid[0]) * p.grid[1] * p.grid[2];
    dv = p.spacing[0] * p.spacing[1] * p.spacing[2];
  }

  /// The forward and backward plans; returns the bytes of the work area they share.
  std::size_t make_fft_plans(const PseParameters& p) {
    // Plans with 64-bit sizes (a batch of 3 grids may exceed 2^31 elements) and without their own
    // work areas: both run on the default stream one after the other, so they share one, and the
    // plans' sizes are known before anything large is allocated.
    long long dims[3] = {p.grid[0], p.grid[1], p.grid[2]};
    const auto ng = static_cast<long long>(window.ng);
    const auto nm = static_cast<long long>(modes.modes);
    std::size_t work_fwd = 0, work_bwd = 0;
    check_fft(cufftCreate(&plan_fwd), "cufftCreate");
    have_fwd = true;
    check_fft(cufftSetAutoAllocation(plan_fwd, 0), "cufftSetAutoAllocation");
    const bool single = p.wave_single;
    check_fft(cufftMakePlanMany64(plan_fwd, 3, dims, nullptr, 1, ng, nullptr, 1, nm, single ? CUFFT_R2C : CUFFT_D2Z, 3,
                                  &work_fwd),
              "cufftMakePlanMany64 (forward)");
    check_fft(cufftCreate(&plan_bwd), "cufftCreate");
    have_bwd = true;
    check_fft(cufftSetAutoAllocation(plan_bwd, 0), "cufftSetAutoAllocation");
    check_fft(cufftMakePlanMany64(plan_bwd, 3, dims, nullptr, 1, nm, nullptr, 1, ng, single ? CUFFT_C2R : CUFFT_Z2D, 3,
                                  &work_bwd),
              "cufftMakePlanMany64 (backward)");
    return std::max(work_fwd, work_bwd);
  }

  /// The grid, the half spectrum and the FFT work area: the device's big arrays. A configuration
  /// that cannot fit is refused before any of them is allocated (the CPU path's memory check).
  void allocate_wave(const PseParameters& p, std::size_t work) {
    const std::size_t real_bytes = p.wave_single ? sizeof(float) : sizeof(double);
    // Float grids spread into a separate 64-bit fixed-point accumulator; double grids in place.
    const std::size_t accumulator_bytes = p.wave_single ? 3 * window.ng * sizeof(unsigned long long) : 0;
    const std::size_t need = (3 * window.ng + 2 * 3 * modes.modes) * real_bytes + accumulator_bytes + work;
    std::size_t free_bytes = 0, total_bytes = 0;
    check(cudaMemGetInfo(&free_bytes, &total_bytes), "cudaMemGetInfo");
    require(need <= free_bytes, ErrorCode::out_of_memory, kWhere,
            "the PSE grid " + std::to_string(p.grid[0]) + "x" + std::to_string(p.grid[1]) + "x" +
                std::to_string(p.grid[2]) + " needs " + std::to_string(need >> 20) + " MiB on the device, " +
                std::to_string(free_bytes >> 20) + " MiB are free; raise the tolerance or lower xi");
    grid.resize(3 * window.ng * real_bytes);
    accumulator.resize(accumulator_bytes / sizeof(unsigned long long));
    max_force_bits.resize(1);
    spectrum.resize(2 * 3 * modes.modes * real_bytes);
    fft_work.resize(work);
    if (work > 0) {
      check_fft(cufftSetWorkArea(plan_fwd, fft_work.get()), "cufftSetWorkArea D2Z");
      check_fft(cufftSetWorkArea(plan_bwd, fft_work.get()), "cufftSetWorkArea Z2D");
    }
  }

  /// The slot order, the real-space neighbours (device cell list, or the CPU's lists) and the
  /// window bins for positions wrapped into the box (input order, on the host).
  void place_particles(std::span<const double> positions) {
    const auto t0 = std::chrono::steady_clock::now();
    np = positions.size() / 3;
    cells_active = false;
    if (cuda_options.device_cell_list) {
      events.begin("transfer");
      upload_input(positions.data());
      events.end();
      cells_active = device_cells_of(io.get());
    }
    if (!cells_active) upload_host_lists(positions);
    finish_placement(t0);
  }

  /// place_particles for the same N at positions in device memory (input order, any image):
  /// wrapped into xin on the device; where the device cell list is off or does not fit (< 3
  /// cells a side), the wrapped positions are copied to the host for the CPU's lists.
  void place_particles_device(const double* positions_device) {
    const auto t0 = std::chrono::steady_clock::now();
    xin.resize(n3());
    events.begin("positions_device");
    wrap_positions_kernel<<<blocks_for(np, kThreads), kThreads>>>(static_cast<int>(np), positions_device, box[0],
                                                                  box[1], box[2], xin.get());
    check_kernel("wrap kernel");
    events.end();
    cells_active = cuda_options.device_cell_list && device_cells_of(xin.get());
    if (!cells_active) {
      std::vector<double> host(n3());
      xin.download(host.data(), n3());
      upload_host_lists(host);
    }
    finish_placement(t0);
  }

  /// The device cell list of the positions at xin_dev (input order, wrapped) and the positions
  /// in its slot order; false (nothing built) where it does not fit.
  bool device_cells_of(const double* xin_dev) {
    events.begin("positions_device");
    const bool built = build_device_cells(xin_dev);
    if (built) gather(xin_dev, x);  // positions in slot order
    events.end();
    return built;
  }

  /// The window bins of the placed particles, then the placement's times.
  void finish_placement(std::chrono::steady_clock::time_point t0) {
    events.begin("positions_device");
    build_bins();
    events.end();
    check(cudaDeviceSynchronize(), "set_positions");
    times["positions_real"] += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    events.collect(times);
  }

  /// u (slot order) = M f + noise_scale M^{1/2} z for f already in slot order: the split sampler's
  /// real-space noise by Lanczos, then one wave pass for the drift and the wave noise ([PSE]
  /// Sec. III), the noise keyed by (seed, step). apply_with_noise and apply_with_noise_device.
  SqrtReport noisy_product(double noise_scale, std::uint64_t seed, std::uint64_t step) {
    SqrtReport rep;
    rep.method = SqrtMethod::split;
    if (noise_scale > 0.0) {
      draw_real_noise(seed, step, z);
      rep = real_sqrt(z, noise);
      rep.method = SqrtMethod::split;
    }
    u.resize(n3());
    real_space(f.get(), u.get());
    const detail::NoiseKey key{seed, step};
    wave(f.get(), u.get(), true, noise_scale > 0.0 ? &key : nullptr, noise_scale);
    if (noise_scale > 0.0) device_axpy(n3(), noise_scale, noise.get(), u.get());
    rep.operator_applications += 1;
    return rep;
  }

  /// The CPU's slot order and full neighbour lists, uploaded, and the positions in slot order.
  void upload_host_lists(std::span<const double> positions) {
    real->set_positions(positions);
    const detail::RealSpaceSum::SlotLists lists = real->slot_lists();
    const std::vector<int> order_host(lists.order.begin(), lists.order.end());
    const std::vector<unsigned long long> row_begin(lists.begin.begin(), lists.begin.end());
    order.upload(order_host.data(), order_host.size());
    begin.upload(row_begin.data(), row_begin.size());
    list.upload(lists.list.data(), lists.list.size());
    upload_to_slots(positions.data(), x);  // the input positions, as the CPU wave space reads them
  }
};

bool PseRpyCuda::device_available() {
  int count = 0;
  const cudaError_t e = cudaGetDeviceCount(&count);
  if (e != cudaSuccess) {
    (void)cudaGetLastError();  // clear the sticky error: any error means no usable device
    return false;
  }
  if (count == 0) return false;
  // The library carries code for the architectures it was built for (CMAKE_CUDA_ARCHITECTURES);
  // a device without a kernel image for it counts as no device, so tests skip instead of failing.
  cudaFuncAttributes attributes{};
  const bool image = cudaFuncGetAttributes(&attributes, scale_kernel<double>) == cudaSuccess;
  (void)cudaGetLastError();
  return image;
}

PseRpyCuda::PseRpyCuda(Geometry geometry, double viscosity, const PseOptions& options,
                       const PseCudaOptions& cuda_options)
    : PseOperator(geometry, viscosity, kWhere), impl_(std::make_unique<Impl>()) {
  require(geometry.is_periodic(), ErrorCode::not_supported, kWhere,
          "PSE needs a periodic box (Geometry::periodic); use the direct or FMM operator for open geometry");
  if (!(std::isfinite(options.tolerance) && options.tolerance >= 1e-8 && options.tolerance < 0.1)) {
    fail(ErrorCode::invalid_argument, kWhere,
         "tolerance must lie in [1e-8, 0.1), got " + std::to_string(options.tolerance));
  }
  require(std::isfinite(options.xi) && options.xi >= 0.0, ErrorCode::invalid_argument, kWhere,
          "xi must be >= 0 (0 = automatic), got " + std::to_string(options.xi));
  require(device_available(), ErrorCode::not_supported, kWhere, "no usable CUDA device");
  impl_->options = options;
  impl_->cuda_options = cuda_options;
  require(cuda_options.window_bin >= -1 && cuda_options.window_bin <= 64, ErrorCode::invalid_argument, kWhere,
          "window_bin must be -1 (per particle), 0 (automatic) or a bin edge in [1, 64], got " +
              std::to_string(cuda_options.window_bin));
  impl_->options.real_space_table = true;  // the device path interpolates the table
  int device = 0, multiprocessors = 0, shared = 0;
  check(cudaGetDevice(&device), "cudaGetDevice");
  check(cudaDeviceGetAttribute(&multiprocessors, cudaDevAttrMultiProcessorCount, device), "cudaDeviceGetAttribute");
  check(cudaDeviceGetAttribute(&shared, cudaDevAttrMaxSharedMemoryPerBlockOptin, device), "cudaDeviceGetAttribute");
  impl_->multiprocessors = std::max(1, multiprocessors);
  impl_->max_shared = static_cast<std::size_t>(std::max(shared, 48 * 1024));
}

PseRpyCuda::~PseRpyCuda() = default;

const PseParameters& PseRpyCuda::parameters() const {
  require_positions("parameters");
  return impl_->params;
}

bool PseRpyCuda::device_cell_list_active() const {
  require_positions("device_cell_list_active");
  return impl_->cells_active;
}

int PseRpyCuda::window_bin_edge() const {
  require_positions("window_bin_edge");
  return impl_->bin_edge;
}

StageTimes PseRpyCuda::stage_times() const {
  return impl_->times;
}
void PseRpyCuda::reset_stage_times() const {
  impl_->times.clear();
}

void PseRpyCuda::on_positions_set() {
  require(equal_radii(), ErrorCode::not_supported, "PseRpyCuda::set_positions",
          "PSE supports equal radii only (the paper's assumption); the radii given differ");
  auto& im = *impl_;
  const double a = radii().front();
  const std::size_t n = size();
  require(3 * n < static_cast<std::size_t>(1) << 31, ErrorCode::not_supported, kWhere,
          "3 N >= 2^31: the device kernels index particle vectors with 32-bit integers");
  if (!im.planned || im.params.radius != a || (im.options.xi == 0.0 && im.planned_n != n)) {
    im.plan(a, geometry().box(), n, viscosity());
  }
  im.place_particles(positions());
}

void PseRpyCuda::do_apply(const double* forces, double* velocities, std::size_t nrhs) const {
  auto& im = *impl_;
  const std::size_t n3 = 3 * size();
  for (std::size_t r = 0; r < nrhs; ++r) {
    im.upload_to_slots(forces + r * n3, im.f);
    im.product(im.f, im.u);
    im.download_from_slots(im.u, velocities + r * n3);
  }
}

void PseRpyCuda::apply_device(const double* forces_device, double* velocities_device) const {
  require_positions("apply_device");
  require(forces_device != nullptr && velocities_device != nullptr, ErrorCode::invalid_argument,
          "PseRpyCuda::apply_device", "null device pointer");
  auto& im = *impl_;
  im.gather(forces_device, im.f);
  im.product(im.f, im.u);
  im.scatter(im.u, velocities_device);
  check(cudaDeviceSynchronize(), "apply_device");
  im.events.collect(im.times);
}

SqrtReport PseRpyCuda::sample_device(std::uint64_t seed, std::uint64_t step, double* w_device) const {
  require_positions("sample_device");
  require(w_device != nullptr, ErrorCode::invalid_argument, "PseRpyCuda::sample_device", "null device pointer");
  auto& im = *impl_;
  const SqrtReport rep = im.split_sample(seed, step, im.u);
  im.scatter(im.u, w_device);
  check(cudaDeviceSynchronize(), "sample_device");
  im.events.collect(im.times);
  return rep;
}

void PseRpyCuda::do_apply_rotation(const double* forces, const double* torques, double* velocities,
                                   double* angular_velocities) const {
  auto& im = *impl_;
  im.prepare_rotation();
  im.upload_to_slots(forces, im.f);
  im.upload_to_slots(torques, im.torque);
  im.product_rotation();
  im.download_from_slots(im.u, velocities);
  im.download_from_slots(im.angular, angular_velocities);
}

void PseRpyCuda::apply_device(const double* forces_device, const double* torques_device, double* velocities_device,
                              double* angular_device) const {
  require_positions("apply_device");
  require(forces_device != nullptr && torques_device != nullptr && velocities_device != nullptr &&
              angular_device != nullptr,
          ErrorCode::invalid_argument, "PseRpyCuda::apply_device", "null device pointer");
  auto& im = *impl_;
  im.prepare_rotation();
  im.gather(forces_device, im.f);
  im.gather(torques_device, im.torque);
  im.product_rotation();
  im.scatter(im.u, velocities_device);
  im.scatter(im.angular, angular_device);
  check(cudaDeviceSynchronize(), "apply_device");
  im.events.collect(im.times);
}

SqrtReport PseRpyCuda::do_apply_sqrt_rotation(std::span<const double> z_translation, std::span<const double> z_rotation,
                                              std::span<double> w_translation, std::span<double> w_rotation,
                                              const SqrtOptions& options) const {
  if (options.method != SqrtMethod::automatic && options.method != SqrtMethod::split) {
    return MobilityOperator::do_apply_sqrt_rotation(z_translation, z_rotation, w_translation, w_rotation, options);
  }
  require(options.preconditioner != SqrtPreconditioner::block, ErrorCode::invalid_argument,
          "PseRpyCuda::apply_sqrt_rotation",
          "the block preconditioner serves the Lanczos and Chebyshev samplers only, not the split sampler");
  auto& im = *impl_;
  const std::size_t n3 = im.n3();
  im.prepare_rotation();
  im.z6.resize(2 * n3);
  im.upload_to_slots(z_translation.data(), im.z6.get());
  im.upload_to_slots(z_rotation.data(), im.z6.get() + n3);
  SqrtReport rep = im.real_sqrt_rotation(im.z6, im.w6);
  // Wave part: the translational noise field keyed by the hash of [z_t; z_r], as PseRpy.
  std::vector<double> z(2 * n3);
  std::copy(z_translation.begin(), z_translation.end(), z.begin());
  std::copy(z_rotation.begin(), z_rotation.end(), z.begin() + static_cast<std::ptrdiff_t>(n3));
  const detail::NoiseKey key{noise_hash(z), 0};
  im.wave_rotation(nullptr, nullptr, im.w6.get(), im.w6.get() + n3, &key, 1.0);
  im.download_from_slots(im.w6.get(), w_translation.data());
  im.download_from_slots(im.w6.get() + n3, w_rotation.data());
  rep.method = SqrtMethod::split;
  rep.operator_applications += 1;
  return rep;
}

SqrtReport PseRpyCuda::do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                     const SqrtOptions& options) const {
  if (options.method != SqrtMethod::automatic && options.method != SqrtMethod::split) {
    return MobilityOperator::do_apply_sqrt(z, w, nrhs, options);
  }
  require(options.preconditioner != SqrtPreconditioner::block, ErrorCode::invalid_argument, "PseRpyCuda::apply_sqrt",
          "the block preconditioner serves the Lanczos and Chebyshev samplers only, not the split sampler");
  auto& im = *impl_;
  const std::size_t n3 = 3 * size();
  SqrtReport rep;
  for (std::size_t r = 0; r < nrhs; ++r) {
    im.upload_to_slots(z.data() + r * n3, im.z);
    const SqrtReport one = im.real_sqrt(im.z, im.u);
    const detail::NoiseKey key{noise_hash(z.subspan(r * n3, n3)), 0};
    im.wave(nullptr, im.u.get(), true, &key, 1.0);
    im.download_from_slots(im.u, w.data() + r * n3);
    rep.iterations = std::max(rep.iterations, one.iterations);
    rep.operator_applications += one.operator_applications + 1;
    rep.vector_products += one.vector_products;
    rep.error_estimate = std::max(rep.error_estimate, one.error_estimate);
    rep.converged = rep.converged && one.converged;
    rep.breakdown = rep.breakdown || one.breakdown;
  }
  rep.method = SqrtMethod::split;
  return rep;
}

SqrtReport PseRpyCuda::sample(std::uint64_t seed, std::uint64_t step, std::span<double> w) const {
  require_positions("sample");
  require_size(std::span<const double>(w.data(), w.size()), 3 * size(), "PseRpyCuda::sample", "output");
  auto& im = *impl_;
  const SqrtReport rep = im.split_sample(seed, step, im.u);
  im.download_from_slots(im.u, w.data());
  return rep;
}

namespace {
void require_noise_scale(double noise_scale, const char* where) {
  require(std::isfinite(noise_scale) && noise_scale >= 0.0, ErrorCode::invalid_argument, where,
          "noise_scale must be finite and >= 0");
}
}  // namespace

SqrtReport PseRpyCuda::apply_with_noise(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                                        std::uint64_t step, std::span<double> velocities) const {
  require_positions("apply_with_noise");
  const char* where = "PseRpyCuda::apply_with_noise";
  require_size(forces, 3 * size(), where, "forces");
  require_size(std::span<const double>(velocities.data(), velocities.size()), 3 * size(), where, "velocities");
  require_finite(forces, where, "forces", 3);
  require_noise_scale(noise_scale, where);
  auto& im = *impl_;
  im.upload_to_slots(forces.data(), im.f);  // read by the product only: the noise may be drawn after it
  const SqrtReport rep = im.noisy_product(noise_scale, seed, step);
  im.download_from_slots(im.u, velocities.data());
  return rep;
}

SqrtReport PseRpyCuda::apply_with_noise_device(const double* forces_device, double noise_scale, std::uint64_t seed,
                                               std::uint64_t step, double* velocities_device) const {
  require_positions("apply_with_noise_device");
  const char* where = "PseRpyCuda::apply_with_noise_device";
  require(forces_device != nullptr && velocities_device != nullptr, ErrorCode::invalid_argument, where,
          "null device pointer");
  require_noise_scale(noise_scale, where);
  auto& im = *impl_;
  im.gather(forces_device, im.f);
  const SqrtReport rep = im.noisy_product(noise_scale, seed, step);
  im.scatter(im.u, velocities_device);
  check(cudaDeviceSynchronize(), "apply_with_noise_device");
  im.events.collect(im.times);
  return rep;
}

void PseRpyCuda::set_positions_device(const double* positions_device) {
  require_positions("set_positions_device");
  require(positions_device != nullptr, ErrorCode::invalid_argument, "PseRpyCuda::set_positions_device",
          "null device pointer");
  impl_->place_particles_device(positions_device);
  mark_positions_moved();
}

void PseRpyCuda::read_positions(std::vector<double>& out) const {
  out.resize(impl_->n3());
  impl_->xin.download(out.data(), out.size());
}

}  // namespace rpyfmm::rpy::pse
