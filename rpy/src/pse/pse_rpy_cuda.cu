// rpyfmm — PseRpyCuda: the PSE stages on a CUDA device (PSE.md Sec. 6.3).
//   spread:      one thread block per particle, 1D weights in shared memory, atomicAdd;
//   FFT:         cuFFT D2Z / Z2D, batch of 3 components (same layout as FFTW);
//   scale+noise: one thread per half-spectrum mode, the same scale_mode() as the CPU;
//   interpolate: one block per particle, block reduction;
//   real space:  one thread per particle over its neighbour list (built on the host
//                with the CPU cell list), table lookup, no atomics.
// Parameters, tables and neighbour lists come from the CPU code, so both back ends
// use identical inputs; the Lanczos iteration of the split sampler runs on the host
// with device products.
#include <cuda_runtime.h>
#include <cufft.h>

#include <algorithm>
#include <cstdlib>

#include <numbers>
#include <string>
#include <vector>

#include "kernels_common.hpp"
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

 private:
  T* p_ = nullptr;
  std::size_t n_ = 0;
};

struct WindowParams {
  int n[3];
  int P[3];
  double h[3];
  double inv_2s2;
  double c3;
  std::size_t ng;
};

constexpr int kMaxSupport = 64;

__global__ void spread_kernel(int np, const double* __restrict__ x, const double* __restrict__ f, double* grid,
                              WindowParams w) {
  const int i = blockIdx.x;
  if (i >= np) return;
  __shared__ double wts[3 * kMaxSupport];
  __shared__ int start[3];
  if (threadIdx.x < 3) {
    const int d = threadIdx.x;
    start[d] = detail::window_weights(x[3 * i + d], w.h[d], w.P[d], w.n[d], w.inv_2s2, wts + d * kMaxSupport);
  }
  __syncthreads();
  const double f0 = w.c3 * f[3 * i], f1 = w.c3 * f[3 * i + 1], f2 = w.c3 * f[3 * i + 2];
  const int total = w.P[0] * w.P[1] * w.P[2];
  for (int t = threadIdx.x; t < total; t += blockDim.x) {
    const int l = t % w.P[2];
    const int b = (t / w.P[2]) % w.P[1];
    const int a = t / (w.P[2] * w.P[1]);
    const std::size_t ix = static_cast<std::size_t>((start[0] + a) % w.n[0]);
    const std::size_t iy = static_cast<std::size_t>((start[1] + b) % w.n[1]);
    const std::size_t iz = static_cast<std::size_t>((start[2] + l) % w.n[2]);
    const std::size_t k = (ix * w.n[1] + iy) * w.n[2] + iz;
    const double wt = wts[a] * wts[kMaxSupport + b] * wts[2 * kMaxSupport + l];
    atomicAdd(grid + k, wt * f0);
    atomicAdd(grid + w.ng + k, wt * f1);
    atomicAdd(grid + 2 * w.ng + k, wt * f2);
  }
}

constexpr int kInterpThreads = 128;

