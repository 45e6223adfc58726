// rpyfmm — PseRpyCuda: the PSE stages on a CUDA device (PSE.md Sec. 6.3).
// The particles live on the device in slot order (the CPU cell list's order, so that neighbours
// in space are neighbours in memory: the spreading atomics and the neighbour reads stay in L2);
// a product uploads its forces once and downloads its velocities once, gathered and scattered
// between input and slot order on the device.
//   spread:      one thread block per particle, 1D weights in shared memory, atomicAdd;
//   FFT:         cuFFT D2Z / Z2D (R2C / C2R for single-precision grids, PseParameters::wave_single,
//                as the CPU chooses them), batch of 3 components (same layout as FFTW);
//   scale+noise: one thread per half-spectrum mode, the same scale_mode() as the CPU;
//   interpolate: one block per particle, warp-shuffle reduction, added to the real-space part;
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
#include "cuda_window.cuh"
#include "host_copy.hpp"
#include "kernels_common.hpp"
#include "real_space_sqrt.hpp"
#include "real_space_sum.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "wave_space.hpp"

namespace rpyfmm::rpy::pse {

namespace {

constexpr const char* kWhere = "PseRpyCuda";

void check(cudaError_t e, const char* what) {
  if (e == cudaSuccess) return;
  (void)cudaGetLastError();  // clear a non-sticky error: later launches are judged on their own
  const ErrorCode code = e == cudaErrorMemoryAllocation ? ErrorCode::out_of_memory : ErrorCode::numerical_failure;
  fail(code, kWhere, std::string(what) + ": " + cudaGetErrorString(e));
}

void check_fft(cufftResult r, const char* what) {
  if (r == CUFFT_SUCCESS) return;
  const ErrorCode code = r == CUFFT_ALLOC_FAILED ? ErrorCode::out_of_memory : ErrorCode::numerical_failure;
  fail(code, kWhere, std::string(what) + ": cuFFT error " + std::to_string(static_cast<int>(r)));
}

/// After a kernel launch: launch errors always; with RPYFMM_CUDA_SYNC set in the environment,
/// also the kernel's own faults (a synchronising check, for the first runs on a new device).
void check_kernel(const char* what) {
  check(cudaGetLastError(), what);
  static const bool sync = std::getenv("RPYFMM_CUDA_SYNC") != nullptr;
  if (sync) check(cudaDeviceSynchronize(), what);
}

/// Owning device array.
template <class T>
class DeviceArray {
 public:
  DeviceArray() = default;
  DeviceArray(const DeviceArray&) = delete;
  DeviceArray& operator=(const DeviceArray&) = delete;
  ~DeviceArray() { cudaFree(p_); }
  void resize(std::size_t n) {
    if (n == n_ && (p_ != nullptr || n == 0)) return;
    cudaFree(p_);
    p_ = nullptr;
    n_ = 0;
    if (n > 0) {
      check(cudaMalloc(reinterpret_cast<void**>(&p_), n * sizeof(T)), "cudaMalloc");
      n_ = n;  // only once the allocation succeeded
    }
  }
  void upload(const T* host, std::size_t n) {
    resize(n);
    if (n > 0) check(cudaMemcpy(p_, host, n * sizeof(T), cudaMemcpyHostToDevice), "cudaMemcpy to device");
  }
  void download(T* host, std::size_t n) const {
    if (n > 0) check(cudaMemcpy(host, p_, n * sizeof(T), cudaMemcpyDeviceToHost), "cudaMemcpy to host");
  }
  T* get() { return p_; }
  const T* get() const { return p_; }
  [[nodiscard]] std::size_t size() const { return n_; }

 private:
  T* p_ = nullptr;
  std::size_t n_ = 0;
};

/// Owning page-locked host buffer (grows only).
class PinnedBuffer {
 public:
  PinnedBuffer() = default;
  PinnedBuffer(const PinnedBuffer&) = delete;
  PinnedBuffer& operator=(const PinnedBuffer&) = delete;
  ~PinnedBuffer() { cudaFreeHost(p_); }
  double* reserve(std::size_t n) {
    if (n > n_) {
      cudaFreeHost(p_);
      p_ = nullptr;
      n_ = 0;
      check(cudaMallocHost(reinterpret_cast<void**>(&p_), n * sizeof(double)), "cudaMallocHost");
      n_ = n;
    }
    return p_;
  }

