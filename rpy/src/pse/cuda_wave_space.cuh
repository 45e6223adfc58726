// rpyfmm — PSE on CUDA: the wave-space scaling of the half spectrum (B of [PSE] eq. 19, and its
// square root for the noise, eq. 21; docs/theory/pse.md), one thread per mode, by the CPU's
// scale_mode(). Included by pse_rpy_cuda.cu only.
#pragma once

#include <cuda_runtime.h>

#include <cstddef>
#include <cstdint>

#include "kernels_common.hpp"

namespace rpyfmm::rpy::pse::cuda_detail {

template <class Real>
__global__ void scale_kernel(detail::ModeGeometry g, const double* __restrict__ ck, Real* spec, bool deterministic,
                             bool noise, std::uint64_t seed, std::uint64_t step, double factor) {
  const std::size_t idx = static_cast<std::size_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (idx >= g.modes) return;
  detail::scale_mode(idx, g, ck, spec, deterministic, noise, seed, step, factor);
}

}  // namespace rpyfmm::rpy::pse::cuda_detail
