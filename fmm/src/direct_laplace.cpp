// rpyfmm — direct Laplace sums (see direct.hpp for the formulas).
//
// One target at a time against a contiguous run of sources, with the sources
// in structure-of-arrays form and no branches in the inner loop (the r = 0
// skip is a select on 1/r). Two implementations of the same loops:
//  - portable C++ that GCC vectorizes (simd_dispatch: baseline / AVX2 / AVX-512),
//    1/r = 1/sqrt(r^2) by sqrt and division;
//  - AVX-512F intrinsics, 1/r by rsqrt14 + two Newton steps (direct_simd.hpp),
//    chosen where simd_level() is avx512 (2-3x the pairs per second).
// The requested outputs are template parameters, so the potential alone costs
// 1/r and one multiply-add per pair. Several charge vectors share the
// geometry: per block of sources, d = x - y, 1/r and 1/r^2 are computed once
// and reused for every density.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"

namespace rpyfmm::fmm {

namespace {

constexpr std::size_t kBlock = 512;  // sources per geometry block (multi-density path)

// One target, one density, all sources: out[0..9] += contributions.
template <bool P, bool G, bool H>
[[gnu::always_inline]] inline void p2p_single(double tx, double ty, double tz, const double* __restrict sx,
                                              const double* __restrict sy, const double* __restrict sz,
                                              const double* __restrict q, std::size_t ns, double* __restrict out) {
  double pot = 0, gx = 0, gy = 0, gz = 0, hxx = 0, hyy = 0, hzz = 0, hxy = 0, hxz = 0, hyz = 0;
#pragma omp simd reduction(+ : pot, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz)
  for (std::size_t j = 0; j < ns; ++j) {
    const double dx = tx - sx[j], dy = ty - sy[j], dz = tz - sz[j];
    const double r2 = dx * dx + dy * dy + dz * dz;
    const double ir = r2 > 0.0 ? 1.0 / std::sqrt(r2) : 0.0;  // skip r = 0
    const double qir = q[j] * ir;
    if constexpr (P) pot += qir;
    if constexpr (G || H) {
      const double ir2 = ir * ir;
      const double qir3 = qir * ir2;
      if constexpr (G) {
        gx -= qir3 * dx;
        gy -= qir3 * dy;
        gz -= qir3 * dz;
      }
      if constexpr (H) {
        const double w = 3.0 * qir3 * ir2;
        const double wx = w * dx, wy = w * dy;
        hxx += wx * dx - qir3;
        hyy += wy * dy - qir3;
        hzz += w * dz * dz - qir3;
        hxy += wx * dy;
        hxz += wx * dz;
        hyz += wy * dz;
      }
    }
  }
  if constexpr (P) out[col_pot] += pot;
  if constexpr (G) {
    out[col_gx] += gx;
    out[col_gy] += gy;
    out[col_gz] += gz;
  }
  if constexpr (H) {
    out[col_hxx] += hxx;
    out[col_hyy] += hyy;
    out[col_hzz] += hzz;
    out[col_hxy] += hxy;
    out[col_hxz] += hxz;
    out[col_hyz] += hyz;
  }
}

// Geometry of one target against a block: dx, dy, dz, 1/r (0 at r = 0), 1/r^2.
[[gnu::always_inline]] inline void geometry_block(double tx, double ty, double tz, const double* __restrict sx,
                                                  const double* __restrict sy, const double* __restrict sz,
                                                  std::size_t nb, double* __restrict dx, double* __restrict dy,
                                                  double* __restrict dz, double* __restrict ir,
                                                  double* __restrict ir2) {
#pragma omp simd
  for (std::size_t j = 0; j < nb; ++j) {
    const double ddx = tx - sx[j], ddy = ty - sy[j], ddz = tz - sz[j];
    const double r2 = ddx * ddx + ddy * ddy + ddz * ddz;
    const double v = r2 > 0.0 ? 1.0 / std::sqrt(r2) : 0.0;
    dx[j] = ddx;
    dy[j] = ddy;
    dz[j] = ddz;
    ir[j] = v;
    ir2[j] = v * v;
  }
}

// One density over a precomputed geometry block.
template <bool P, bool G, bool H>
[[gnu::always_inline]] inline void p2p_from_geometry(const double* __restrict dx, const double* __restrict dy,
                                                     const double* __restrict dz, const double* __restrict ir,
                                                     const double* __restrict ir2, const double* __restrict q,
                                                     std::size_t nb, double* __restrict out) {
  double pot = 0, gx = 0, gy = 0, gz = 0, hxx = 0, hyy = 0, hzz = 0, hxy = 0, hxz = 0, hyz = 0;
#pragma omp simd reduction(+ : pot, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz)
  for (std::size_t j = 0; j < nb; ++j) {
    const double qir = q[j] * ir[j];
    if constexpr (P) pot += qir;
    if constexpr (G || H) {
      const double qir3 = qir * ir2[j];
      if constexpr (G) {
        gx -= qir3 * dx[j];
        gy -= qir3 * dy[j];
        gz -= qir3 * dz[j];
      }
      if constexpr (H) {
        const double w = 3.0 * qir3 * ir2[j];
        const double wx = w * dx[j], wy = w * dy[j];
        hxx += wx * dx[j] - qir3;
        hyy += wy * dy[j] - qir3;
        hzz += w * dz[j] * dz[j] - qir3;
        hxy += wx * dy[j];
        hxz += wx * dz[j];
        hyz += wy * dz[j];
      }
    }
  }
  if constexpr (P) out[col_pot] += pot;
  if constexpr (G) {
    out[col_gx] += gx;
    out[col_gy] += gy;
    out[col_gz] += gz;
  }
  if constexpr (H) {
    out[col_hxx] += hxx;
    out[col_hyy] += hyy;
    out[col_hzz] += hzz;
    out[col_hxy] += hxy;
    out[col_hxz] += hxz;
    out[col_hyz] += hyz;
  }
}

#if defined(RPYFMM_HAVE_DIRECT_AVX512)
// GCC 12's _mm512_reduce_add_pd uses _mm256_undefined_pd(): silence its false -Wuninitialized.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
// ---- AVX-512F kernels (8 pairs per instruction, 1/r by rsqrt14 + Newton) ----

using detail::rsqrt_or_zero;

template <bool P, bool G, bool H>
RPYFMM_DIRECT_AVX512 void p2p_single_avx512(double tx, double ty, double tz, const double* sx, const double* sy,
                                            const double* sz, const double* q, std::size_t ns, double* out) {
  const __m512d vtx = _mm512_set1_pd(tx), vty = _mm512_set1_pd(ty), vtz = _mm512_set1_pd(tz);
  const __m512d three = _mm512_set1_pd(3.0);
  __m512d pot = _mm512_setzero_pd(), gx = pot, gy = pot, gz = pot;
  __m512d hxx = pot, hyy = pot, hzz = pot, hxy = pot, hxz = pot, hyz = pot;
  for (std::size_t j = 0; j < ns; j += 8) {
    // tail: masked-out lanes load q = 0 (and a finite position), so they add 0
    const __mmask8 m = ns - j >= 8 ? __mmask8(0xff) : __mmask8((1u << (ns - j)) - 1u);
    const __m512d dx = _mm512_sub_pd(vtx, _mm512_maskz_loadu_pd(m, sx + j));
    const __m512d dy = _mm512_sub_pd(vty, _mm512_maskz_loadu_pd(m, sy + j));
    const __m512d dz = _mm512_sub_pd(vtz, _mm512_maskz_loadu_pd(m, sz + j));
    const __m512d r2 = _mm512_fmadd_pd(dz, dz, _mm512_fmadd_pd(dy, dy, _mm512_mul_pd(dx, dx)));
    const __m512d ir = rsqrt_or_zero(r2);
    const __m512d qir = _mm512_mul_pd(_mm512_maskz_loadu_pd(m, q + j), ir);
    if constexpr (P) pot = _mm512_add_pd(pot, qir);
    if constexpr (G || H) {
      const __m512d ir2 = _mm512_mul_pd(ir, ir);
      const __m512d qir3 = _mm512_mul_pd(qir, ir2);
      if constexpr (G) {
        gx = _mm512_fnmadd_pd(qir3, dx, gx);
        gy = _mm512_fnmadd_pd(qir3, dy, gy);
        gz = _mm512_fnmadd_pd(qir3, dz, gz);
      }
      if constexpr (H) {
        const __m512d w = _mm512_mul_pd(_mm512_mul_pd(three, qir3), ir2);
        const __m512d wx = _mm512_mul_pd(w, dx), wy = _mm512_mul_pd(w, dy);
        hxx = _mm512_add_pd(hxx, _mm512_fmsub_pd(wx, dx, qir3));
        hyy = _mm512_add_pd(hyy, _mm512_fmsub_pd(wy, dy, qir3));
        hzz = _mm512_add_pd(hzz, _mm512_fmsub_pd(_mm512_mul_pd(w, dz), dz, qir3));
        hxy = _mm512_fmadd_pd(wx, dy, hxy);
        hxz = _mm512_fmadd_pd(wx, dz, hxz);
        hyz = _mm512_fmadd_pd(wy, dz, hyz);
      }
    }
  }
  if constexpr (P) out[col_pot] += _mm512_reduce_add_pd(pot);
  if constexpr (G) {
    out[col_gx] += _mm512_reduce_add_pd(gx);
    out[col_gy] += _mm512_reduce_add_pd(gy);
    out[col_gz] += _mm512_reduce_add_pd(gz);
  }
  if constexpr (H) {
    out[col_hxx] += _mm512_reduce_add_pd(hxx);
    out[col_hyy] += _mm512_reduce_add_pd(hyy);
    out[col_hzz] += _mm512_reduce_add_pd(hzz);
    out[col_hxy] += _mm512_reduce_add_pd(hxy);
    out[col_hxz] += _mm512_reduce_add_pd(hxz);
    out[col_hyz] += _mm512_reduce_add_pd(hyz);
  }
}

RPYFMM_DIRECT_AVX512 void geometry_block_avx512(double tx, double ty, double tz, const double* sx, const double* sy,
                                                const double* sz, std::size_t nb, double* dx, double* dy, double* dz,
                                                double* ir, double* ir2) {
  const __m512d vtx = _mm512_set1_pd(tx), vty = _mm512_set1_pd(ty), vtz = _mm512_set1_pd(tz);
  for (std::size_t j = 0; j < nb; j += 8) {
    const __mmask8 m = nb - j >= 8 ? __mmask8(0xff) : __mmask8((1u << (nb - j)) - 1u);
    const __m512d ddx = _mm512_sub_pd(vtx, _mm512_maskz_loadu_pd(m, sx + j));
    const __m512d ddy = _mm512_sub_pd(vty, _mm512_maskz_loadu_pd(m, sy + j));
    const __m512d ddz = _mm512_sub_pd(vtz, _mm512_maskz_loadu_pd(m, sz + j));
    const __m512d r2 = _mm512_fmadd_pd(ddz, ddz, _mm512_fmadd_pd(ddy, ddy, _mm512_mul_pd(ddx, ddx)));
    const __m512d v = rsqrt_or_zero(r2);
    _mm512_mask_storeu_pd(dx + j, m, ddx);
    _mm512_mask_storeu_pd(dy + j, m, ddy);
    _mm512_mask_storeu_pd(dz + j, m, ddz);
    _mm512_mask_storeu_pd(ir + j, m, v);
    _mm512_mask_storeu_pd(ir2 + j, m, _mm512_mul_pd(v, v));
  }
}
#pragma GCC diagnostic pop
#endif  // RPYFMM_HAVE_DIRECT_AVX512

template <bool P, bool G, bool H>
[[gnu::always_inline]] inline void p2p_range(const PointsSoA& s, const double* q, std::size_t ldq, std::size_t nd,
                                             const PointsSoA& t, std::size_t t0, std::size_t t1, double* out,
                                             std::size_t ldo) {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  const bool avx512 = simd_level() == SimdLevel::avx512;
#endif
  if (nd == 1) {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
    if (avx512) {
      for (std::size_t i = t0; i < t1; ++i) {
        p2p_single_avx512<P, G, H>(t.x[i], t.y[i], t.z[i], s.x, s.y, s.z, q, s.n, out + i * result_width);
      }
      return;
    }
#endif
    for (std::size_t i = t0; i < t1; ++i) {
      p2p_single<P, G, H>(t.x[i], t.y[i], t.z[i], s.x, s.y, s.z, q, s.n, out + i * result_width);
    }
    return;
  }
  alignas(64) double buf[5 * kBlock];
  double* dx = buf;
  double* dy = dx + kBlock;
  double* dz = dy + kBlock;
  double* ir = dz + kBlock;
  double* ir2 = ir + kBlock;
  for (std::size_t i = t0; i < t1; ++i) {
    for (std::size_t j0 = 0; j0 < s.n; j0 += kBlock) {
      const std::size_t nb = std::min(kBlock, s.n - j0);
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
      if (avx512) {
        geometry_block_avx512(t.x[i], t.y[i], t.z[i], s.x + j0, s.y + j0, s.z + j0, nb, dx, dy, dz, ir, ir2);
      } else {
        geometry_block(t.x[i], t.y[i], t.z[i], s.x + j0, s.y + j0, s.z + j0, nb, dx, dy, dz, ir, ir2);
      }
#else
      geometry_block(t.x[i], t.y[i], t.z[i], s.x + j0, s.y + j0, s.z + j0, nb, dx, dy, dz, ir, ir2);
#endif
      for (std::size_t d = 0; d < nd; ++d) {
        p2p_from_geometry<P, G, H>(dx, dy, dz, ir, ir2, q + d * ldq + j0, nb, out + d * ldo + i * result_width);
      }
    }
  }
}

// The multiversioned entry: targets [t0, t1) against all sources.
void p2p_dispatch(const PointsSoA& s, const double* q, std::size_t ldq, std::size_t nd, const PointsSoA& t,
                  std::size_t t0, std::size_t t1, unsigned outputs, double* out, std::size_t ldo) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    switch (outputs & all_outputs) {
      case 1:
        p2p_range<true, false, false>(s, q, ldq, nd, t, t0, t1, out, ldo);
        break;
      case 2:
        p2p_range<false, true, false>(s, q, ldq, nd, t, t0, t1, out, ldo);
        break;
      case 3:
        p2p_range<true, true, false>(s, q, ldq, nd, t, t0, t1, out, ldo);
        break;
      case 4:
        p2p_range<false, false, true>(s, q, ldq, nd, t, t0, t1, out, ldo);
        break;
      case 5:
        p2p_range<true, false, true>(s, q, ldq, nd, t, t0, t1, out, ldo);
        break;
      case 6:
        p2p_range<false, true, true>(s, q, ldq, nd, t, t0, t1, out, ldo);
        break;
      case 7:
        p2p_range<true, true, true>(s, q, ldq, nd, t, t0, t1, out, ldo);
        break;
      default:
        break;
    }
  });
}

