// Applies stored RPY pair blocks M_iq = f_q I + gr_q d_q d_q^T to one force vector (SoA):
// the accumulation loop shared by DirectRpy (per source block) and FmmRpy's block near field
// (per right-hand side). Inlined into each caller's instruction-set clones.
#pragma once

#include <cstddef>

namespace rpyfmm::rpy::detail {

/// (sx, sy, sz) = sum_q (f_q F_q + gr_q d_q (d_q . F_q)), q < m.
[[gnu::always_inline]] inline void sum_pair_blocks(std::size_t m, const double* __restrict dx,
                                                   const double* __restrict dy, const double* __restrict dz,
                                                   const double* __restrict f, const double* __restrict gr,
                                                   const double* __restrict fx, const double* __restrict fy,
                                                   const double* __restrict fz, double& sx, double& sy, double& sz) {
  double ux = 0.0, uy = 0.0, uz = 0.0;
#pragma omp simd reduction(+ : ux, uy, uz)
  for (std::size_t q = 0; q < m; ++q) {
    const double t = gr[q] * (dx[q] * fx[q] + dy[q] * fy[q] + dz[q] * fz[q]);
    ux += f[q] * fx[q] + t * dx[q];
    uy += f[q] * fy[q] + t * dy[q];
    uz += f[q] * fz[q] + t * dz[q];
  }
  sx = ux;
  sy = uy;
  sz = uz;
}

}  // namespace rpyfmm::rpy::detail