__global__ void interpolate_kernel(int np, const double* __restrict__ x, const double* __restrict__ grid,
                                   double* out, WindowParams w, double scale) {
  const int i = blockIdx.x;
  if (i >= np) return;
  __shared__ double wts[3 * kMaxSupport];
  __shared__ int start[3];
  __shared__ double red[3][kInterpThreads];
  if (threadIdx.x < 3) {
    const int d = threadIdx.x;
    start[d] = detail::window_weights(x[3 * i + d], w.h[d], w.P[d], w.n[d], w.inv_2s2, wts + d * kMaxSupport);
  }
  __syncthreads();
  double s0 = 0.0, s1 = 0.0, s2 = 0.0;
  const int total = w.P[0] * w.P[1] * w.P[2];
  for (int t = threadIdx.x; t < total; t += blockDim.x) {
    const int l = t % w.P[2];
    const int b = (t / w.P[2]) % w.P[1];
    const int a = t / (w.P[2] * w.P[1]);
    const std::size_t ix = static_cast<std::size_t>((start[0] + a) % w.n[0]);
    const std::size_t iy = static_cast<std::size_t>((start[1] + b) % w.n[1]);
    const std::size_t iz = static_cast<std::size_t>((start[2] + l) % w.n[2]);
    const std::size_t k = (ix * w.n[1] + iy) * w.n[2] + iz;
    const double wt = wts[a] * wts[kMaxSupport + b] * wts[2 * kMaxSupport + l];
    s0 += wt * grid[k];
    s1 += wt * grid[w.ng + k];
    s2 += wt * grid[2 * w.ng + k];
  }
  red[0][threadIdx.x] = s0;
  red[1][threadIdx.x] = s1;
  red[2][threadIdx.x] = s2;
  __syncthreads();
  for (int half = kInterpThreads / 2; half > 0; half /= 2) {
    if (static_cast<int>(threadIdx.x) < half) {
      for (int c = 0; c < 3; ++c) red[c][threadIdx.x] += red[c][threadIdx.x + half];
    }
    __syncthreads();
  }
  if (threadIdx.x == 0) {
    for (int c = 0; c < 3; ++c) out[3 * i + c] = scale * w.c3 * red[c][0];
  }
}

__global__ void scale_kernel(detail::ModeGeometry g, const double* __restrict__ ck, double* spec, bool deterministic,
                             bool noise, std::uint64_t seed, std::uint64_t step, double factor) {
  const std::size_t idx = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (idx >= g.modes) return;
  detail::scale_mode(idx, g, ck, spec, deterministic, noise, seed, step, factor);
}

__global__ void real_space_kernel(int np, const double* __restrict__ x, const double* __restrict__ f, double* out,
                                  const unsigned long long* __restrict__ begin, const int* __restrict__ list,
                                  const double* __restrict__ table, double inv_dr, double self, double m0, double3 L,
                                  double3 inv_L) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= np) return;
  double u[3] = {self * f[3 * i], self * f[3 * i + 1], self * f[3 * i + 2]};
  for (unsigned long long q = begin[i]; q < begin[i + 1]; ++q) {
    const int j = list[q];
    const double dx = detail::minimum_image(x[3 * i] - x[3 * j], L.x, inv_L.x);
    const double dy = detail::minimum_image(x[3 * i + 1] - x[3 * j + 1], L.y, inv_L.y);
    const double dz = detail::minimum_image(x[3 * i + 2] - x[3 * j + 2], L.z, inv_L.z);
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

unsigned blocks_for(std::size_t n, unsigned threads) { return static_cast<unsigned>((n + threads - 1) / threads); }

}  // namespace

struct PseRpyCuda::Impl {
  PseOptions options;
  PseParameters params;
  bool planned = false;
  std::size_t planned_n = 0;
  std::unique_ptr<detail::RealSpaceSum> real;  // host: table + neighbour lists
  detail::ModeGeometry modes{};
  WindowParams window{};
  double dv = 0.0;
  cufftHandle plan_fwd = 0, plan_bwd = 0;
  bool have_fwd = false, have_bwd = false;
  DeviceArray<double> ck, grid, spectrum, x, f, u, table;
  DeviceArray<unsigned char> fft_work;  // one cuFFT work area, shared by the two plans (run in turn)
  DeviceArray<unsigned long long> begin;
  DeviceArray<int> list;

  ~Impl() { destroy_plans(); }
  void destroy_plans() {
    if (have_fwd) cufftDestroy(plan_fwd);
    if (have_bwd) cufftDestroy(plan_bwd);
    have_fwd = have_bwd = false;
  }