 private:
  double* p_ = nullptr;
  std::size_t n_ = 0;
};

/// Bits of the radix sort's keys for keys below `count`.
int key_bits(std::size_t count) {
  int bits = 1;
  while (bits < 32 && (std::size_t{1} << bits) < count) ++bits;
  return bits;
}

using cuda_window::BinGrid;
using cuda_window::block_sum;
using cuda_window::kMaxSupport;
using cuda_window::kWarp;
using cuda_window::WindowParams;

constexpr unsigned kThreads = 256;       // element-wise kernels
constexpr unsigned kReduceBlocks = 240;  // inner products: fixed, so their sums do not depend on the device

unsigned blocks_for(std::size_t n, unsigned threads) {
  return static_cast<unsigned>((n + threads - 1) / threads);
}

/// out[3 s + c] = in[3 order[s] + c] (input -> slot order).
__global__ void gather3_kernel(int np, const int* __restrict__ order, const double* __restrict__ in,
                               double* __restrict__ out) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= np) return;
  const std::size_t i = static_cast<std::size_t>(order[s]);
  for (int c = 0; c < 3; ++c) out[3 * static_cast<std::size_t>(s) + c] = in[3 * i + c];
}

/// out[3 order[s] + c] = in[3 s + c] (slot -> input order).
__global__ void scatter3_kernel(int np, const int* __restrict__ order, const double* __restrict__ in,
                                double* __restrict__ out) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= np) return;
  const std::size_t i = static_cast<std::size_t>(order[s]);
  for (int c = 0; c < 3; ++c) out[3 * i + c] = in[3 * static_cast<std::size_t>(s) + c];
}

template <class Real>
__global__ void scale_kernel(detail::ModeGeometry g, const double* __restrict__ ck, Real* spec, bool deterministic,
                             bool noise, std::uint64_t seed, std::uint64_t step, double factor) {
  const std::size_t idx = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (idx >= g.modes) return;
  detail::scale_mode(idx, g, ck, spec, deterministic, noise, seed, step, factor);
}

/// out = M_r f, everything in slot order (the neighbour lists hold slots).
__global__ void real_space_kernel(int np, const double* __restrict__ x, const double* __restrict__ f, double* out,
                                  const unsigned long long* __restrict__ begin, const int* __restrict__ list,
                                  const double* __restrict__ table, double inv_dr, double self, double m0, double3 L,
                                  double3 inv_L) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= np) return;
  double u[3] = {self * f[3 * i], self * f[3 * i + 1], self * f[3 * i + 2]};
  const double xi = x[3 * i], yi = x[3 * i + 1], zi = x[3 * i + 2];
  for (unsigned long long q = begin[i]; q < begin[i + 1]; ++q) {
    const int j = list[q];
    const double dx = detail::minimum_image(xi - x[3 * j], L.x, inv_L.x);
    const double dy = detail::minimum_image(yi - x[3 * j + 1], L.y, inv_L.y);
    const double dz = detail::minimum_image(zi - x[3 * j + 2], L.z, inv_L.z);
    const double r = sqrt(dx * dx + dy * dy + dz * dz);
    if (r == 0.0) {
      for (int c = 0; c < 3; ++c) u[c] += self * f[3 * j + c];
      continue;
    }
    double F, G;
    detail::table_fg(table, inv_dr, r, F, G);
    detail::pair_block_add(dx, dy, dz, r, F, G, f + 3 * j, u);
  }
  for (int c = 0; c < 3; ++c) out[3 * i + c] = m0 * u[c];
}

/// The device cell list: cells of edge >= r_cut, nc[d] >= 3 per axis (so that the 27 cells
/// around a cell are distinct and every pair within r_cut < L / 2 is found once).
struct CellGrid {
  int nc[3];
  double inv_cell[3];  // nc[d] / L[d]
};

