// rpyfmm — PSE on CUDA: Gaussian spreading and interpolation (D and D^-1 of [PSE] eq. 19;
// docs/theory/pse.md), the device side of wave_space.cpp's windows. Included by pse_rpy_cuda.cu only.
//
// Two forms: the same grid bit for bit from spreading (integer sums, below), the same
// interpolated sums to the order of the floating-point additions:
// - per particle: one block per particle over its P^3 window, atomics straight into the grid;
// - by bins (the default where it pays): the grid is cut into bins of B^3 points and the
//   particles are sorted by the bin of their window's first point; one block per bin spreads
//   into a subgrid of (B + P - 1)^3 points in shared memory and adds that to the grid once
//   (interpolation: loads the subgrid once and reads the windows from shared memory). The
//   global atomics fall from N P^3 to (B + P - 1)^3 per bin, about (1 + (P-1)/B)^3 per grid point
//   (at Table I's N = 1e6, 320^3 points, P = 7, B = 10: 2.6x fewer). The shared-memory
//   subgrid is the "SM" method of cuFINUFFT (Shih et al., IPDPSW 2021), written here anew.
//
// Spreading sums in 64-bit fixed point, so that a product does not depend on the order in
// which the atomics land (docs/reproducibility.md): each contribution c3 w f_c is rounded once
// to an integer multiple of 2^-shift, integer addition is associative, and the sums are turned
// back into the grid's Real at the end. The shift is chosen per product from max |f|: every
// contribution is at most |c3| max|f| (w is a product of Gaussians <= 1), a grid point sums at
// most N of them (contributions_per_point: more only where a window wraps onto itself), so
// 2^shift |c3| max|f| N < 2^62 keeps every partial sum below 2^63 (fixed_point_shift, tested on
// the host with the other arithmetic in tests/pse/test_pse_bin_plan.cpp). The
// rounding is at most 2^-63 |c3| max|f| N per contribution (1.1e-13 of the largest
// contribution at N = 1e6): below the float grids' own rounding, and far below the smallest
// tolerance of the CUDA path (1e-8) on double grids. (Fixed-point accumulation for
// reproducible GPU sums as in Le Grand, Goetz & Walker, Comput. Phys. Commun. 184 (2013) 374.)
#pragma once

#include <cuda_runtime.h>

#include <cstddef>

#include "cuda_window_plan.hpp"
#include "kernels_common.hpp"

namespace rpyfmm::rpy::pse::cuda_window {

/// The wrapped first grid index of x's window along one axis, as window_weights returns it.
__device__ inline int window_first(double x, double h, int P, int n) {
  long s = detail::window_start(x, h, P) % n;
  if (s < 0) s += n;
  return static_cast<int>(s);
}

/// key[s] = the bin of slot s's window (its first point), value[s] = s.
__global__ void bin_key_kernel(int np, const double* __restrict__ x, WindowParams w, BinGrid g,
                               unsigned* __restrict__ key, int* __restrict__ value) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= np) return;
  int b[3];
  for (int d = 0; d < 3; ++d) b[d] = window_first(x[3 * s + d], w.h[d], w.P[d], w.n[d]) / g.B[d];
  key[s] = static_cast<unsigned>((b[0] * g.nb[1] + b[1]) * g.nb[2] + b[2]);
  value[s] = s;
}

/// range_begin[k] / range_end[k]: the slot range of key k in the sorted keys (both zero-filled
/// before, so absent keys stay empty).
__global__ void key_range_kernel(int np, const unsigned* __restrict__ sorted_key, int* __restrict__ range_begin,
                                 int* __restrict__ range_end) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= np) return;
  const unsigned k = sorted_key[s];
  if (s == 0 || sorted_key[s - 1] != k) range_begin[k] = s;
  if (s == np - 1 || sorted_key[s + 1] != k) range_end[k] = s + 1;
}

/// Sum over the block (blockDim.x a multiple of 32, at most 1024) in a fixed order: shuffles
/// within each warp, then the warps' sums in order by thread 0; valid in thread 0 only.
__device__ inline double block_sum(double v, double* shared_warps) {
  for (unsigned offset = kWarp / 2; offset > 0; offset /= 2) v += __shfl_down_sync(0xffffffffu, v, offset);
  const unsigned lane = threadIdx.x % kWarp, warp = threadIdx.x / kWarp;
  if (lane == 0) shared_warps[warp] = v;
  __syncthreads();
  double s = 0.0;
  if (threadIdx.x == 0)
    for (unsigned q = 0; q < blockDim.x / kWarp; ++q) s += shared_warps[q];
  __syncthreads();  // shared_warps may be reused by the caller's next call
  return s;
}