  /// out (+)= M_w f + noise_scale M_w^{1/2} z2(key) for one right-hand side (host arrays).
  void wave(const double* f_host, double* out, bool accumulate, const detail::NoiseKey* key, double noise_scale,
            std::size_t np) {
    const std::size_t n3 = 3 * np;
    const bool deterministic = f_host != nullptr;
    if (deterministic) {
      f.upload(f_host, n3);
      check(cudaMemset(grid.get(), 0, 3 * window.ng * sizeof(double)), "cudaMemset");
      spread_kernel<<<static_cast<unsigned>(np), 128>>>(static_cast<int>(np), x.get(), f.get(), grid.get(), window);
      check_kernel("spread kernel");
      check_fft(cufftExecD2Z(plan_fwd, grid.get(), reinterpret_cast<cufftDoubleComplex*>(spectrum.get())), "D2Z");
      check_kernel("D2Z");  // cuFFT faults are asynchronous: name them here, not at the next kernel
    }
    const bool with_noise = key != nullptr && noise_scale != 0.0;
    scale_kernel<<<blocks_for(modes.modes, 256), 256>>>(modes, ck.get(), spectrum.get(), deterministic, with_noise,
                                                         with_noise ? key->seed : 0, with_noise ? key->step : 0,
                                                         noise_scale / std::sqrt(dv));
    check_kernel("scale kernel");
    check_fft(cufftExecZ2D(plan_bwd, reinterpret_cast<cufftDoubleComplex*>(spectrum.get()), grid.get()), "Z2D");
    check_kernel("Z2D");
    u.resize(n3);
    interpolate_kernel<<<static_cast<unsigned>(np), kInterpThreads>>>(static_cast<int>(np), x.get(), grid.get(),
                                                                      u.get(), window, dv);
    check_kernel("interpolate kernel");
    std::vector<double> h(n3);
    u.download(h.data(), n3);
    for (std::size_t q = 0; q < n3; ++q) out[q] = accumulate ? out[q] + h[q] : h[q];
  }

