// rpyfmm — the candidate filters of the PSE neighbour-list build with AVX-512 and AVX2
// intrinsics (neighbour_lists.cpp; the portable filter is there). Private.
//
// Each appends to `out` the slots t0 + q (q < count) with |(xs - x_t, ys - y_t, zs - z_t)|^2 <
// rc2, in ascending order, and returns how many: (xs, ys, zs) is the row's position less the
// run's image shift, and xt, yt, zt are the positions by slot. They round as the portable filter
// rounds in the default (portable x86-64) build ((xs - x_t) - shift per axis; products and sums
// without fused multiply-adds), so all keep the same pairs; where the compiler may fuse the
// portable filter's products (-march=native), a pair within a rounding of r_cut may differ,
// whose block is below the tolerance there anyway.
#pragma once

#include <cstddef>

#include "rpyfmm/fmm/direct_simd.hpp"

#if defined(RPYFMM_HAVE_DIRECT_AVX512)

namespace rpyfmm::rpy::pse::detail {

/// Eight candidates at a time; `out` needs 16 entries of slack past the kept ones (one 512-bit
/// store of 16 slots). For half lists (t0 > the row's slot, which is then never a candidate).
RPYFMM_DIRECT_AVX512 std::size_t pairs_within_avx512(const double* xt, const double* yt, const double* zt,
                                                     std::size_t t0, std::size_t count, const double xs[3],
                                                     const double shift[3], double rc2, int* out);

/// Four candidates at a time, for CPUs with AVX2 but not the AVX-512 kernels (full lists, both
/// directions); the slot `skip` (the row's own; any other value: none) is never kept. `out`
/// needs 4 entries of slack past the kept ones.
__attribute__((target("avx2"))) std::size_t pairs_within_avx2(const double* xt, const double* yt, const double* zt,
                                                              std::size_t t0, std::size_t count, const double xs[3],
                                                              const double shift[3], double rc2, std::size_t skip,
                                                              int* out);

}  // namespace rpyfmm::rpy::pse::detail

#endif  // RPYFMM_HAVE_DIRECT_AVX512