/// Point t of a window (0 <= t < P0 P1 P2, the last axis fastest): its grid index (the window
/// starting at start[d], wrapped) and its weight w_a w_b w_l from the axes' weights (stride
/// `stride` in wts).
__device__ inline std::size_t window_point_in_grid(int t, const int start[3], const double* wts, int stride,
                                                   const WindowParams& w, double& weight) {
  const int l = t % w.P[2];
  const int b = (t / w.P[2]) % w.P[1];
  const int a = t / (w.P[2] * w.P[1]);
  const std::size_t ix = static_cast<std::size_t>((start[0] + a) % w.n[0]);
  const std::size_t iy = static_cast<std::size_t>((start[1] + b) % w.n[1]);
  const std::size_t iz = static_cast<std::size_t>((start[2] + l) % w.n[2]);
  weight = wts[a] * wts[stride + b] * wts[2 * stride + l];
  return (ix * w.n[1] + iy) * w.n[2] + iz;
}

/// The same in a bin's subgrid, for a window at offsets o[d] there (no wrapping).
__device__ inline int window_point_in_subgrid(int t, const int o[3], const double* wts, const BinGrid& g,
                                              const WindowParams& w, double& weight) {
  const int l = t % w.P[2];
  const int b = (t / w.P[2]) % w.P[1];
  const int a = t / (w.P[2] * w.P[1]);
  weight = wts[a] * wts[g.max_support + b] * wts[2 * g.max_support + l];
  return ((o[0] + a) * g.m[1] + (o[1] + b)) * g.m[2] + (o[2] + l);
}

/// The fixed-point scale of one product: the bits of max |f| (written by max_abs_kernel; a
/// non-negative double's bits order as its value, +inf's bits where some |f| is not finite) and
/// the contributions a grid point can receive (contributions_per_point).
struct FixedPointBound {
  const unsigned long long* max_bits;
  double contributions;
};

/// *max_bits = max(*max_bits, bits of max_q |f[q]|), the bits of +inf where an f[q] is not
/// finite (grid-stride; *max_bits zeroed before). The maximum does not depend on the order.
__global__ void max_abs_kernel(std::size_t n, const double* __restrict__ f, unsigned long long* max_bits) {
  unsigned long long m = 0;
  for (std::size_t q = blockIdx.x * std::size_t{blockDim.x} + threadIdx.x; q < n;
       q += std::size_t{gridDim.x} * blockDim.x) {
    const double a = fabs(f[q]);
    const double kept = isfinite(a) ? a : static_cast<double>(INFINITY);
    const auto bits = static_cast<unsigned long long>(__double_as_longlong(kept));
    m = bits > m ? bits : m;
  }
  for (unsigned offset = kWarp / 2; offset > 0; offset /= 2) {
    const unsigned long long other = __shfl_down_sync(0xffffffffu, m, offset);
    m = other > m ? other : m;
  }
  if (threadIdx.x % kWarp == 0 && m != 0) atomicMax(max_bits, m);
}

/// fixed_point_shift of this product (cuda_window_plan.hpp).
__device__ inline int product_shift(const FixedPointBound& b, double c3) {
  return fixed_point_shift(c3, __longlong_as_double(static_cast<long long>(*b.max_bits)), b.contributions);
}

/// grid[k] = acc[k] 2^-shift in Real (grid-stride over n = 3 ng values). For double grids acc
/// and grid are the same storage: each value is read before it is written, by the same thread.
template <class Real>
__global__ void fixed_to_grid_kernel(std::size_t n, const unsigned long long* acc, Real* grid, WindowParams w,
                                     FixedPointBound b) {
  const int shift = product_shift(b, w.c3);
  for (std::size_t k = blockIdx.x * std::size_t{blockDim.x} + threadIdx.x; k < n;
       k += std::size_t{gridDim.x} * blockDim.x)
    grid[k] = static_cast<Real>(from_fixed(acc[k], shift));
}

/// acc_c += c3 w f_c over each particle's window in fixed point (one block of kParticleThreads
/// per particle).
__global__ void spread_particles_kernel(int np, const double* __restrict__ x, const double* __restrict__ f,
                                        unsigned long long* acc, WindowParams w, FixedPointBound b) {
  const int i = blockIdx.x;
  if (i >= np) return;
  __shared__ double wts[3 * kMaxSupport];
  __shared__ int start[3];
  if (threadIdx.x < 3) {
    const int d = threadIdx.x;
    start[d] = detail::window_weights(x[3 * i + d], w.h[d], w.P[d], w.n[d], w.inv_2s2, wts + d * kMaxSupport);
  }
  __syncthreads();
  const int shift = product_shift(b, w.c3);
  if (shift == INT_MIN) return;  // fixed_to_grid_kernel writes NaN
  const double f0 = w.c3 * f[3 * i], f1 = w.c3 * f[3 * i + 1], f2 = w.c3 * f[3 * i + 2];
  const int total = w.P[0] * w.P[1] * w.P[2];
  for (int t = threadIdx.x; t < total; t += blockDim.x) {
    double wt;
    const std::size_t k = window_point_in_grid(t, start, wts, kMaxSupport, w, wt);
    atomicAdd(acc + k, to_fixed(wt * f0, shift));
    atomicAdd(acc + w.ng + k, to_fixed(wt * f1, shift));
    atomicAdd(acc + 2 * w.ng + k, to_fixed(wt * f2, shift));
  }
}