  /// out (+)= M_r f for nrhs right-hand sides (host arrays).
  void real_space(const double* f_host, double* out, std::size_t nrhs, bool accumulate, std::size_t np,
                  const std::array<double, 3>& L) {
    const std::size_t n3 = 3 * np;
    std::vector<double> h(n3);
    for (std::size_t r = 0; r < nrhs; ++r) {
      f.upload(f_host + r * n3, n3);
      u.resize(n3);
      real_space_kernel<<<blocks_for(np, 128), 128>>>(static_cast<int>(np), x.get(), f.get(), u.get(), begin.get(),
                                                      list.get(), table.get(), 1.0 / real->table().dr(), real->self(),
                                                      real->mobility_unit(), make_double3(L[0], L[1], L[2]),
                                                      make_double3(1.0 / L[0], 1.0 / L[1], 1.0 / L[2]));
      check_kernel("real-space kernel");
      u.download(h.data(), n3);
      double* o = out + r * n3;
      for (std::size_t q = 0; q < n3; ++q) o[q] = accumulate ? o[q] + h[q] : h[q];
    }
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
  const bool image = cudaFuncGetAttributes(&attributes, scale_kernel) == cudaSuccess;
  (void)cudaGetLastError();
  return image;
}

PseRpyCuda::PseRpyCuda(Geometry geometry, double viscosity, const PseOptions& options)
    : MobilityOperator(geometry, viscosity, kWhere), impl_(std::make_unique<Impl>()) {
  require(geometry.is_periodic(), ErrorCode::not_supported, kWhere,
          "PSE needs a periodic box (Geometry::periodic); use the direct or FMM operator for open geometry");
  if (!(std::isfinite(options.tolerance) && options.tolerance >= 1e-8 && options.tolerance < 0.1)) {
    fail(ErrorCode::invalid_argument, kWhere, "tolerance must lie in [1e-8, 0.1), got " + std::to_string(options.tolerance));
  }
  require(std::isfinite(options.xi) && options.xi >= 0.0, ErrorCode::invalid_argument, kWhere,
          "xi must be >= 0 (0 = automatic), got " + std::to_string(options.xi));
  require(options.wave_precision != WavePrecision::single_precision, ErrorCode::not_supported, kWhere,
          "single-precision wave grids (PseOptions::wave_precision) are CPU-only; the CUDA backend computes in "
          "double precision (use automatic or double_precision)");
  require(device_available(), ErrorCode::not_supported, kWhere, "no usable CUDA device");
  impl_->options = options;
  impl_->options.real_space_table = true;                           // the device path interpolates the table
  impl_->options.wave_precision = WavePrecision::double_precision;  // cuFFT in double (Z2D / D2Z)
}

PseRpyCuda::~PseRpyCuda() = default;

const PseParameters& PseRpyCuda::parameters() const {
  require_positions("parameters");
  return impl_->params;
}

void PseRpyCuda::on_positions_set() {
  require(equal_radii(), ErrorCode::not_supported, "PseRpyCuda::set_positions",
          "PSE supports equal radii only (the paper's assumption); the radii given differ");
  auto& im = *impl_;
  const double a = radii().front();
  const std::size_t n = size();
  const auto& L = geometry().box();
  if (!im.planned || im.params.radius != a || (im.options.xi == 0.0 && im.planned_n != n)) {
    im.planned = false;
    im.destroy_plans();
    im.grid.resize(0);  // the old plan's big arrays do not count against the new one's memory check
    im.spectrum.resize(0);
    im.fft_work.resize(0);
    PseParameters p = choose_parameters(im.options, a, L, n);
    for (int d = 0; d < 3; ++d)
      require(p.support[d] <= kMaxSupport, ErrorCode::not_supported, kWhere,
              "Gaussian support of " + std::to_string(p.support[d]) + " points exceeds the device limit 64");
    im.real = std::make_unique<detail::RealSpaceSum>(p, L, viscosity(), true);
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
    check_fft(cufftMakePlanMany64(im.plan_fwd, 3, dims, nullptr, 1, ng, nullptr, 1, nm, CUFFT_D2Z, 3, &work_fwd),
              "cufftMakePlanMany64 D2Z");
    check_fft(cufftCreate(&im.plan_bwd), "cufftCreate");
    im.have_bwd = true;
    check_fft(cufftSetAutoAllocation(im.plan_bwd, 0), "cufftSetAutoAllocation");
    check_fft(cufftMakePlanMany64(im.plan_bwd, 3, dims, nullptr, 1, nm, nullptr, 1, ng, CUFFT_Z2D, 3, &work_bwd),
              "cufftMakePlanMany64 Z2D");
    const std::size_t work = std::max(work_fwd, work_bwd);
    // The grid, the half spectrum and the work area are the device's big arrays: refuse a
    // configuration that cannot fit before allocating any of them (the CPU path's memory check).
    const std::size_t need = (3 * im.window.ng + 2 * 3 * im.modes.modes) * sizeof(double) + work;
    std::size_t free_bytes = 0, total_bytes = 0;
    check(cudaMemGetInfo(&free_bytes, &total_bytes), "cudaMemGetInfo");
    require(need <= free_bytes, ErrorCode::out_of_memory, kWhere,
            "the PSE grid " + std::to_string(p.grid[0]) + "x" + std::to_string(p.grid[1]) + "x" +
                std::to_string(p.grid[2]) + " needs " + std::to_string(need >> 20) + " MiB on the device, " +
                std::to_string(free_bytes >> 20) + " MiB are free; raise the tolerance or lower xi");
    im.grid.resize(3 * im.window.ng);
    im.spectrum.resize(2 * 3 * im.modes.modes);
    im.fft_work.resize(work);
    if (work > 0) {
      check_fft(cufftSetWorkArea(im.plan_fwd, im.fft_work.get()), "cufftSetWorkArea D2Z");
      check_fft(cufftSetWorkArea(im.plan_bwd, im.fft_work.get()), "cufftSetWorkArea Z2D");
    }
    im.params = p;
    im.planned = true;
    im.planned_n = n;
  }
  im.real->set_positions(positions());
  im.x.upload(positions().data(), positions().size());
  std::vector<std::size_t> begin;
  std::vector<int> list;
  im.real->input_order_lists(begin, list);  // rows and neighbours in input numbering
  std::vector<unsigned long long> b(begin.begin(), begin.end());
  im.begin.upload(b.data(), b.size());
  im.list.upload(list.data(), list.size());
}

void PseRpyCuda::do_apply(const double* forces, double* velocities, std::size_t nrhs) const {
  const std::size_t n3 = 3 * size();
  for (std::size_t r = 0; r < nrhs; ++r) impl_->wave(forces + r * n3, velocities + r * n3, false, nullptr, 0.0, size());
  impl_->real_space(forces, velocities, nrhs, true, size(), geometry().box());
}

namespace {

SqrtReport lanczos_real(const LinearOperatorView& view, std::span<const double> z, std::span<double> w,
                        std::size_t nrhs, double tol) {
  SqrtOptions o;
  o.method = SqrtMethod::lanczos;
  o.tolerance = tol;
  return sqrt_apply(view, z, w, nrhs, o);
}

}  // namespace

SqrtReport PseRpyCuda::do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                     const SqrtOptions& options) const {
  if (options.method != SqrtMethod::automatic && options.method != SqrtMethod::split) {
    return MobilityOperator::do_apply_sqrt(z, w, nrhs, options);
  }
  auto& im = *impl_;
  LinearOperatorView view;
  view.n = 3 * size();
  view.apply = [this](std::span<const double> xin, std::span<double> y, std::size_t k) {
    impl_->real_space(xin.data(), y.data(), k, false, size(), geometry().box());
  };
  SqrtReport rep = lanczos_real(view, z, w, nrhs, im.params.lanczos_tolerance);
  const std::size_t n3 = 3 * size();
  for (std::size_t r = 0; r < nrhs; ++r) {
    const detail::NoiseKey key{noise_hash(z.subspan(r * n3, n3)), 0};
    im.wave(nullptr, w.data() + r * n3, true, &key, 1.0, size());
  }
  rep.method = SqrtMethod::split;
  rep.operator_applications += 1;
  return rep;
}

