// rpyfmm — AVX-512 window kernels of the PSE wave space (window_avx512.hpp).
#include "window_avx512.hpp"

#include "rpyfmm/fmm/direct_simd.hpp"

namespace rpyfmm::rpy::pse::detail {

bool avx512_window_kernels(int Pz) noexcept {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  return Pz >= 1 && Pz <= 8 && fmm::detail::avx512_kernels_active();
#else
  (void)Pz;
  return false;
#endif
}

#if defined(RPYFMM_HAVE_DIRECT_AVX512)

namespace {

/// Lanes 0 ... len - 1 (len in 0 ... 8).
RPYFMM_DIRECT_AVX512 inline __mmask8 lanes(int len) {
  return static_cast<__mmask8>((1u << len) - 1u);
}

/// p[0 ... len) += w * v (masked read-modify-write of one run).
RPYFMM_DIRECT_AVX512 inline void add_run(double* p, __mmask8 m, __m512d w, __m512d v) {
  _mm512_mask_storeu_pd(p, m, _mm512_fmadd_pd(w, v, _mm512_maskz_loadu_pd(m, p)));
}

/// Sum of the 8 lanes (GCC 12's _mm512_reduce_add_pd trips -Wuninitialized in its own header).
RPYFMM_DIRECT_AVX512 inline double sum_lanes(__m512d v) {
  alignas(64) double t[8];
  _mm512_store_pd(t, v);
  return ((t[0] + t[1]) + (t[2] + t[3])) + ((t[4] + t[5]) + (t[6] + t[7]));
}

}  // namespace

RPYFMM_DIRECT_AVX512 void spread_window_avx512(double* g0, double* g1, double* g2, const std::size_t* xline,
                                               const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx,
                                               const double* wy, const double* wz, const double f[3]) {
  const int len1 = z.Pz - z.len0;
  const __mmask8 m0 = lanes(z.len0), m1 = lanes(len1);
  // wz f_c on each run: lanes of the first run, then those that wrap.
  const __m512d w0 = _mm512_maskz_loadu_pd(m0, wz), w1 = _mm512_maskz_loadu_pd(m1, wz + z.len0);
  const __m512d a0 = _mm512_mul_pd(w0, _mm512_set1_pd(f[0])), b0 = _mm512_mul_pd(w1, _mm512_set1_pd(f[0]));
  const __m512d a1 = _mm512_mul_pd(w0, _mm512_set1_pd(f[1])), b1 = _mm512_mul_pd(w1, _mm512_set1_pd(f[1]));
  const __m512d a2 = _mm512_mul_pd(w0, _mm512_set1_pd(f[2])), b2 = _mm512_mul_pd(w1, _mm512_set1_pd(f[2]));
  for (int a = 0; a < Px; ++a) {
    for (int b = 0; b < Py; ++b) {
      const std::size_t line = xline[a] + yline[b];
      const __m512d wxy = _mm512_set1_pd(wx[a] * wy[b]);
      add_run(g0 + line + z.z0, m0, wxy, a0);
      add_run(g1 + line + z.z0, m0, wxy, a1);
      add_run(g2 + line + z.z0, m0, wxy, a2);
      if (len1 > 0) {
        add_run(g0 + line, m1, wxy, b0);
        add_run(g1 + line, m1, wxy, b1);
        add_run(g2 + line, m1, wxy, b2);
      }
    }
  }
}

RPYFMM_DIRECT_AVX512 void gather_window_avx512(const double* g0, const double* g1, const double* g2,
                                               const std::size_t* xline, const std::size_t* yline, int Px, int Py,
                                               WindowZ z, const double* wx, const double* wy, const double* wz,
                                               double u[3]) {
  const int len1 = z.Pz - z.len0;
  const __mmask8 m0 = lanes(z.len0), m1 = lanes(len1);
  const __m512d w0 = _mm512_maskz_loadu_pd(m0, wz), w1 = _mm512_maskz_loadu_pd(m1, wz + z.len0);
  __m512d s0 = _mm512_setzero_pd(), s1 = _mm512_setzero_pd(), s2 = _mm512_setzero_pd();
  for (int a = 0; a < Px; ++a) {
    for (int b = 0; b < Py; ++b) {
      const std::size_t line = xline[a] + yline[b];
      const __m512d wxy = _mm512_set1_pd(wx[a] * wy[b]);
      // sum over the line of wz[l] g(l), lane by lane; the lanes are summed once at the end.
      __m512d t0 = _mm512_mul_pd(w0, _mm512_maskz_loadu_pd(m0, g0 + line + z.z0));
      __m512d t1 = _mm512_mul_pd(w0, _mm512_maskz_loadu_pd(m0, g1 + line + z.z0));
      __m512d t2 = _mm512_mul_pd(w0, _mm512_maskz_loadu_pd(m0, g2 + line + z.z0));
      if (len1 > 0) {
        t0 = _mm512_fmadd_pd(w1, _mm512_maskz_loadu_pd(m1, g0 + line), t0);
        t1 = _mm512_fmadd_pd(w1, _mm512_maskz_loadu_pd(m1, g1 + line), t1);
        t2 = _mm512_fmadd_pd(w1, _mm512_maskz_loadu_pd(m1, g2 + line), t2);
      }
      s0 = _mm512_fmadd_pd(wxy, t0, s0);
      s1 = _mm512_fmadd_pd(wxy, t1, s1);
      s2 = _mm512_fmadd_pd(wxy, t2, s2);
    }
  }
  u[0] += sum_lanes(s0);
  u[1] += sum_lanes(s1);
  u[2] += sum_lanes(s2);
}

#else

void spread_window_avx512(double*, double*, double*, const std::size_t*, const std::size_t*, int, int, WindowZ,
                          const double*, const double*, const double*, const double*) {}
void gather_window_avx512(const double*, const double*, const double*, const std::size_t*, const std::size_t*, int, int,
                          WindowZ, const double*, const double*, const double*, double*) {}

#endif

}  // namespace rpyfmm::rpy::pse::detail