struct SoA {
  std::vector<double> x, y, z;
  explicit SoA(std::span<const double> p) : x(p.size() / 3), y(p.size() / 3), z(p.size() / 3) {
    for (std::size_t i = 0; i < x.size(); ++i) {
      x[i] = p[3 * i];
      y[i] = p[3 * i + 1];
      z[i] = p[3 * i + 2];
    }
  }
  [[nodiscard]] PointsSoA view() const { return {x.data(), y.data(), z.data(), x.size()}; }
};

}  // namespace

void laplace_p2p_add(const PointsSoA& sources, const double* q, std::size_t ldq, std::size_t nd,
                     const PointsSoA& targets, unsigned outputs, double* out, std::size_t ldo) {
  if (sources.n == 0 || targets.n == 0 || nd == 0) return;
  p2p_dispatch(sources, q, ldq, nd, targets, 0, targets.n, outputs, out, ldo);
}

void laplace_direct(std::span<const double> sources, std::span<const double> charges, std::size_t nd,
                    std::span<const double> targets, unsigned outputs, std::span<double> results) {
  constexpr const char* where = "laplace_direct";
  require(sources.size() % 3 == 0, ErrorCode::invalid_input, where,
          "sources has " + std::to_string(sources.size()) + " entries, not a multiple of 3");
  require(!sources.empty(), ErrorCode::invalid_input, where, "no sources (N = 0)");
  require(targets.size() % 3 == 0, ErrorCode::invalid_input, where,
          "targets has " + std::to_string(targets.size()) + " entries, not a multiple of 3");
  require(nd >= 1, ErrorCode::invalid_argument, where, "number of charge vectors nd must be >= 1");
  require(outputs != 0 && (outputs & ~all_outputs) == 0, ErrorCode::invalid_argument, where,
          "outputs must be a non-empty combination of potential (1), gradient (2), hessian (4), got " +
              std::to_string(outputs));
  const std::size_t n = sources.size() / 3;
  const bool at_sources = targets.empty();
  const std::size_t m = at_sources ? n : targets.size() / 3;
  require_size(charges, nd * n, where, "charges (nd x N)");
  require_size(std::span<const double>(results.data(), results.size()), nd * m * result_width, where,
               "results (nd x M x 10)");
  require_finite(sources, where, "sources", 3);
  require_finite(charges, where, "charges", n);
  if (!at_sources) require_finite(targets, where, "targets", 3);

  const SoA src(sources);
  const SoA tgt_store(at_sources ? std::span<const double>{} : targets);
  const PointsSoA s = src.view();
  const PointsSoA t = at_sources ? s : tgt_store.view();
  std::fill(results.begin(), results.end(), 0.0);
  const std::size_t ldo = m * result_width;
  constexpr std::size_t chunk = 32;  // targets per task
  const std::size_t nchunks = (m + chunk - 1) / chunk;
#pragma omp parallel for schedule(dynamic, 1)
  for (std::size_t c = 0; c < nchunks; ++c) {
    const std::size_t t0 = c * chunk;
    const std::size_t t1 = std::min(m, t0 + chunk);
    p2p_dispatch(s, charges.data(), n, nd, t, t0, t1, outputs, results.data(), ldo);
  }
}

}  // namespace rpyfmm::fmm
