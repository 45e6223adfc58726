// rpyfmm — PSE on CUDA with rotation (docs/theory/pse.md Sec. 5; Fiore & Swan 2018): the
// rotational real-space rows by rotation_pair_terms (the CPU rows' per-pair arithmetic), over the
// host's neighbour lists or the device cell list, and the per-mode scaling of the force and
// torque spectra by scale_rotation_mode_at (the CPU's scale_rotation_mode and noise draw).
// Included by pse_rpy_cuda.cu only.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "cuda_real_space.cuh"
#include "kernels_common.hpp"
#include "rotation_modes.hpp"
#include "rotation_pair_device.hpp"

namespace rpyfmm::rpy::pse::cuda_detail {

/// The rows over the host's neighbour lists (slots; pairs within r_cut, coincident included).
__global__ void rotation_real_space_kernel(int np, detail::RotationRows r, const unsigned long long* __restrict__ begin,
                                           const int* __restrict__ list) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= np) return;
  double acc[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  const double xi[3] = {r.x[3 * i], r.x[3 * i + 1], r.x[3 * i + 2]};
  for (unsigned long long q = begin[i]; q < begin[i + 1]; ++q) detail::rotation_pair_add(r, list[q], xi, acc);
  detail::rotation_row_store(r, i, acc);
}

/// The rows over the device cell list: the pairs with |d|^2 < rc2 (coincident included).
__global__ void rotation_real_space_cells_kernel(int np, detail::RotationRows r,
                                                 const unsigned* __restrict__ sorted_key,
                                                 const int* __restrict__ cell_begin, const int* __restrict__ cell_end,
                                                 CellGrid cg, double rc2) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= np) return;
  double acc[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  const double xi[3] = {r.x[3 * i], r.x[3 * i + 1], r.x[3 * i + 2]};
  for_each_cell_neighbour(i, sorted_key, cell_begin, cell_end, cg, [&](int j) {
    double d[3];
    detail::rotation_displacement(r, j, xi, d);
    if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < rc2) detail::rotation_pair_add(r, j, xi, acc);
  });
  detail::rotation_row_store(r, i, acc);
}

/// factors[idx] = rotation_mode_factors of every half-spectrum mode (once per plan).
__global__ void rotation_factors_kernel(detail::ModeGeometry g, detail::RotationModeConstants rc,
                                        detail::RotationModeFactors* __restrict__ factors) {
  const std::size_t idx = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (idx >= g.modes) return;
  factors[idx] = detail::rotation_mode_factors_at(idx, g, rc);
}

/// The force spectrum fs and torque spectrum ts -> U and W, one thread per mode (rotation_modes.hpp).
template <class Real>
__global__ void scale_rotation_kernel(detail::ModeGeometry g, const double* __restrict__ ck,
                                      const detail::RotationModeFactors* __restrict__ factors, Real* fs, Real* ts,
                                      bool deterministic, bool noise, std::uint64_t seed, std::uint64_t step,
                                      double factor) {
  const std::size_t idx = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (idx >= g.modes) return;
  detail::scale_rotation_mode_at(idx, g, ck, factors, fs, ts, deterministic, noise, seed, step, factor);
}

}  // namespace rpyfmm::rpy::pse::cuda_detail
