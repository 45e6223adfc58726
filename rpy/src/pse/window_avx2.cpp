// rpyfmm — AVX2 window kernels of the PSE wave space (window_avx2.hpp).
#include "window_avx2.hpp"

#include "rpyfmm/fmm/direct_simd.hpp"  // RPYFMM_HAVE_DIRECT_AVX512: GCC on x86-64, run-time dispatch

namespace rpyfmm::rpy::pse::detail {

bool avx2_window_kernels(int Pz) noexcept {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  return simd_level() >= SimdLevel::avx2 && Pz >= 1 && Pz <= 8;
#else
  (void)Pz;
  return false;
#endif
}

#if defined(RPYFMM_HAVE_DIRECT_AVX512)

#define RPYFMM_WINDOW_AVX2 __attribute__((target("avx2,fma")))

namespace {

/// Eight doubles as two 4-lane halves.
struct Pair {
  __m256d lo, hi;
};

/// The lanes of a run of len (0 ... 8) points: double halves lo (lanes 0-3) and hi (4-7), and
/// the eight float lanes; masks have the sign bit set in the lanes taken.
struct RunMask {
  __m256i lo, hi, all8;
  bool high;  // len > 4: the hi half has lanes
};

RPYFMM_WINDOW_AVX2 inline RunMask run_mask(int len) {
  const __m256i idx4 = _mm256_setr_epi64x(0, 1, 2, 3);
  const __m256i idx8 = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  return {_mm256_cmpgt_epi64(_mm256_set1_epi64x(len), idx4), _mm256_cmpgt_epi64(_mm256_set1_epi64x(len - 4), idx4),
          _mm256_cmpgt_epi32(_mm256_set1_epi32(len), idx8), len > 4};
}

RPYFMM_WINDOW_AVX2 inline Pair load_pair(const double* p, const RunMask& m) {
  return {_mm256_maskload_pd(p, m.lo), m.high ? _mm256_maskload_pd(p + 4, m.hi) : _mm256_setzero_pd()};
}

RPYFMM_WINDOW_AVX2 inline double sum_lanes(__m256d v) {
  alignas(32) double t[4];
  _mm256_store_pd(t, v);
  return (t[0] + t[1]) + (t[2] + t[3]);
}

/// One run of a grid line in the grid's precision: wz f per run, the masked read-modify-write of
/// spreading and the masked load (widened to double) of interpolation.
template <class Real>
struct Run;

template <>
struct Run<double> {
  using Vec = Pair;
  using Wxy = __m256d;
  RPYFMM_WINDOW_AVX2 static RunMask mask(int len) { return run_mask(len); }
  RPYFMM_WINDOW_AVX2 static Vec scaled(const double* w, const RunMask& m, int, double f) {
    const Pair wv = load_pair(w, m);
    const __m256d fv = _mm256_set1_pd(f);
    return {_mm256_mul_pd(wv.lo, fv), _mm256_mul_pd(wv.hi, fv)};
  }
  RPYFMM_WINDOW_AVX2 static Wxy broadcast(double v) { return _mm256_set1_pd(v); }
  RPYFMM_WINDOW_AVX2 static void add(double* p, const RunMask& m, Wxy w, const Vec& v) {
    _mm256_maskstore_pd(p, m.lo, _mm256_fmadd_pd(w, v.lo, _mm256_maskload_pd(p, m.lo)));
    if (m.high) _mm256_maskstore_pd(p + 4, m.hi, _mm256_fmadd_pd(w, v.hi, _mm256_maskload_pd(p + 4, m.hi)));
  }
  RPYFMM_WINDOW_AVX2 static Pair load(const double* p, const RunMask& m) { return load_pair(p, m); }
};

template <>
struct Run<float> {
  using Vec = __m256;
  using Wxy = __m256;
  RPYFMM_WINDOW_AVX2 static RunMask mask(int len) { return run_mask(len); }
  /// w f rounded to float, eight lanes.
  RPYFMM_WINDOW_AVX2 static Vec scaled(const double* w, const RunMask& m, int, double f) {
    const Pair wv = load_pair(w, m);
    const __m256d fv = _mm256_set1_pd(f);
    return _mm256_set_m128(_mm256_cvtpd_ps(_mm256_mul_pd(wv.hi, fv)), _mm256_cvtpd_ps(_mm256_mul_pd(wv.lo, fv)));
  }
  RPYFMM_WINDOW_AVX2 static Wxy broadcast(double v) { return _mm256_set1_ps(static_cast<float>(v)); }
  RPYFMM_WINDOW_AVX2 static void add(float* p, const RunMask& m, Wxy w, Vec v) {
    _mm256_maskstore_ps(p, m.all8, _mm256_fmadd_ps(w, v, _mm256_maskload_ps(p, m.all8)));
  }
  RPYFMM_WINDOW_AVX2 static Pair load(const float* p, const RunMask& m) {
    const __m256 v = _mm256_maskload_ps(p, m.all8);
    return {_mm256_cvtps_pd(_mm256_castps256_ps128(v)), _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1))};
  }
};

