// rpyfmm — the PSE wave-space line scaling (scale_line.hpp).
#include "scale_line.hpp"

#include <cmath>

#include "rpyfmm/fmm/direct_simd.hpp"  // RPYFMM_HAVE_DIRECT_AVX512: GCC on x86-64, run-time dispatch

namespace rpyfmm::rpy::pse::detail {
namespace {

/// The loop of scale_line. Det / Noisy select the terms (loop-invariant, so the loop has no
/// branch); c(k) = 0 (k = 0, Nyquist planes) gives exact zeros, as scale_mode_with's early return.
template <class Real, bool Det, bool Noisy>
[[gnu::always_inline]] inline void scale_line_body(const ModeGeometry& g, const ModeLine<Real>& line) {
  const double k0 = g.two_pi_L[0] * signed_index(line.ix, g.n[0]);
  const double k1 = g.two_pi_L[1] * signed_index(line.iy, g.n[1]);
  const double k01 = k0 * k0 + k1 * k1;
  const double tz = g.two_pi_L[2];
  const int nzh = g.nzh;
  const std::size_t base =
      (static_cast<std::size_t>(line.ix) * static_cast<std::size_t>(g.n[1]) + static_cast<std::size_t>(line.iy)) *
      static_cast<std::size_t>(nzh);
  const double* __restrict ck = line.ck + base;
  Real* __restrict s0 = line.spec + 2 * base;
  Real* __restrict s1 = s0 + g.comp_stride;
  Real* __restrict s2 = s1 + g.comp_stride;
  const Real* __restrict z = line.z;
  const std::size_t zs = line.z_stride;
  const Real* __restrict sign = line.sign;
  const double noise_factor = line.noise_factor;
#pragma omp simd
  for (int iz = 0; iz < nzh; ++iz) {
    const double c = ck[iz];
    const bool zero = c == 0.0;
    const double k2 = tz * iz;
    const double inv_k2 = 1.0 / (zero ? 1.0 : k01 + k2 * k2);
    double re0 = 0.0, re1 = 0.0, re2 = 0.0, im0 = 0.0, im1 = 0.0, im2 = 0.0;
    if constexpr (Det) {
      re0 = c * s0[2 * iz];
      re1 = c * s1[2 * iz];
      re2 = c * s2[2 * iz];
      im0 = c * s0[2 * iz + 1];
      im1 = c * s1[2 * iz + 1];
      im2 = c * s2[2 * iz + 1];
    }
    if constexpr (Noisy) {
      // z = (a + i b)/sqrt(2); conjugate off the representative (scale_mode_with).
      const double amp = noise_factor * std::sqrt(c) * 0.70710678118654752440;
      const double sgn = amp * static_cast<double>(sign[iz]);  // +-amp exactly
      re0 += amp * z[iz];
      re1 += amp * z[zs + iz];
      re2 += amp * z[2 * zs + iz];
      im0 += sgn * z[3 * zs + iz];
      im1 += sgn * z[4 * zs + iz];
      im2 += sgn * z[5 * zs + iz];
    }
    // Projection I - k k^T / k^2 on the real and imaginary parts.
    const double pr = (k0 * re0 + k1 * re1 + k2 * re2) * inv_k2;
    const double pi = (k0 * im0 + k1 * im1 + k2 * im2) * inv_k2;
    s0[2 * iz] = zero ? Real(0) : static_cast<Real>(re0 - k0 * pr);
    s0[2 * iz + 1] = zero ? Real(0) : static_cast<Real>(im0 - k0 * pi);
    s1[2 * iz] = zero ? Real(0) : static_cast<Real>(re1 - k1 * pr);
    s1[2 * iz + 1] = zero ? Real(0) : static_cast<Real>(im1 - k1 * pi);
    s2[2 * iz] = zero ? Real(0) : static_cast<Real>(re2 - k2 * pr);
    s2[2 * iz + 1] = zero ? Real(0) : static_cast<Real>(im2 - k2 * pi);
  }
}

/// The loop of line_noise_keys: mode_pair's lin and partner per iz, in 64-bit lanes.
template <class Real>
[[gnu::always_inline]] inline void line_noise_keys_body(const ModeGeometry& g, int ix, int iy,
                                                        std::uint64_t* __restrict rep, Real* __restrict sign) {
  const auto nx = static_cast<std::uint64_t>(g.n[0]);
  const auto ny = static_cast<std::uint64_t>(g.n[1]);
  const auto nz = static_cast<std::uint64_t>(g.n[2]);
  const auto ux = static_cast<std::uint64_t>(ix);
  const auto uy = static_cast<std::uint64_t>(iy);
  const std::uint64_t lin0 = (ux * ny + uy) * nz;
  const std::uint64_t px = ix == 0 ? 0 : nx - ux;
  const std::uint64_t py = iy == 0 ? 0 : ny - uy;
  const std::uint64_t partner0 = (px * ny + py) * nz;
  const int nzh = g.nzh;
#pragma omp simd
  for (int iz = 0; iz < nzh; ++iz) {
    const auto uz = static_cast<std::uint64_t>(iz);
    const std::uint64_t lin = lin0 + uz;
    const std::uint64_t partner = partner0 + (iz == 0 ? 0 : nz - uz);
    rep[iz] = lin < partner ? lin : partner;
    sign[iz] = lin <= partner ? Real(1) : Real(-1);
  }
}

template <class Real>
[[gnu::always_inline]] inline void scale_line_dispatch(const ModeGeometry& g, const ModeLine<Real>& line) {
  const bool noisy = line.z != nullptr;
  if (line.deterministic && noisy) {
    scale_line_body<Real, true, true>(g, line);
  } else if (line.deterministic) {
    scale_line_body<Real, true, false>(g, line);
  } else if (noisy) {
    scale_line_body<Real, false, true>(g, line);
  } else {
    scale_line_body<Real, false, false>(g, line);
  }
}

template <class Real>
void scale_line_portable(const ModeGeometry& g, const ModeLine<Real>& line) {
  scale_line_dispatch(g, line);
}

#if defined(RPYFMM_HAVE_DIRECT_AVX512)
template <class Real>
__attribute__((target("avx2,fma"))) void scale_line_avx2(const ModeGeometry& g, const ModeLine<Real>& line) {
  scale_line_dispatch(g, line);
}

template <class Real>
__attribute__((target("avx512f,avx512vl,avx512dq,prefer-vector-width=512"))) void scale_line_avx512(
    const ModeGeometry& g, const ModeLine<Real>& line) {
  scale_line_dispatch(g, line);
}
#endif

template <class Real>
void line_noise_keys_portable(const ModeGeometry& g, int ix, int iy, std::uint64_t* rep, Real* sign) {
  line_noise_keys_body(g, ix, iy, rep, sign);
}

#if defined(RPYFMM_HAVE_DIRECT_AVX512)
template <class Real>
__attribute__((target("avx2,fma"))) void line_noise_keys_avx2(const ModeGeometry& g, int ix, int iy, std::uint64_t* rep,
                                                              Real* sign) {
  line_noise_keys_body(g, ix, iy, rep, sign);
}

template <class Real>
__attribute__((target("avx512f,avx512vl,avx512dq,prefer-vector-width=512"))) void line_noise_keys_avx512(
    const ModeGeometry& g, int ix, int iy, std::uint64_t* rep, Real* sign) {
  line_noise_keys_body(g, ix, iy, rep, sign);
}
#endif

#if defined(RPYFMM_HAVE_DIRECT_AVX512)
/// Which build of a loop runs: the one simd_level() names (AVX-512, AVX2 with FMA, or portable).
enum class LineKernels { portable, avx2, avx512 };
LineKernels line_kernels() {
  if (simd_level() == SimdLevel::avx512) return LineKernels::avx512;
  if (simd_level() == SimdLevel::avx2) return LineKernels::avx2;
  return LineKernels::portable;
}
#endif

template <class Real>
void scale_line_any(const ModeGeometry& g, const ModeLine<Real>& line) {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  const LineKernels k = line_kernels();
  if (k == LineKernels::avx512) return scale_line_avx512(g, line);
  if (k == LineKernels::avx2) return scale_line_avx2(g, line);
#endif
  scale_line_portable(g, line);
}

template <class Real>
void line_noise_keys_any(const ModeGeometry& g, int ix, int iy, std::uint64_t* rep, Real* sign) {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  const LineKernels k = line_kernels();
  if (k == LineKernels::avx512) return line_noise_keys_avx512(g, ix, iy, rep, sign);
  if (k == LineKernels::avx2) return line_noise_keys_avx2(g, ix, iy, rep, sign);
#endif
  line_noise_keys_portable(g, ix, iy, rep, sign);
}

}  // namespace

void scale_line(const ModeGeometry& g, const ModeLine<double>& line) {
  scale_line_any(g, line);
}
void scale_line(const ModeGeometry& g, const ModeLine<float>& line) {
  scale_line_any(g, line);
}
void line_noise_keys(const ModeGeometry& g, int ix, int iy, std::uint64_t* rep, double* sign) {
  line_noise_keys_any(g, ix, iy, rep, sign);
}
void line_noise_keys(const ModeGeometry& g, int ix, int iy, std::uint64_t* rep, float* sign) {
  line_noise_keys_any(g, ix, iy, rep, sign);
}

}  // namespace rpyfmm::rpy::pse::detail
