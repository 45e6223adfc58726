// rpyfmm — PSE on CUDA with rotation (docs/theory/pse.md section 5; Fiore & Swan 2018): the
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

/// One rotational real-space product in slot order: u += (1 / eta) M_r^{UT} (s_t t) and
/// w = s_w (1 / eta) (M_r^{WF} f + M_r^{WT} (s_t t)), with the self block h(0) on the diagonal.
/// s_t = s_w = 1 for a product; s_t = s_w = a for the sampler's S M_r S (S = diag(I, a I)).
struct RotationRows {
  const double* x;
  const double* f;
  const double* t;
  double* u;
  double* w;
  detail::RotationTableView table;
  double self;  ///< h(0) times eta (PseRotationTable::self)
  double inv_mu;
  double torque_scale, angular_scale;
  double3 L, inv_L;
};

/// acc (u then w) += the terms of neighbour slot j of the particle at (xi, yi, zi).
__device__ inline void rotation_pair_add(const RotationRows& r, int j, double xi, double yi, double zi, double acc[6]) {
  const double dx = detail::minimum_image(xi - r.x[3 * j], r.L.x, r.inv_L.x);
  const double dy = detail::minimum_image(yi - r.x[3 * j + 1], r.L.y, r.inv_L.y);
  const double dz = detail::minimum_image(zi - r.x[3 * j + 2], r.L.z, r.inv_L.z);
  const double s = r.torque_scale;
  const detail::RotationPairTerms p =
      detail::rotation_pair_terms(dx, dy, dz, r.f[3 * j], r.f[3 * j + 1], r.f[3 * j + 2], s * r.t[3 * j],
                                  s * r.t[3 * j + 1], s * r.t[3 * j + 2], r.table);
  acc[0] += p.ux;
  acc[1] += p.uy;
  acc[2] += p.uz;
  acc[3] += p.wx;
  acc[4] += p.wy;
  acc[5] += p.wz;
}

/// Writes row i's sums: u added, w set (RotationRows), with the self block.
__device__ inline void rotation_row_store(const RotationRows& r, int i, const double acc[6]) {
  for (int c = 0; c < 3; ++c) {
    r.u[3 * i + c] += r.inv_mu * acc[c];
    r.w[3 * i + c] = r.angular_scale * r.inv_mu * (r.self * r.torque_scale * r.t[3 * i + c] + acc[3 + c]);
  }
}

/// The rows over the host's neighbour lists (slots; pairs within r_cut, coincident included).
__global__ void rotation_real_space_kernel(int np, RotationRows r, const unsigned long long* __restrict__ begin,
                                           const int* __restrict__ list) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= np) return;
  double acc[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  const double xi = r.x[3 * i], yi = r.x[3 * i + 1], zi = r.x[3 * i + 2];
  for (unsigned long long q = begin[i]; q < begin[i + 1]; ++q) rotation_pair_add(r, list[q], xi, yi, zi, acc);
  rotation_row_store(r, i, acc);
}

/// The rows over the device cell list: the pairs with |d|^2 < rc2 (coincident included).
__global__ void rotation_real_space_cells_kernel(int np, RotationRows r, const unsigned* __restrict__ sorted_key,
                                                 const int* __restrict__ cell_begin, const int* __restrict__ cell_end,
                                                 CellGrid cg, double rc2) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= np) return;
  double acc[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  const double xi = r.x[3 * i], yi = r.x[3 * i + 1], zi = r.x[3 * i + 2];
  for_each_cell_neighbour(i, sorted_key, cell_begin, cell_end, cg, [&](int j) {
    const double dx = detail::minimum_image(xi - r.x[3 * j], r.L.x, r.inv_L.x);
    const double dy = detail::minimum_image(yi - r.x[3 * j + 1], r.L.y, r.inv_L.y);
    const double dz = detail::minimum_image(zi - r.x[3 * j + 2], r.L.z, r.inv_L.z);
    if (dx * dx + dy * dy + dz * dz < rc2) rotation_pair_add(r, j, xi, yi, zi, acc);
  });
  rotation_row_store(r, i, acc);
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