#define RPYFMM_WINDOW_TARGET RPYFMM_WINDOW_AVX2
#include "window_spread.inc"
#undef RPYFMM_WINDOW_TARGET

template <class Real>
RPYFMM_WINDOW_AVX2 void gather_window(const Real* g0, const Real* g1, const Real* g2, const std::size_t* xline,
                                      const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx,
                                      const double* wy, const double* wz, double u[3]) {
  using R = Run<Real>;
  const int len1 = z.Pz - z.len0;
  const RunMask m0 = run_mask(z.len0), m1 = run_mask(len1);
  const Pair w0 = load_pair(wz, m0), w1 = load_pair(wz + z.len0, m1);
  const Real* g[3] = {g0, g1, g2};
  Pair s[3];
  for (auto& v : s) v = {_mm256_setzero_pd(), _mm256_setzero_pd()};
  for (int a = 0; a < Px; ++a) {
    for (int b = 0; b < Py; ++b) {
      const std::size_t line = xline[a] + yline[b];
      const __m256d wxy = _mm256_set1_pd(wx[a] * wy[b]);
      for (int c = 0; c < 3; ++c) {
        // sum over the line of wz[l] g(l), lane by lane (in double); the lanes are summed at the end.
        const Pair v0 = R::load(g[c] + line + z.z0, m0);
        __m256d lo = _mm256_mul_pd(w0.lo, v0.lo), hi = _mm256_mul_pd(w0.hi, v0.hi);
        if (len1 > 0) {
          const Pair v1 = R::load(g[c] + line, m1);
          lo = _mm256_fmadd_pd(w1.lo, v1.lo, lo);
          hi = _mm256_fmadd_pd(w1.hi, v1.hi, hi);
        }
        s[c].lo = _mm256_fmadd_pd(wxy, lo, s[c].lo);
        s[c].hi = _mm256_fmadd_pd(wxy, hi, s[c].hi);
      }
    }
  }
  for (int c = 0; c < 3; ++c) u[c] += sum_lanes(_mm256_add_pd(s[c].lo, s[c].hi));
}

}  // namespace

void spread_window_avx2(double* g0, double* g1, double* g2, const std::size_t* xline, const std::size_t* yline, int Px,
                        int Py, WindowZ z, const double* wx, const double* wy, const double* wz, const double f[3]) {
  spread_window(g0, g1, g2, xline, yline, Px, Py, z, wx, wy, wz, f);
}
void spread_window_avx2(float* g0, float* g1, float* g2, const std::size_t* xline, const std::size_t* yline, int Px,
                        int Py, WindowZ z, const double* wx, const double* wy, const double* wz, const double f[3]) {
  spread_window(g0, g1, g2, xline, yline, Px, Py, z, wx, wy, wz, f);
}
void gather_window_avx2(const double* g0, const double* g1, const double* g2, const std::size_t* xline,
                        const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx, const double* wy,
                        const double* wz, double u[3]) {
  gather_window(g0, g1, g2, xline, yline, Px, Py, z, wx, wy, wz, u);
}
void gather_window_avx2(const float* g0, const float* g1, const float* g2, const std::size_t* xline,
                        const std::size_t* yline, int Px, int Py, WindowZ z, const double* wx, const double* wy,
                        const double* wz, double u[3]) {
  gather_window(g0, g1, g2, xline, yline, Px, Py, z, wx, wy, wz, u);
}

#else

void spread_window_avx2(double*, double*, double*, const std::size_t*, const std::size_t*, int, int, WindowZ,
                        const double*, const double*, const double*, const double*) {}
void spread_window_avx2(float*, float*, float*, const std::size_t*, const std::size_t*, int, int, WindowZ,
                        const double*, const double*, const double*, const double*) {}
void gather_window_avx2(const double*, const double*, const double*, const std::size_t*, const std::size_t*, int, int,
                        WindowZ, const double*, const double*, const double*, double*) {}
void gather_window_avx2(const float*, const float*, const float*, const std::size_t*, const std::size_t*, int, int,
                        WindowZ, const double*, const double*, const double*, double*) {}

#endif

}  // namespace rpyfmm::rpy::pse::detail