/// out[3 i + c] (+)= scale c3 sum_window w grid_c (one block of kParticleThreads per particle;
/// the sums in double whatever the grid's Real).
template <class Real>
__global__ void interpolate_particles_kernel(int np, const double* __restrict__ x, const Real* __restrict__ grid,
                                             double* out, WindowParams w, double scale, bool accumulate) {
  const int i = blockIdx.x;
  if (i >= np) return;
  __shared__ double wts[3 * kMaxSupport];
  __shared__ int start[3];
  __shared__ double warps[kParticleThreads / kWarp];
  if (threadIdx.x < 3) {
    const int d = threadIdx.x;
    start[d] = detail::window_weights(x[3 * i + d], w.h[d], w.P[d], w.n[d], w.inv_2s2, wts + d * kMaxSupport);
  }
  __syncthreads();
  double s[3] = {0.0, 0.0, 0.0};
  const int total = w.P[0] * w.P[1] * w.P[2];
  for (int t = threadIdx.x; t < total; t += blockDim.x) {
    double wt;
    const std::size_t k = window_point_in_grid(t, start, wts, kMaxSupport, w, wt);
    s[0] += wt * static_cast<double>(grid[k]);
    s[1] += wt * static_cast<double>(grid[w.ng + k]);
    s[2] += wt * static_cast<double>(grid[2 * w.ng + k]);
  }
  for (int c = 0; c < 3; ++c) {
    const double total_c = block_sum(s[c], warps);
    if (threadIdx.x == 0) {
      const double v = scale * w.c3 * total_c;
      out[3 * i + c] = accumulate ? out[3 * i + c] + v : v;
    }
  }
}

/// The first grid point of bin `bin` along each axis.
__device__ inline void bin_corner(int bin, const BinGrid& g, int corner[3]) {
  corner[2] = (bin % g.nb[2]) * g.B[2];
  corner[1] = ((bin / g.nb[2]) % g.nb[1]) * g.B[1];
  corner[0] = (bin / (g.nb[2] * g.nb[1])) * g.B[0];
}

/// The grid index of subgrid point i of the bin at `corner` (wrapped: the subgrid reaches
/// P - 1 points past the bin, and past the grid's end for the last bins).
__device__ inline std::size_t subgrid_to_grid(int i, const int corner[3], const BinGrid& g, const WindowParams& w) {
  int q[3];
  q[2] = i % g.m[2];
  q[1] = (i / g.m[2]) % g.m[1];
  q[0] = i / (g.m[2] * g.m[1]);
  std::size_t k = 0;
  for (int d = 0; d < 3; ++d) {
    int gd = corner[d] + q[d];
    while (gd >= w.n[d]) gd -= w.n[d];
    k = k * static_cast<std::size_t>(w.n[d]) + static_cast<std::size_t>(gd);
  }
  return k;
}

/// One warp's window of slot s: lanes 0-2 write the weights of axis `lane` into `wts` (stride
/// g.max_support) and the window's offsets in the bin's subgrid are returned to every lane.
__device__ inline void warp_window(int s, const double* __restrict__ x, const WindowParams& w, const BinGrid& g,
                                   const int corner[3], double* wts, int offset[3]) {
  const unsigned lane = threadIdx.x % kWarp;
  int mine = 0;
  if (lane < 3) {
    const int d = static_cast<int>(lane);
    mine = detail::window_weights(x[3 * s + d], w.h[d], w.P[d], w.n[d], w.inv_2s2, wts + d * g.max_support) - corner[d];
  }
  __syncwarp();
  for (int d = 0; d < 3; ++d) offset[d] = __shfl_sync(0xffffffffu, mine, d);
}