/// key[i] = linear cell index of input particle i (positions wrapped into [0, L)), value[i] = i.
__global__ void cell_key_kernel(int np, const double* __restrict__ x, CellGrid cg, unsigned* __restrict__ key,
                                int* __restrict__ value) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= np) return;
  int c[3];
  for (int d = 0; d < 3; ++d) {
    const int cd = static_cast<int>(x[3 * i + d] * cg.inv_cell[d]);
    c[d] = cd < 0 ? 0 : (cd >= cg.nc[d] ? cg.nc[d] - 1 : cd);
  }
  key[i] = static_cast<unsigned>((c[0] * cg.nc[1] + c[1]) * cg.nc[2] + c[2]);
  value[i] = i;
}

/// out = M_r f in slot order from the cell list: each row scans the 27 cells around its own
/// and takes the pairs with |r|^2 < rc2 (coincident particles included, as the lists do).
__global__ void real_space_cells_kernel(int np, const double* __restrict__ x, const double* __restrict__ f, double* out,
                                        const unsigned* __restrict__ sorted_key, const int* __restrict__ cell_begin,
                                        const int* __restrict__ cell_end, CellGrid cg, double rc2,
                                        const double* __restrict__ table, double inv_dr, double self, double m0,
                                        double3 L, double3 inv_L) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= np) return;
  double u[3] = {self * f[3 * i], self * f[3 * i + 1], self * f[3 * i + 2]};
  const double xi = x[3 * i], yi = x[3 * i + 1], zi = x[3 * i + 2];
  const int key = static_cast<int>(sorted_key[i]);
  const int cz = key % cg.nc[2];
  const int cy = (key / cg.nc[2]) % cg.nc[1];
  const int cx = key / (cg.nc[2] * cg.nc[1]);
  for (int ox = -1; ox <= 1; ++ox) {
    const int nx = (cx + ox + cg.nc[0]) % cg.nc[0];
    for (int oy = -1; oy <= 1; ++oy) {
      const int ny = (cy + oy + cg.nc[1]) % cg.nc[1];
      for (int oz = -1; oz <= 1; ++oz) {
        const int c = (nx * cg.nc[1] + ny) * cg.nc[2] + (cz + oz + cg.nc[2]) % cg.nc[2];
        for (int j = cell_begin[c]; j < cell_end[c]; ++j) {
          if (j == i) continue;
          const double dx = detail::minimum_image(xi - x[3 * j], L.x, inv_L.x);
          const double dy = detail::minimum_image(yi - x[3 * j + 1], L.y, inv_L.y);
          const double dz = detail::minimum_image(zi - x[3 * j + 2], L.z, inv_L.z);
          const double r2 = dx * dx + dy * dy + dz * dz;
          if (!(r2 < rc2)) continue;
          if (r2 == 0.0) {
            for (int q = 0; q < 3; ++q) u[q] += self * f[3 * j + q];
            continue;
          }
          const double r = sqrt(r2);
          double F, G;
          detail::table_fg(table, inv_dr, r, F, G);
          detail::pair_block_add(dx, dy, dz, r, F, G, f + 3 * j, u);
        }
      }
    }
  }
  for (int q = 0; q < 3; ++q) out[3 * i + q] = m0 * u[q];
}

/// out[3 s + c] = normal3(seed, step, stream, order[s])[c]: fill_normal's values (keyed by the
/// input index), drawn on the device straight into slot order.
__global__ void normal_slots_kernel(int np, const int* __restrict__ order, std::uint64_t seed, std::uint64_t step,
                                    std::uint32_t stream, double* __restrict__ out) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= np) return;
  normal3(seed, step, stream, static_cast<std::uint64_t>(order[s]), out + 3 * static_cast<std::size_t>(s));
}

// ---- vector kernels of the device Lanczos (KrylovSpace) ----

/// partial[b] = sum over block b's grid-stride share of x[q] y[q] (kReduceBlocks blocks).
__global__ void dot_partial_kernel(std::size_t n, const double* __restrict__ x, const double* __restrict__ y,
                                   double* __restrict__ partial) {
  __shared__ double warps[kThreads / kWarp];
  double s = 0.0;
  for (std::size_t q = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x; q < n;
       q += static_cast<std::size_t>(gridDim.x) * blockDim.x)
    s += x[q] * y[q];
  s = block_sum(s, warps);
  if (threadIdx.x == 0) partial[blockIdx.x] = s;
}

