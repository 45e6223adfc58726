// Applies stored RPY pair blocks M_iq = f_q I + gr_q d_q d_q^T to one force vector (SoA):
// the accumulation loop shared by DirectRpy (per source block) and FmmRpy's block near field
// (per right-hand side, one or both directions). Inlined into each caller's instruction-set clones.
#pragma once

#include <cstddef>

namespace rpyfmm::rpy::detail {

/// (sx, sy, sz) = sum_q (f_q F_q + gr_q d_q (d_q . F_q)), q < m; with kBothWays also the
/// reverse direction of the same (symmetric) blocks: (ux, uy, uz)[q] += f_q F_i + gr_q d_q (d_q . F_i).
template <bool kBothWays>
[[gnu::always_inline]] inline void apply_pair_blocks(std::size_t m, const double* __restrict dx,
                                                     const double* __restrict dy, const double* __restrict dz,
                                                     const double* __restrict f, const double* __restrict gr,
                                                     const double* __restrict fx, const double* __restrict fy,
                                                     const double* __restrict fz, const double* fi,
                                                     double* __restrict ux_s, double* __restrict uy_s,
                                                     double* __restrict uz_s, double& sx, double& sy, double& sz) {
  const double fxi = kBothWays ? fi[0] : 0.0, fyi = kBothWays ? fi[1] : 0.0, fzi = kBothWays ? fi[2] : 0.0;
  double ux = 0.0, uy = 0.0, uz = 0.0;
#pragma omp simd reduction(+ : ux, uy, uz)
  for (std::size_t q = 0; q < m; ++q) {
    const double t = gr[q] * (dx[q] * fx[q] + dy[q] * fy[q] + dz[q] * fz[q]);
    ux += f[q] * fx[q] + t * dx[q];
    uy += f[q] * fy[q] + t * dy[q];
    uz += f[q] * fz[q] + t * dz[q];
    if constexpr (kBothWays) {
      const double ti = gr[q] * (dx[q] * fxi + dy[q] * fyi + dz[q] * fzi);
      ux_s[q] += f[q] * fxi + ti * dx[q];
      uy_s[q] += f[q] * fyi + ti * dy[q];
      uz_s[q] += f[q] * fzi + ti * dz[q];
    }
  }
  sx = ux;
  sy = uy;
  sz = uz;
}

/// One direction only (DirectRpy per source block, FmmRpy's one-sided block products).
[[gnu::always_inline]] inline void sum_pair_blocks(std::size_t m, const double* dx, const double* dy, const double* dz,
                                                   const double* f, const double* gr, const double* fx,
                                                   const double* fy, const double* fz, double& sx, double& sy,
                                                   double& sz) {
  apply_pair_blocks<false>(m, dx, dy, dz, f, gr, fx, fy, fz, nullptr, nullptr, nullptr, nullptr, sx, sy, sz);
}

}  // namespace rpyfmm::rpy::detail
