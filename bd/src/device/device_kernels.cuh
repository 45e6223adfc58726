// rpyfmm::bd::device — the device engine's kernels: one item (particle, slot or cell) per thread,
// each a call of its stage's host-device function (the same the host launcher loops over), and a
// bounding-box reduction for the cell grid of open geometry. The force and update kernels take the
// particles in the slot order of the last build when given it (along the grid: the locality of
// Tran et al. (2015)), which changes which thread computes a particle, not what. Included by
// device_engine.cu only.
#pragma once

#include <cuda_runtime.h>

#include <cfloat>
#include <cstdint>

#include "cell_binning.hpp"
#include "euler_maruyama.hpp"
#include "particle_force.hpp"
#include "verlet_rows.hpp"

namespace rpyfmm::bd::device::kernels {

constexpr unsigned kThreads = 256;       ///< threads per block
constexpr unsigned kBoundsBlocks = 256;  ///< blocks of the bounding-box reduction (grid-stride)

inline unsigned blocks_for(std::uint64_t n) {
  return static_cast<unsigned>((n + kThreads - 1) / kThreads);
}

__device__ inline std::uint32_t thread_item() {
  return blockIdx.x * blockDim.x + threadIdx.x;
}

/// Per block, the bounding box of its particles (grid-stride): lo[3], hi[3] at out[6 b].
__global__ void bounds_kernel(std::uint32_t n, const double* x, double* out) {
  __shared__ double lo[3][kThreads], hi[3][kThreads];
  for (int c = 0; c < 3; ++c) {
    lo[c][threadIdx.x] = DBL_MAX;
    hi[c][threadIdx.x] = -DBL_MAX;
  }
  for (std::uint64_t i = thread_item(); i < n; i += static_cast<std::uint64_t>(gridDim.x) * blockDim.x) {
    for (int c = 0; c < 3; ++c) {
      lo[c][threadIdx.x] = fmin(lo[c][threadIdx.x], x[3 * i + c]);
      hi[c][threadIdx.x] = fmax(hi[c][threadIdx.x], x[3 * i + c]);
    }
  }
  __syncthreads();
  for (unsigned half = blockDim.x / 2; half > 0; half /= 2) {
    if (threadIdx.x < half) {
      for (int c = 0; c < 3; ++c) {
        lo[c][threadIdx.x] = fmin(lo[c][threadIdx.x], lo[c][threadIdx.x + half]);
        hi[c][threadIdx.x] = fmax(hi[c][threadIdx.x], hi[c][threadIdx.x + half]);
      }
    }
    __syncthreads();
  }
  if (threadIdx.x == 0) {
    for (int c = 0; c < 3; ++c) {
      out[6 * blockIdx.x + c] = lo[c][0];
      out[6 * blockIdx.x + 3 + c] = hi[c][0];
    }
  }
}

__global__ void bin_kernel(std::uint32_t n, const double* x, CellGrid g, CellBins bins) {
  const std::uint32_t i = thread_item();
  if (i < n) bin_particle(i, x, g, bins);
}

__global__ void place_kernel(std::uint32_t n, CellBins bins) {
  const std::uint32_t i = thread_item();
  if (i < n) place_particle(i, bins);
}

__global__ void sort_cells_kernel(std::uint64_t cells, CellBins bins) {
  const std::uint64_t cell = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (cell < cells) sort_cell(cell, bins);
}

__global__ void gather_kernel(std::uint32_t n, const double* x, const std::uint32_t* type, CellGrid g, CellBins bins,
                              double* xs, std::uint32_t* ts) {
  const std::uint32_t s = thread_item();
  if (s < n) gather_slot(s, x, type, g, bins, xs, ts);
}

__global__ void count_cells_kernel(std::uint32_t n, CellGrid g, SlotView slots, ListRadii radii, RowsBuild rows) {
  const std::uint32_t s = thread_item();
  if (s < n) count_row_from_cells(s, g, slots, radii, rows);
}

__global__ void fill_cells_kernel(std::uint32_t n, CellGrid g, SlotView slots, ListRadii radii, RowsBuild rows) {
  const std::uint32_t s = thread_item();
  if (s < n) fill_row_from_cells(s, g, slots, radii, rows);
}

__global__ void count_all_kernel(std::uint32_t n, const double* x, const std::uint32_t* type, MinimumImage image,
                                 ListRadii radii, RowsBuild rows) {
  const std::uint32_t i = thread_item();
  if (i < n) count_row_from_all(i, n, x, type, image, radii, rows);
}

__global__ void fill_all_kernel(std::uint32_t n, const double* x, const std::uint32_t* type, MinimumImage image,
                                ListRadii radii, RowsBuild rows) {
  const std::uint32_t i = thread_item();
  if (i < n) fill_row_from_all(i, n, x, type, image, radii, rows);
}

/// The particle of thread item k: along the grid (the slots of the last build) when `order` is
/// set, so that a warp's particles share neighbours in cache; else k.
__device__ inline std::uint32_t particle_of(std::uint32_t k, const std::uint32_t* order) {
  return order != nullptr ? order[k] : k;
}

__global__ void forces_kernel(std::uint32_t n, const std::uint32_t* order, const double* x, ForceTables t,
                              RowsView rows, ForceOutput out) {
  const std::uint32_t k = thread_item();
  if (k < n) particle_force(particle_of(k, order), x, t, rows, out);
}

__global__ void advance_kernel(std::uint32_t n, const std::uint32_t* order, const double* x, const double* f,
                               MotionTables m, MotionOutput out) {
  const std::uint32_t k = thread_item();
  if (k < n) advance_particle(particle_of(k, order), x, f, m, out);
}

/// The update from the velocities u of the step's PSE product (input order, as the engine keeps
/// every per-particle array).
__global__ void advance_with_kernel(std::uint32_t n, const std::uint32_t* order, const double* x, const double* u,
                                    MotionTables m, MotionOutput out) {
  const std::uint32_t k = thread_item();
  if (k < n) advance_particle_with(particle_of(k, order), x, u, m, out);
}

}  // namespace rpyfmm::bd::device::kernels