SqrtReport PseRpyCuda::sample(std::uint64_t seed, std::uint64_t step, std::span<double> w) const {
  require_positions("sample");
  require_size(std::span<const double>(w.data(), w.size()), 3 * size(), "PseRpyCuda::sample", "output");
  std::vector<double> z1(3 * size());
  fill_normal(z1, seed, step, detail::kStreamReal);
  LinearOperatorView view;
  view.n = 3 * size();
  view.apply = [this](std::span<const double> xin, std::span<double> y, std::size_t k) {
    impl_->real_space(xin.data(), y.data(), k, false, size(), geometry().box());
  };
  SqrtReport rep = lanczos_real(view, z1, w, 1, impl_->params.lanczos_tolerance);
  const detail::NoiseKey key{seed, step};
  impl_->wave(nullptr, w.data(), true, &key, 1.0, size());
  rep.method = SqrtMethod::split;
  rep.operator_applications += 1;
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
  SqrtReport rep;
  rep.method = SqrtMethod::split;
  std::vector<double> y;
  if (noise_scale > 0.0) {
    std::vector<double> z1(3 * size());
    fill_normal(z1, seed, step, detail::kStreamReal);
    y.resize(3 * size());
    LinearOperatorView view;
    view.n = 3 * size();
    view.apply = [this](std::span<const double> xin, std::span<double> yo, std::size_t k) {
      impl_->real_space(xin.data(), yo.data(), k, false, size(), geometry().box());
    };
    rep = lanczos_real(view, z1, y, 1, impl_->params.lanczos_tolerance);
    rep.method = SqrtMethod::split;
  }
  const detail::NoiseKey key{seed, step};
  impl_->wave(forces.data(), velocities.data(), false, noise_scale > 0.0 ? &key : nullptr, noise_scale, size());
  impl_->real_space(forces.data(), velocities.data(), 1, true, size(), geometry().box());
  for (std::size_t i = 0; i < y.size(); ++i) velocities[i] += noise_scale * y[i];
  rep.operator_applications += 1;
  return rep;
}

}  // namespace rpyfmm::rpy::pse
