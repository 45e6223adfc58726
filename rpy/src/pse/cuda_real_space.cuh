// rpyfmm — PSE on CUDA: the real-space kernels ([PSE] eq. 10 with App. A via the linear table;
// docs/theory/pse.md), the device cell list, the real-space noise z1, and the permutations
// between input and slot order. Included by pse_rpy_cuda.cu only.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "kernels_common.hpp"
#include "rpyfmm/rpy/random.hpp"

namespace rpyfmm::rpy::pse::cuda_detail {

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

/// visit(j) for every slot j != i in the 27 cells around slot i's cell (cells of the sorted keys;
/// the caller filters by distance).
template <class Visit>
__device__ inline void for_each_cell_neighbour(int i, const unsigned* __restrict__ sorted_key,
                                               const int* __restrict__ cell_begin, const int* __restrict__ cell_end,
                                               const CellGrid& cg, Visit&& visit) {
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
          if (j != i) visit(j);
        }
      }
    }
  }
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
  for_each_cell_neighbour(i, sorted_key, cell_begin, cell_end, cg, [&](int j) {
    const double dx = detail::minimum_image(xi - x[3 * j], L.x, inv_L.x);
    const double dy = detail::minimum_image(yi - x[3 * j + 1], L.y, inv_L.y);
    const double dz = detail::minimum_image(zi - x[3 * j + 2], L.z, inv_L.z);
    const double r2 = dx * dx + dy * dy + dz * dz;
    if (!(r2 < rc2)) return;
    if (r2 == 0.0) {
      for (int q = 0; q < 3; ++q) u[q] += self * f[3 * j + q];
      return;
    }
    const double r = sqrt(r2);
    double F, G;
    detail::table_fg(table, inv_dr, r, F, G);
    detail::pair_block_add(dx, dy, dz, r, F, G, f + 3 * j, u);
  });
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

}  // namespace rpyfmm::rpy::pse::cuda_detail
