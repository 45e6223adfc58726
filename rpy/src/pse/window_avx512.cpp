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

/// Sum of the 8 lanes (GCC 12's _mm512_reduce_add_pd trips -Wuninitialized in its own header).
RPYFMM_DIRECT_AVX512 inline double sum_lanes(__m512d v) {
  alignas(64) double t[8];
  _mm512_store_pd(t, v);
  return ((t[0] + t[1]) + (t[2] + t[3])) + ((t[4] + t[5]) + (t[6] + t[7]));
}

/// One run of a grid line (at most 8 points) in the grid's precision: the masked
/// read-modify-write of spreading and the masked load (widened to double) of interpolation.
template <class Real>
struct Run;

template <>
struct Run<double> {
  using Vec = __m512d;
  using Mask = __mmask8;
  RPYFMM_DIRECT_AVX512 static Mask mask(int len) { return lanes(len); }
  /// w[0 ... len) f in lanes 0 ... len - 1, zeros above.
  RPYFMM_DIRECT_AVX512 static Vec scaled(const double* w, Mask m, int, double f) {
    return _mm512_mul_pd(_mm512_maskz_loadu_pd(m, w), _mm512_set1_pd(f));
  }
  RPYFMM_DIRECT_AVX512 static Vec broadcast(double v) { return _mm512_set1_pd(v); }
  /// p[0 ... len) += w * v.
  RPYFMM_DIRECT_AVX512 static void add(double* p, Mask m, Vec w, Vec v) {
    _mm512_mask_storeu_pd(p, m, _mm512_fmadd_pd(w, v, _mm512_maskz_loadu_pd(m, p)));
  }
  RPYFMM_DIRECT_AVX512 static __m512d load(const double* p, Mask m) { return _mm512_maskz_loadu_pd(m, p); }
};

template <>
struct Run<float> {
  using Vec = __m512;  // lanes 0 ... 7 used
  using Mask = __mmask16;
  RPYFMM_DIRECT_AVX512 static Mask mask(int len) { return lanes(len); }
  /// w[0 ... len) f rounded to float in lanes 0 ... len - 1, zeros above (once per particle).
  RPYFMM_DIRECT_AVX512 static Vec scaled(const double* w, Mask, int len, double f) {
    alignas(64) float t[16] = {};
    for (int l = 0; l < len; ++l) t[l] = static_cast<float>(w[l] * f);
    return _mm512_load_ps(t);
  }
  RPYFMM_DIRECT_AVX512 static Vec broadcast(double v) { return _mm512_set1_ps(static_cast<float>(v)); }
  /// p[0 ... len) += w * v, in float.
  RPYFMM_DIRECT_AVX512 static void add(float* p, Mask m, Vec w, Vec v) {
    _mm512_mask_storeu_ps(p, m, _mm512_fmadd_ps(w, v, _mm512_maskz_loadu_ps(m, p)));
  }
  /// Float lanes 0 ... 7 widened to double (the maskz forms: GCC 12's plain conversions and
  /// extracts read an undefined register and trip -Wmaybe-uninitialized).
  RPYFMM_DIRECT_AVX512 static __m512d load(const float* p, Mask m) {
    const __m512d v = _mm512_castps_pd(_mm512_maskz_loadu_ps(m, p));
    return _mm512_maskz_cvtps_pd(0xFF, _mm256_castpd_ps(_mm512_maskz_extractf64x4_pd(0x0F, v, 0)));
  }
};

#define RPYFMM_WINDOW_TARGET RPYFMM_DIRECT_AVX512
#include "window_spread.inc"
#undef RPYFMM_WINDOW_TARGET

template <class Real>
RPYFMM_DIRECT_AVX512 void gather_window(const Real* g0, const Real* g1, const Real* g2, const std::size_t* xline,
                                        const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx,
                                        const double* wy, const double* wz, double u[3]) {
  using R = Run<Real>;
  const int len1 = z.Pz - z.len0;
  const auto m0 = R::mask(z.len0), m1 = R::mask(len1);
  const __m512d w0 = _mm512_maskz_loadu_pd(lanes(z.len0), wz), w1 = _mm512_maskz_loadu_pd(lanes(len1), wz + z.len0);
  __m512d s0 = _mm512_setzero_pd(), s1 = _mm512_setzero_pd(), s2 = _mm512_setzero_pd();
  for (int a = 0; a < Px; ++a) {
    for (int b = 0; b < Py; ++b) {
      const std::size_t line = xline[a] + yline[b];
      const __m512d wxy = _mm512_set1_pd(wx[a] * wy[b]);
      // sum over the line of wz[l] g(l), lane by lane (in double); the lanes are summed once at the end.
      __m512d t0 = _mm512_mul_pd(w0, R::load(g0 + line + z.z0, m0));
      __m512d t1 = _mm512_mul_pd(w0, R::load(g1 + line + z.z0, m0));
      __m512d t2 = _mm512_mul_pd(w0, R::load(g2 + line + z.z0, m0));
      if (len1 > 0) {
        t0 = _mm512_fmadd_pd(w1, R::load(g0 + line, m1), t0);
        t1 = _mm512_fmadd_pd(w1, R::load(g1 + line, m1), t1);
        t2 = _mm512_fmadd_pd(w1, R::load(g2 + line, m1), t2);
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

}  // namespace

void spread_window_avx512(double* g0, double* g1, double* g2, const std::size_t* xline, const std::size_t* yline,
                          int Px, int Py, WindowZ z, const double* wx, const double* wy, const double* wz,
                          const double f[3]) {
  spread_window(g0, g1, g2, xline, yline, Px, Py, z, wx, wy, wz, f);
}
void spread_window_avx512(float* g0, float* g1, float* g2, const std::size_t* xline, const std::size_t* yline, int Px,
                          int Py, WindowZ z, const double* wx, const double* wy, const double* wz, const double f[3]) {
  spread_window(g0, g1, g2, xline, yline, Px, Py, z, wx, wy, wz, f);
}
void gather_window_avx512(const double* g0, const double* g1, const double* g2, const std::size_t* xline,
                          const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx, const double* wy,
                          const double* wz, double u[3]) {
  gather_window(g0, g1, g2, xline, yline, Px, Py, z, wx, wy, wz, u);
}
void gather_window_avx512(const float* g0, const float* g1, const float* g2, const std::size_t* xline,
                          const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx, const double* wy,
                          const double* wz, double u[3]) {
  gather_window(g0, g1, g2, xline, yline, Px, Py, z, wx, wy, wz, u);
}

#else

void spread_window_avx512(float*, float*, float*, const std::size_t*, const std::size_t*, int, int, WindowZ,
                          const double*, const double*, const double*, const double*) {}
void gather_window_avx512(const float*, const float*, const float*, const std::size_t*, const std::size_t*, int, int,
                          WindowZ, const double*, const double*, const double*, double*) {}
void spread_window_avx512(double*, double*, double*, const std::size_t*, const std::size_t*, int, int, WindowZ,
                          const double*, const double*, const double*, const double*) {}
void gather_window_avx512(const double*, const double*, const double*, const std::size_t*, const std::size_t*, int, int,
                          WindowZ, const double*, const double*, const double*, double*) {}

#endif

}  // namespace rpyfmm::rpy::pse::detail
