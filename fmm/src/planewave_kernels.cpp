// Elementwise plane-wave kernels (planewave_kernels.hpp). Complex numbers are read as
// interleaved (re, im) doubles, which std::complex<double> guarantees ([complex.numbers]/4),
// so that GCC vectorizes the products without the C99 Annex G inf/nan path.
#include "planewave_kernels.hpp"

namespace rpyfmm::fmm::detail {

void shift_accumulate(std::size_t m, std::size_t nd, const cplx* sh, const cplx* w, cplx* acc) noexcept {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    const double* s = reinterpret_cast<const double*>(sh);
    for (std::size_t d = 0; d < nd; ++d) {
      const double* x = reinterpret_cast<const double*>(w + d * m);
      double* a = reinterpret_cast<double*>(acc + d * m);
#pragma omp simd
      for (std::size_t j = 0; j < m; ++j) {
        const double sr = s[2 * j], si = s[2 * j + 1], xr = x[2 * j], xi = x[2 * j + 1];
        a[2 * j] += sr * xr - si * xi;
        a[2 * j + 1] += sr * xi + si * xr;
      }
    }
  });
}

void shift_in_place(std::size_t m, std::size_t nd, const cplx* sh, cplx* v) noexcept {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    const double* s = reinterpret_cast<const double*>(sh);
    for (std::size_t d = 0; d < nd; ++d) {
      double* x = reinterpret_cast<double*>(v + d * m);
#pragma omp simd
      for (std::size_t j = 0; j < m; ++j) {
        const double sr = s[2 * j], si = s[2 * j + 1], xr = x[2 * j], xi = x[2 * j + 1];
        x[2 * j] = sr * xr - si * xi;
        x[2 * j + 1] = sr * xi + si * xr;
      }
    }
  });
}

void accumulate(std::size_t n, const cplx* src, cplx* dst) noexcept {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    const double* s = reinterpret_cast<const double*>(src);
    double* d = reinterpret_cast<double*>(dst);
#pragma omp simd
    for (std::size_t i = 0; i < 2 * n; ++i) d[i] += s[i];
  });
}

}  // namespace rpyfmm::fmm::detail