__global__ void axpy_kernel(std::size_t n, double a, const double* __restrict__ x, double* __restrict__ y) {
  const std::size_t q = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (q < n) y[q] += a * x[q];
}

/// y += a x on n device doubles.
void device_axpy(std::size_t n, double a, const double* x, double* y) {
  axpy_kernel<<<blocks_for(n, kThreads), kThreads>>>(n, a, x, y);
  check_kernel("axpy kernel");
}

__global__ void scale_into_kernel(std::size_t n, double a, const double* x, double* out) {
  const std::size_t q = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (q < n) out[q] = a * x[q];
}

/// first[0] = min index q with a non-finite y[q] (stays at its initial n when there is none).
__global__ void first_nonfinite_kernel(std::size_t n, const double* __restrict__ y, unsigned long long* first) {
  const std::size_t q = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (q < n && !isfinite(y[q])) atomicMin(first, static_cast<unsigned long long>(q));
}

/// The Lanczos basis in device memory: one allocation per basis vector, kept across samples.
class DeviceKrylovSpace final : public sqrt_detail::KrylovSpace {
 public:
  void set_size(std::size_t n) {
    if (n == n_) return;
    n_ = n;
    store_.clear();
    count_ = 0;
    work_.resize(0);
  }
  [[nodiscard]] std::size_t n() const override { return n_; }
  void clear() override { count_ = 0; }
  double* push() override {
    if (count_ == store_.size()) {
      auto v = std::make_unique<DeviceArray<double>>();
      v->resize(n_);  // allocated before it joins the basis: a failed cudaMalloc leaves no null entry
      store_.push_back(std::move(v));
    }
    return store_[count_++]->get();
  }
  [[nodiscard]] double* vector(std::size_t q) override { return store_[q]->get(); }
  [[nodiscard]] std::size_t basis_size() const override { return count_; }
  [[nodiscard]] double* work() override {
    work_.resize(n_);
    return work_.get();
  }
  double dot(const double* x, const double* y) override {
    double h = 0.0;
    dots_of({x}, y, &h);
    return h;
  }
  void dots(std::size_t k, const double* y, double* h) override {
    std::vector<const double*> v(k);
    for (std::size_t q = 0; q < k; ++q) v[q] = store_[q]->get();
    dots_of(v, y, h);
  }
  void subtract_combination(std::size_t k, const double* h, double* y) override {
    for (std::size_t q = 0; q < k; ++q) axpy(-h[q], store_[q]->get(), y);
  }
  void axpy(double a, const double* x, double* y) override { device_axpy(n_, a, x, y); }
  void scale_into(double a, const double* x, double* out) override {
    scale_into_kernel<<<blocks_for(n_, kThreads), kThreads>>>(n_, a, x, out);
    check_kernel("scale kernel (Lanczos)");
  }
  void combine(std::size_t k, const double* c, double* out) override {
    check(cudaMemset(out, 0, n_ * sizeof(double)), "cudaMemset");
    for (std::size_t q = 0; q < k; ++q) axpy(c[q], store_[q]->get(), out);
  }
  void require_finite(const double* y, const char* where, long long product) override {
    flag_.resize(1);
    const auto none = static_cast<unsigned long long>(n_);
    check(cudaMemcpy(flag_.get(), &none, sizeof(none), cudaMemcpyHostToDevice), "cudaMemcpy to device");
    first_nonfinite_kernel<<<blocks_for(n_, kThreads), kThreads>>>(n_, y, flag_.get());
    check_kernel("finiteness kernel");
    unsigned long long first = none;
    flag_.download(&first, 1);
    if (first < none) {
      fail(ErrorCode::numerical_failure, where,
           "the operator returned a non-finite value (entry " + std::to_string(first) +
               " of right-hand side 0, slot order) at product " + std::to_string(product));
    }
  }

