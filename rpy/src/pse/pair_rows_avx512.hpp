// rpyfmm — the AVX-512 rows of the PSE real-space product ([PSE] eq. 10 with App. A via the
// linear table; docs/theory/pse.md), run where simd_level() is SimdLevel::avx512. Private.
//
// Every row reads its neighbours from `packed` rows of eight doubles per slot (x, y, z, fx, fy,
// fz, 0, 0; 64-byte aligned), eight neighbours at a time, and sums M_r f / M0 without the self
// term. L, inv_L: the box and its inverse; table, inv_dr: the linear table (PseRealSpaceTable).
#pragma once

#include <cstddef>

#include "rpyfmm/fmm/direct_simd.hpp"

#if defined(RPYFMM_HAVE_DIRECT_AVX512)

namespace rpyfmm::rpy::pse::detail {

/// u += the full row of slot `self` over its neighbours nb[0..count).
RPYFMM_DIRECT_AVX512 void packed_row_avx512(const int* nb, std::size_t count, std::size_t self, const double* packed,
                                            const double* table, double inv_dr, const double L[3],
                                            const double inv_L[3], double u[3]);

/// The half row of slot `self` over its neighbours with larger slots nb[0..count): each pair's
/// block B_st once, added to both rows (acc: rows of four doubles per slot, x, y, z, 0). With a
/// pair cache (T = float or double), the blocks are kept at `cache` (five vectors of eight lanes
/// per chunk of eight pairs: F - F(0), G - G(0), e_x, e_y, e_z) and applied as kept; T = void:
/// no cache.
template <class T>
RPYFMM_DIRECT_AVX512 void packed_half_row_avx512(const int* nb, std::size_t count, std::size_t self,
                                                 const double* packed, const double* table, double inv_dr,
                                                 const double L[3], const double inv_L[3], double* acc, T* cache);

/// The half row from the filled pair cache, on force rows of four doubles per slot (fx, fy, fz,
/// 0): the pairs are not evaluated again.
template <class T>
RPYFMM_DIRECT_AVX512 void cached_half_row_avx512(const int* nb, std::size_t count, std::size_t self,
                                                 const double* forces, const T* cache, const double* table,
                                                 double* acc);

}  // namespace rpyfmm::rpy::pse::detail

#endif  // RPYFMM_HAVE_DIRECT_AVX512
