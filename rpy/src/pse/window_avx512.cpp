// rpyfmm — AVX-512 window kernels of the PSE wave space (window_avx512.hpp).
#include "window_avx512.hpp"

#include "rpyfmm/fmm/direct_simd.hpp"

namespace rpyfmm::rpy::pse::detail {

bool avx512_window_kernels(int Pz) noexcept {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  return Pz >= 1 && Pz <= 8 && simd_level() == SimdLevel::avx512;  // x86-64-v4: AVX-512F and VL
#else
  (void)Pz;
  return false;
#endif
}

#if defined(RPYFMM_HAVE_DIRECT_AVX512)

// AVX-512F with the 256-bit forms of VL (single-precision runs).
#define RPYFMM_WINDOW_VL __attribute__((target("avx512f,avx512vl,fma")))

namespace {

/// Lanes 0 ... len - 1 (len in 0 ... 8).
RPYFMM_WINDOW_VL inline __mmask8 lanes(int len) {
  return static_cast<__mmask8>((1u << len) - 1u);
}

/// Sum of the 8 lanes, pairwise in registers (GCC 12's _mm512_reduce_add_pd trips
/// -Wuninitialized in its own header).
RPYFMM_WINDOW_VL inline double sum_lanes(__m512d v) {
  return fmm::detail::sum_lanes_pairwise(v);
}

/// One run of a grid line (at most 8 points) in the grid's precision: the masked
/// read-modify-write of spreading and the masked load (widened to double) of interpolation.
template <class Real>
struct Run;

template <>
struct Run<double> {
  using Vec = __m512d;
  using Mask = __mmask8;
  RPYFMM_WINDOW_VL static Mask mask(int len) { return lanes(len); }
  /// w[0 ... len) f in lanes 0 ... len - 1, zeros above.
  RPYFMM_WINDOW_VL static Vec scaled(const double* w, Mask m, int, double f) {
    return _mm512_mul_pd(_mm512_maskz_loadu_pd(m, w), _mm512_set1_pd(f));
  }
  RPYFMM_WINDOW_VL static Vec broadcast(double v) { return _mm512_set1_pd(v); }
  /// p[0 ... len) += w * v.
  RPYFMM_WINDOW_VL static void add(double* p, Mask m, Vec w, Vec v) {
    _mm512_mask_storeu_pd(p, m, _mm512_fmadd_pd(w, v, _mm512_maskz_loadu_pd(m, p)));
  }
  RPYFMM_WINDOW_VL static __m512d load(const double* p, Mask m) { return _mm512_maskz_loadu_pd(m, p); }
};

/// Single-precision grids: a run of at most 8 floats is one 256-bit masked vector (AVX-512VL).
/// A 512-bit one, though masked, spans 64 bytes: it crosses a cache line for most window starts
/// and overlaps the neighbouring particles' runs, so that loads wait for earlier masked
/// stores (measured: spreading 1.25x slower at 128000 particles).
template <>
struct Run<float> {
  using Vec = __m256;
  using Mask = __mmask8;
  RPYFMM_WINDOW_VL static Mask mask(int len) { return lanes(len); }
  /// w[0 ... len) f rounded to float in lanes 0 ... len - 1, zeros above (once per particle).
  RPYFMM_WINDOW_VL static Vec scaled(const double* w, Mask m, int, double f) {
    return _mm512_maskz_cvtpd_ps(0xFF, _mm512_mul_pd(_mm512_maskz_loadu_pd(m, w), _mm512_set1_pd(f)));
  }
  RPYFMM_WINDOW_VL static Vec broadcast(double v) { return _mm256_set1_ps(static_cast<float>(v)); }
  /// p[0 ... len) += w * v, in float.
  RPYFMM_WINDOW_VL static void add(float* p, Mask m, Vec w, Vec v) {
    _mm256_mask_storeu_ps(p, m, _mm256_fmadd_ps(w, v, _mm256_maskz_loadu_ps(m, p)));
  }
  /// Float lanes 0 ... 7 widened to double (the maskz forms of the conversions: GCC 12's plain
  /// ones read an undefined register and trip -Wmaybe-uninitialized).
  RPYFMM_WINDOW_VL static __m512d load(const float* p, Mask m) {
    return _mm512_maskz_cvtps_pd(0xFF, _mm256_maskz_loadu_ps(m, p));
  }
};

#define RPYFMM_WINDOW_TARGET RPYFMM_WINDOW_VL
#include "window_spread.inc"
#undef RPYFMM_WINDOW_TARGET

template <class Real>
RPYFMM_WINDOW_VL void gather_window(const Real* g0, const Real* g1, const Real* g2, const std::size_t* xline,
                                    const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx,
                                    const double* wy, const double* wz, double u[3]) {
  using R = Run<Real>;
  const int len1 = z.Pz - z.len0;
  const auto m0 = R::mask(z.len0), m1 = R::mask(len1);
  const __m512d w0 = _mm512_maskz_loadu_pd(lanes(z.len0), wz), w1 = _mm512_maskz_loadu_pd(lanes(len1), wz + z.len0);
  // Lane by lane (in double): the sum over y of wy[b] g(line) per x plane, then wx[a] wz times
  // that; the lanes (z) are summed once at the end.
  __m512d s0 = _mm512_setzero_pd(), s1 = _mm512_setzero_pd(), s2 = _mm512_setzero_pd();
  for (int a = 0; a < Px; ++a) {
    __m512d r0 = _mm512_setzero_pd(), r1 = _mm512_setzero_pd(), r2 = _mm512_setzero_pd();
    __m512d q0 = _mm512_setzero_pd(), q1 = _mm512_setzero_pd(), q2 = _mm512_setzero_pd();
    for (int b = 0; b < Py; ++b) {
      const std::size_t line = xline[a] + yline[b];
      const __m512d wb = _mm512_set1_pd(wy[b]);
      r0 = _mm512_fmadd_pd(wb, R::load(g0 + line + z.z0, m0), r0);
      r1 = _mm512_fmadd_pd(wb, R::load(g1 + line + z.z0, m0), r1);
      r2 = _mm512_fmadd_pd(wb, R::load(g2 + line + z.z0, m0), r2);
      if (len1 > 0) {
        q0 = _mm512_fmadd_pd(wb, R::load(g0 + line, m1), q0);
        q1 = _mm512_fmadd_pd(wb, R::load(g1 + line, m1), q1);
        q2 = _mm512_fmadd_pd(wb, R::load(g2 + line, m1), q2);
      }
    }
    const __m512d wa = _mm512_set1_pd(wx[a]);
    const __m512d v0 = _mm512_mul_pd(wa, w0);
    s0 = _mm512_fmadd_pd(v0, r0, s0);
    s1 = _mm512_fmadd_pd(v0, r1, s1);
    s2 = _mm512_fmadd_pd(v0, r2, s2);
    if (len1 > 0) {
      const __m512d v1 = _mm512_mul_pd(wa, w1);
      s0 = _mm512_fmadd_pd(v1, q0, s0);
      s1 = _mm512_fmadd_pd(v1, q1, s1);
      s2 = _mm512_fmadd_pd(v1, q2, s2);
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