 private:
  /// h[q] = v[q] . y: kReduceBlocks partial sums per vector on the device, added on the host in
  /// block order (deterministic).
  void dots_of(const std::vector<const double*>& v, const double* y, double* h) {
    const std::size_t need = std::max<std::size_t>(1, v.size()) * kReduceBlocks;
    if (partial_.size() < need) partial_.resize(2 * need);  // grows only: no allocation per call
    for (std::size_t q = 0; q < v.size(); ++q) {
      dot_partial_kernel<<<kReduceBlocks, kThreads>>>(n_, v[q], y, partial_.get() + q * kReduceBlocks);
      check_kernel("dot kernel");
    }
    host_partial_.resize(v.size() * kReduceBlocks);
    partial_.download(host_partial_.data(), host_partial_.size());
    for (std::size_t q = 0; q < v.size(); ++q) {
      double s = 0.0;
      for (unsigned b = 0; b < kReduceBlocks; ++b) s += host_partial_[q * kReduceBlocks + b];
      h[q] = s;
    }
  }

  std::size_t n_ = 0;
  std::vector<std::unique_ptr<DeviceArray<double>>> store_;
  std::size_t count_ = 0;
  DeviceArray<double> work_, partial_;
  DeviceArray<unsigned long long> flag_;
  std::vector<double> host_partial_;
};

/// Wall-clock seconds of the device's stages, from CUDA events (the stream's own timeline);
/// read (and accumulated) once the product's result has been downloaded.
class StageEvents {
 public:
  StageEvents() = default;
  StageEvents(const StageEvents&) = delete;
  StageEvents& operator=(const StageEvents&) = delete;
  ~StageEvents() {
    for (auto& e : pool_) cudaEventDestroy(e);
  }
  /// Marks the start of `stage` on the default stream.
  void begin(const char* stage) { open_.push_back({stage, record()}); }
  /// Marks the end of the stage begun last.
  void end() {
    if (open_.empty()) return;
    const Open o = open_.back();
    open_.pop_back();
    done_.push_back({o.stage, o.event, record()});
  }
  /// Adds the finished stages' times to `times` (waits for their events) and recycles the
  /// events; called where no stage is open (a stage left open by an exception is dropped).
  void collect(StageTimes& times) {
    std::vector<Done> done;
    done.swap(done_);
    open_.clear();
    used_ = 0;
    for (const Done& d : done) {
      check(cudaEventSynchronize(pool_[d.stop]), "cudaEventSynchronize");
      float ms = 0.0F;
      check(cudaEventElapsedTime(&ms, pool_[d.start], pool_[d.stop]), "cudaEventElapsedTime");
      times[d.stage] += 1e-3 * static_cast<double>(ms);
    }
  }