/// Spreading by bins in fixed point: one block per bin (kBinThreads threads, g.shared_bytes()
/// of dynamic shared memory), its particles (slots bin_slots[bin_begin[bin] .. bin_end[bin])) a
/// warp each into the shared subgrid, then the subgrid added to the accumulator.
__global__ void spread_bins_kernel(const int* __restrict__ bin_slots, const int* __restrict__ bin_begin,
                                   const int* __restrict__ bin_end, const double* __restrict__ x,
                                   const double* __restrict__ f, unsigned long long* acc, WindowParams w, BinGrid g,
                                   FixedPointBound bound) {
  const int bin = blockIdx.x;
  const int first = bin_begin[bin], last = bin_end[bin];
  if (first >= last) return;  // the whole block: no barrier skipped
  const int shift = product_shift(bound, w.c3);
  if (shift == INT_MIN) return;  // the whole block; fixed_to_grid_kernel writes NaN
  extern __shared__ double shared[];
  const int warp = static_cast<int>(threadIdx.x / kWarp), warps = static_cast<int>(blockDim.x / kWarp);
  const int lane = static_cast<int>(threadIdx.x % kWarp);
  double* wts = shared + warp * 3 * g.max_support;
  auto* sub = reinterpret_cast<unsigned long long*>(shared + warps * 3 * g.max_support);
  for (int i = threadIdx.x; i < 3 * g.sub; i += blockDim.x) sub[i] = 0;
  int corner[3];
  bin_corner(bin, g, corner);
  __syncthreads();
  const int total = w.P[0] * w.P[1] * w.P[2];
  for (int p = first + warp; p < last; p += warps) {
    const int s = bin_slots[p];
    int o[3];
    warp_window(s, x, w, g, corner, wts, o);
    const double f0 = w.c3 * f[3 * s], f1 = w.c3 * f[3 * s + 1], f2 = w.c3 * f[3 * s + 2];
    for (int t = lane; t < total; t += kWarp) {
      double wt;
      const int k = window_point_in_subgrid(t, o, wts, g, w, wt);
      atomicAdd(sub + k, to_fixed(wt * f0, shift));
      atomicAdd(sub + g.sub + k, to_fixed(wt * f1, shift));
      atomicAdd(sub + 2 * g.sub + k, to_fixed(wt * f2, shift));
    }
    __syncwarp();  // the weights are rewritten for the warp's next particle
  }
  __syncthreads();
  for (int i = threadIdx.x; i < g.sub; i += blockDim.x) {
    const std::size_t k = subgrid_to_grid(i, corner, g, w);
    for (int c = 0; c < 3; ++c) {
      const unsigned long long v = sub[c * g.sub + i];
      if (v != 0) atomicAdd(acc + c * w.ng + k, v);
    }
  }
}

/// Interpolation by bins: one block per bin loads the bin's subgrid into shared memory
/// (g.shared_bytes() holds it in either precision), then each warp sums a particle's window from there (shuffles; the
/// sums in double).
template <class Real>
__global__ void interpolate_bins_kernel(const int* __restrict__ bin_slots, const int* __restrict__ bin_begin,
                                        const int* __restrict__ bin_end, const double* __restrict__ x,
                                        const Real* __restrict__ grid, double* out, WindowParams w, BinGrid g,
                                        double scale, bool accumulate) {
  const int bin = blockIdx.x;
  const int first = bin_begin[bin], last = bin_end[bin];
  if (first >= last) return;
  extern __shared__ double shared[];
  const int warp = static_cast<int>(threadIdx.x / kWarp), warps = static_cast<int>(blockDim.x / kWarp);
  const int lane = static_cast<int>(threadIdx.x % kWarp);
  double* wts = shared + warp * 3 * g.max_support;
  Real* sub = reinterpret_cast<Real*>(shared + warps * 3 * g.max_support);
  int corner[3];
  bin_corner(bin, g, corner);
  for (int i = threadIdx.x; i < g.sub; i += blockDim.x) {
    const std::size_t k = subgrid_to_grid(i, corner, g, w);
    for (int c = 0; c < 3; ++c) sub[c * g.sub + i] = grid[c * w.ng + k];
  }
  __syncthreads();
  const int total = w.P[0] * w.P[1] * w.P[2];
  for (int p = first + warp; p < last; p += warps) {
    const int s = bin_slots[p];
    int o[3];
    warp_window(s, x, w, g, corner, wts, o);
    double sum[3] = {0.0, 0.0, 0.0};
    for (int t = lane; t < total; t += kWarp) {
      double wt;
      const int k = window_point_in_subgrid(t, o, wts, g, w, wt);
      sum[0] += wt * static_cast<double>(sub[k]);
      sum[1] += wt * static_cast<double>(sub[g.sub + k]);
      sum[2] += wt * static_cast<double>(sub[2 * g.sub + k]);
    }
    for (unsigned offset = kWarp / 2; offset > 0; offset /= 2)
      for (int c = 0; c < 3; ++c) sum[c] += __shfl_down_sync(0xffffffffu, sum[c], offset);
    if (lane == 0) {
      for (int c = 0; c < 3; ++c) {
        const double v = scale * w.c3 * sum[c];
        out[3 * s + c] = accumulate ? out[3 * s + c] + v : v;
      }
    }
    __syncwarp();
  }
}

}  // namespace rpyfmm::rpy::pse::cuda_window
