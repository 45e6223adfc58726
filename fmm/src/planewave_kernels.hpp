// Elementwise plane-wave kernels of the merge-and-shift M2L (docs/theory/fmm.md), compiled for
// x86-64-v4 (AVX-512), x86-64-v3 (AVX2 + FMA) and the baseline and chosen by simd_level(): the shift of physical values
// V_kj *= Sh_kj and the accumulation of shifted waves are most of the M2L at low precision.
#pragma once

#include <cstddef>

#include "rpyfmm/fmm/detail/expansions.hpp"

// Run-time dispatch for the plane-wave loops (also M2F, F2P, P2F, F2L in planewave.cpp, the batched
// conversions in planewave_batch.cpp and the rotations in rotation.cpp): simd_dispatch.
#include "rpyfmm/core/simd_dispatch.hpp"

namespace rpyfmm::fmm::detail {

/// acc[d m + j] += sh[j] * w[d m + j] for j < m, d < nd (one shift factor table for nd densities).
void shift_accumulate(std::size_t m, std::size_t nd, const cplx* sh, const cplx* w, cplx* acc) noexcept;
/// v[d m + j] *= sh[j] for j < m, d < nd.
void shift_in_place(std::size_t m, std::size_t nd, const cplx* sh, cplx* v) noexcept;
/// dst[i] += src[i] for i < n.
void accumulate(std::size_t n, const cplx* src, cplx* dst) noexcept;

}  // namespace rpyfmm::fmm::detail