 private:
  struct Open {
    const char* stage;
    std::size_t event;
  };
  struct Done {
    const char* stage;
    std::size_t start, stop;
  };
  std::size_t record() {
    if (used_ == pool_.size()) {
      cudaEvent_t e{};
      check(cudaEventCreate(&e), "cudaEventCreate");
      pool_.push_back(e);
    }
    check(cudaEventRecord(pool_[used_], 0), "cudaEventRecord");
    return used_++;
  }
  std::vector<cudaEvent_t> pool_;
  std::size_t used_ = 0;
  std::vector<Open> open_;
  std::vector<Done> done_;
};

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
  DeviceArray<double> x;                // positions
  DeviceArray<double> io;               // one vector in input order: the transfers
  DeviceArray<double> f, u, z;          // forces, velocities, the real-space noise
  DeviceArray<double> noise;            // apply_with_noise: M_r^{1/2} z1
  DeviceArray<unsigned char> fft_work;  // one cuFFT work area, shared by the two plans (run in turn)
  DeviceArray<unsigned long long> begin;
  DeviceArray<int> list, order;
  DeviceKrylovSpace krylov;
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
    gather3_kernel<<<blocks_for(np, kThreads), kThreads>>>(static_cast<int>(np), order.get(), src, dst.get());
    check_kernel("gather kernel");
  }
  /// dst (input order) = src (slot order), both on the device.
  void scatter(const DeviceArray<double>& src, double* dst) {
    scatter3_kernel<<<blocks_for(np, kThreads), kThreads>>>(static_cast<int>(np), order.get(), src.get(), dst);
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
    events.begin("transfer");
    upload_input(host);
    gather(io.get(), dst);
    events.end();
  }

  /// host (input order) = src (slot order, device); then the stage times of the work so far.
  void download_from_slots(const DeviceArray<double>& src, double* host) {
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
    const std::size_t real_bytes = params.wave_single ? sizeof(float) : sizeof(double);
    bin_edge =
        cuda_window::choose_bin_edge(window, np, real_bytes, cuda_options.window_bin, multiprocessors, max_shared);
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
    const auto bytes =
        static_cast<int>(params.wave_single ? bin_grid.shared_bytes<float>() : bin_grid.shared_bytes<double>());
    if (params.wave_single) {
      allow_bin_shared_memory<float>(bytes);
    } else {
      allow_bin_shared_memory<double>(bytes);
    }
  }

  /// Lets the bin kernels on Real grids use `bytes` of dynamic shared memory (above 48 KiB
  /// needs the opt-in).
  template <class Real>
  static void allow_bin_shared_memory(int bytes) {
    check(
        cudaFuncSetAttribute(cuda_window::spread_bins_kernel<Real>, cudaFuncAttributeMaxDynamicSharedMemorySize, bytes),
        "shared memory of the bin kernels");
    check(cudaFuncSetAttribute(cuda_window::interpolate_bins_kernel<Real>, cudaFuncAttributeMaxDynamicSharedMemorySize,
                               bytes),
          "shared memory of the bin kernels");
  }

  /// The slot order and cell ranges of the device cell list for the positions in `io` (input
  /// order, wrapped into the box); false (nothing built) where a box side holds < 3 cells.
  bool build_device_cells() {
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
    cell_key_kernel<<<blocks_for(np, kThreads), kThreads>>>(static_cast<int>(np), io.get(), cell_grid, keys_in.get(),
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

  /// wave() on Real grids: cuFFT R2C / C2R for float, D2Z / Z2D for double.
  template <class Real>
  void wave_in(const double* f_dev, double* out, bool accumulate, const detail::NoiseKey* key, double noise_scale) {
    auto* g = reinterpret_cast<Real*>(grid.get());
    auto* spec = reinterpret_cast<Real*>(spectrum.get());
    const bool deterministic = f_dev != nullptr;
    if (deterministic) {
      events.begin("spread");
      check(cudaMemset(g, 0, 3 * window.ng * sizeof(Real)), "cudaMemset");
      if (bin_edge > 0) {
        cuda_window::spread_bins_kernel<Real>
            <<<static_cast<unsigned>(bin_grid.bins()), cuda_window::kBinThreads, bin_grid.shared_bytes<Real>()>>>(
                bin_slots.get(), bin_begin.get(), bin_end.get(), x.get(), f_dev, g, window, bin_grid);
      } else {
        cuda_window::spread_particles_kernel<Real><<<static_cast<unsigned>(np), cuda_window::kParticleThreads>>>(
            static_cast<int>(np), x.get(), f_dev, g, window);
      }
      check_kernel("spread kernel");
      events.end();
      events.begin("fft_forward");
      if constexpr (std::is_same_v<Real, float>) {
        check_fft(cufftExecR2C(plan_fwd, g, reinterpret_cast<cufftComplex*>(spec)), "R2C");
      } else {
        check_fft(cufftExecD2Z(plan_fwd, g, reinterpret_cast<cufftDoubleComplex*>(spec)), "D2Z");
      }
      check_kernel("forward FFT");  // cuFFT faults are asynchronous: name them here, not at the next kernel
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
    if constexpr (std::is_same_v<Real, float>) {
      check_fft(cufftExecC2R(plan_bwd, reinterpret_cast<cufftComplex*>(spec), g), "C2R");
    } else {
      check_fft(cufftExecZ2D(plan_bwd, reinterpret_cast<cufftDoubleComplex*>(spec), g), "Z2D");
    }
    check_kernel("backward FFT");
    events.end();
    events.begin("interpolate");
    if (bin_edge > 0) {
      cuda_window::interpolate_bins_kernel<Real>
          <<<static_cast<unsigned>(bin_grid.bins()), cuda_window::kBinThreads, bin_grid.shared_bytes<Real>()>>>(
              bin_slots.get(), bin_begin.get(), bin_end.get(), x.get(), g, out, window, bin_grid, dv, accumulate);
    } else {
      cuda_window::interpolate_particles_kernel<Real><<<static_cast<unsigned>(np), cuda_window::kParticleThreads>>>(
          static_cast<int>(np), x.get(), g, out, window, dv, accumulate);
    }
    check_kernel("interpolate kernel");
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
    fail(ErrorCode::invalid_argument, kWhere, "tolerance must lie in [1e-8, 0.1), got " + std::to_string(options.tolerance));
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
  const auto& L = geometry().box();
  require(3 * n < static_cast<std::size_t>(1) << 31, ErrorCode::not_supported, kWhere,
          "3 N >= 2^31: the device kernels index particle vectors with 32-bit integers");
  if (!im.planned || im.params.radius != a || (im.options.xi == 0.0 && im.planned_n != n)) {
    const auto t0 = std::chrono::steady_clock::now();
    im.planned = false;
    im.destroy_plans();
    im.grid.resize(0);  // the old plan's big arrays do not count against the new one's memory check
    im.spectrum.resize(0);
    im.fft_work.resize(0);
    PseParameters p = choose_parameters(im.options, a, L, n);
    for (int d = 0; d < 3; ++d)
      require(p.support[d] <= kMaxSupport, ErrorCode::not_supported, kWhere,
              "Gaussian support of " + std::to_string(p.support[d]) + " points exceeds the device limit 64");
    im.real = std::make_unique<detail::RealSpaceSum>(p, L, viscosity(), true, detail::PairCache::off, 0,
                                                     /*full_lists=*/true);  // as the kernels read them
    p.table_dr = im.real->table().dr();
    p.table_size = im.real->table().size();
    const std::vector<double> ck = detail::wave_scaling_table(p, L, viscosity(), im.modes);
    im.ck.upload(ck.data(), ck.size());
    im.table.upload(im.real->table().data().data(), im.real->table().data().size());
    for (int d = 0; d < 3; ++d) {
      im.window.n[d] = p.grid[d];
      im.window.P[d] = p.support[d];
      im.window.h[d] = p.spacing[d];
    }
    im.window.inv_2s2 = 1.0 / (2.0 * p.sigma * p.sigma);
    im.window.c3 = std::pow(2.0 * std::numbers::pi * p.sigma * p.sigma, -1.5);
    im.window.ng = static_cast<std::size_t>(p.grid[0]) * p.grid[1] * p.grid[2];
    im.dv = p.spacing[0] * p.spacing[1] * p.spacing[2];
    // Plans with 64-bit sizes (a batch of 3 grids may exceed 2^31 elements) and without their own
    // work areas: both run on the default stream one after the other, so they share one, and the
    // plans' sizes are known before anything large is allocated.
    long long dims[3] = {p.grid[0], p.grid[1], p.grid[2]};
    const auto ng = static_cast<long long>(im.window.ng);
    const auto nm = static_cast<long long>(im.modes.modes);
    std::size_t work_fwd = 0, work_bwd = 0;
    check_fft(cufftCreate(&im.plan_fwd), "cufftCreate");
    im.have_fwd = true;
    check_fft(cufftSetAutoAllocation(im.plan_fwd, 0), "cufftSetAutoAllocation");
    const bool single = p.wave_single;
    check_fft(cufftMakePlanMany64(im.plan_fwd, 3, dims, nullptr, 1, ng, nullptr, 1, nm, single ? CUFFT_R2C : CUFFT_D2Z,
                                  3, &work_fwd),
              "cufftMakePlanMany64 (forward)");
    check_fft(cufftCreate(&im.plan_bwd), "cufftCreate");
    im.have_bwd = true;
    check_fft(cufftSetAutoAllocation(im.plan_bwd, 0), "cufftSetAutoAllocation");
    check_fft(cufftMakePlanMany64(im.plan_bwd, 3, dims, nullptr, 1, nm, nullptr, 1, ng, single ? CUFFT_C2R : CUFFT_Z2D,
                                  3, &work_bwd),
              "cufftMakePlanMany64 (backward)");
    const std::size_t work = std::max(work_fwd, work_bwd);
    // The grid, the half spectrum and the work area are the device's big arrays: refuse a
    // configuration that cannot fit before allocating any of them (the CPU path's memory check).
    const std::size_t real_bytes = single ? sizeof(float) : sizeof(double);
    const std::size_t need = (3 * im.window.ng + 2 * 3 * im.modes.modes) * real_bytes + work;
    std::size_t free_bytes = 0, total_bytes = 0;
    check(cudaMemGetInfo(&free_bytes, &total_bytes), "cudaMemGetInfo");
    require(need <= free_bytes, ErrorCode::out_of_memory, kWhere,
            "the PSE grid " + std::to_string(p.grid[0]) + "x" + std::to_string(p.grid[1]) + "x" +
                std::to_string(p.grid[2]) + " needs " + std::to_string(need >> 20) + " MiB on the device, " +
                std::to_string(free_bytes >> 20) + " MiB are free; raise the tolerance or lower xi");
    im.grid.resize(3 * im.window.ng * real_bytes);
    im.spectrum.resize(2 * 3 * im.modes.modes * real_bytes);
    im.fft_work.resize(work);
    if (work > 0) {
      check_fft(cufftSetWorkArea(im.plan_fwd, im.fft_work.get()), "cufftSetWorkArea D2Z");
      check_fft(cufftSetWorkArea(im.plan_bwd, im.fft_work.get()), "cufftSetWorkArea Z2D");
    }
    im.params = p;
    im.box = L;
    im.planned = true;
    im.planned_n = n;
    im.times["plan"] += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  const auto t0 = std::chrono::steady_clock::now();
  im.np = n;
  im.cells_active = false;
  if (im.cuda_options.device_cell_list) {
    im.events.begin("transfer");
    im.upload_input(positions().data());  // wrapped into the box by set_positions
    im.events.end();
    im.events.begin("positions_device");
    im.cells_active = im.build_device_cells();
    if (im.cells_active) im.gather(im.io.get(), im.x);  // positions in slot order
    im.events.end();
  }
  if (!im.cells_active) {
    im.real->set_positions(positions());
    const detail::RealSpaceSum::SlotLists lists = im.real->slot_lists();
    const std::vector<int> order(lists.order.begin(), lists.order.end());
    const std::vector<unsigned long long> row_begin(lists.begin.begin(), lists.begin.end());
    im.order.upload(order.data(), order.size());
    im.begin.upload(row_begin.data(), row_begin.size());
    im.list.upload(lists.list.data(), lists.list.size());
    im.upload_to_slots(positions().data(), im.x);  // the input positions, as the CPU wave space reads them
  }
  im.events.begin("positions_device");
  im.build_bins();
  im.events.end();
  check(cudaDeviceSynchronize(), "set_positions");
  im.times["positions_real"] += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  im.events.collect(im.times);
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

SqrtReport PseRpyCuda::apply_with_noise(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                                        std::uint64_t step, std::span<double> velocities) const {
  require_positions("apply_with_noise");
  const char* where = "PseRpyCuda::apply_with_noise";
  require_size(forces, 3 * size(), where, "forces");
  require_size(std::span<const double>(velocities.data(), velocities.size()), 3 * size(), where, "velocities");
  require_finite(forces, where, "forces", 3);
  require(std::isfinite(noise_scale) && noise_scale >= 0.0, ErrorCode::invalid_argument, where,
          "noise_scale must be finite and >= 0");
  auto& im = *impl_;
  const std::size_t n3 = 3 * size();
  SqrtReport rep;
  rep.method = SqrtMethod::split;
  if (noise_scale > 0.0) {
    im.draw_real_noise(seed, step, im.z);
    rep = im.real_sqrt(im.z, im.noise);
    rep.method = SqrtMethod::split;
  }
  im.upload_to_slots(forces.data(), im.f);
  im.u.resize(n3);
  im.real_space(im.f.get(), im.u.get());
  const detail::NoiseKey key{seed, step};
  im.wave(im.f.get(), im.u.get(), true, noise_scale > 0.0 ? &key : nullptr, noise_scale);
  if (noise_scale > 0.0) device_axpy(n3, noise_scale, im.noise.get(), im.u.get());
  im.download_from_slots(im.u, velocities.data());
  rep.operator_applications += 1;
  return rep;
}

}  // namespace rpyfmm::rpy::pse
