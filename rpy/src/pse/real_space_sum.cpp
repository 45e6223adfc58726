// rpyfmm — PSE real-space product (PSE.md Sec. 1.2, 6.2; [PSE] eq. 10 with App. A).
#include "real_space_sum.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <numbers>
#include <type_traits>

#include "kernels_common.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "window_avx2.hpp"

namespace rpyfmm::rpy::pse::detail {

namespace {

/// Positions and forces by slot, one array per axis.
struct SlotArrays {
  const double* x[3];
  const double* f[3];
};

/// F, G and the unit vector e = (x_s - x_t)/r of the pair of a particle at xi with slot t (minimum
/// image, [PSE] App. A via the linear table). Branch-free, so that the loops over neighbours
/// that call it vectorize (gathers): a coincident neighbour (r = 0) gets e = 0 and the table's
/// r = 0 node F(0) = G(0), i.e. the block F(0) I.
struct PairValues {
  double F, G, ex, ey, ez;
};

[[gnu::always_inline]] inline PairValues table_pair(const double xi[3], const SlotArrays& s, std::size_t t,
                                                    const double* table, double inv_dr, const double L[3],
                                                    const double inv_L[3]) {
  const double dx = minimum_image(xi[0] - s.x[0][t], L[0], inv_L[0]);
  const double dy = minimum_image(xi[1] - s.x[1][t], L[1], inv_L[1]);
  const double dz = minimum_image(xi[2] - s.x[2][t], L[2], inv_L[2]);
  const double r2 = dx * dx + dy * dy + dz * dz;
  const double r = std::sqrt(r2);
  const double inv_r = r2 > 0.0 ? 1.0 / r : 0.0;
  double w = r * inv_dr;
  const int j = static_cast<int>(w);
  w -= static_cast<double>(j);
  const double* e = table + 4 * j;
  return {e[0] + w * (e[2] - e[0]), e[1] + w * (e[3] - e[1]), dx * inv_r, dy * inv_r, dz * inv_r};
}

/// One row of M_r F / M0 without the self term: u += sum_q [F (I - rr) + G rr] f_q over the
/// neighbour slots nb[0..count) of a particle at xi ([PSE] eq. 10, App. A via the linear table).
void table_row(const int* nb, std::size_t count, const double xi[3], const SlotArrays& s, const double* table,
               double inv_dr, const double L[3], const double inv_L[3], double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    double ux = 0.0, uy = 0.0, uz = 0.0;
#pragma omp simd reduction(+ : ux, uy, uz)
    for (std::size_t q = 0; q < count; ++q) {
      const auto t = static_cast<std::size_t>(nb[q]);
      const PairValues v = table_pair(xi, s, t, table, inv_dr, L, inv_L);
      const double fx = s.f[0][t], fy = s.f[1][t], fz = s.f[2][t];
      const double proj = (v.G - v.F) * (v.ex * fx + v.ey * fy + v.ez * fz);
      ux += v.F * fx + proj * v.ex;
      uy += v.F * fy + proj * v.ey;
      uz += v.F * fz + proj * v.ez;
    }
    u[0] += ux;
    u[1] += uy;
    u[2] += uz;
  });
}

/// The row-layout pair cache of the portable rows (design note 23): per row entry q, F - F(0),
/// G - G(0), e_x, e_y, e_z in five arrays of `stride` values each.
template <class T>
struct RowCache {
  T* data;
  std::size_t stride;
};

/// Keeps each pair's values of one row in the row cache (entries from `first` on), rounded to T:
/// the table_row arithmetic without the sum, which cached_row_body then forms from the kept
/// values, in the same order as every later product.
template <class T>
[[gnu::always_inline]] inline void keep_row_body(const int* nb, std::size_t count, const double xi[3],
                                                 const SlotArrays& s, const double* table, double inv_dr,
                                                 const double L[3], const double inv_L[3], RowCache<T> c,
                                                 std::size_t first) {
  const double F0 = table[0], G0 = table[1];
  T* cF = c.data + first;
  T* cG = cF + c.stride;
  T* cx = cG + c.stride;
  T* cy = cx + c.stride;
  T* cz = cy + c.stride;
#pragma omp simd
  for (std::size_t q = 0; q < count; ++q) {
    const PairValues v = table_pair(xi, s, static_cast<std::size_t>(nb[q]), table, inv_dr, L, inv_L);
    cF[q] = static_cast<T>(v.F - F0);
    cG[q] = static_cast<T>(v.G - G0);
    cx[q] = static_cast<T>(v.ex);
    cy[q] = static_cast<T>(v.ey);
    cz[q] = static_cast<T>(v.ez);
  }
}

/// One row from the row cache: the forces of the neighbours and the kept values only.
template <class T>
[[gnu::always_inline]] inline void cached_row_body(const int* nb, std::size_t count, const SlotArrays& s,
                                                   const double* table, RowCache<T> c, std::size_t first, double u[3]) {
  const double F0 = table[0], G0 = table[1];
  const T* cF = c.data + first;
  const T* cG = cF + c.stride;
  const T* cx = cG + c.stride;
  const T* cy = cx + c.stride;
  const T* cz = cy + c.stride;
  double ux = 0.0, uy = 0.0, uz = 0.0;
#pragma omp simd reduction(+ : ux, uy, uz)
  for (std::size_t q = 0; q < count; ++q) {
    const auto t = static_cast<std::size_t>(nb[q]);
    const double F = F0 + static_cast<double>(cF[q]), G = G0 + static_cast<double>(cG[q]);
    const double ex = cx[q], ey = cy[q], ez = cz[q];
    const double fx = s.f[0][t], fy = s.f[1][t], fz = s.f[2][t];
    const double proj = (G - F) * (ex * fx + ey * fy + ez * fz);
    ux += F * fx + proj * ex;
    uy += F * fy + proj * ey;
    uz += F * fz + proj * ez;
  }
  u[0] += ux;
  u[1] += uy;
  u[2] += uz;
}

// Non-template entry points, each compiled per instruction-set level (simd_dispatch).
void fill_row(const int* nb, std::size_t count, const double xi[3], const SlotArrays& s, const double* table,
              double inv_dr, const double L[3], const double inv_L[3], RowCache<float> c, std::size_t first,
              double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    keep_row_body(nb, count, xi, s, table, inv_dr, L, inv_L, c, first);
    cached_row_body(nb, count, s, table, c, first, u);
  });
}
void fill_row(const int* nb, std::size_t count, const double xi[3], const SlotArrays& s, const double* table,
              double inv_dr, const double L[3], const double inv_L[3], RowCache<double> c, std::size_t first,
              double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    keep_row_body(nb, count, xi, s, table, inv_dr, L, inv_L, c, first);
    cached_row_body(nb, count, s, table, c, first, u);
  });
}
void cached_row(const int* nb, std::size_t count, const SlotArrays& s, const double* table, RowCache<float> c,
                std::size_t first, double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY { cached_row_body(nb, count, s, table, c, first, u); });
}
void cached_row(const int* nb, std::size_t count, const SlotArrays& s, const double* table, RowCache<double> c,
                std::size_t first, double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY { cached_row_body(nb, count, s, table, c, first, u); });
}

#if defined(RPYFMM_HAVE_DIRECT_AVX512)
// GCC 12's AVX-512 headers start gathers and conversions from _mm512_undefined_*, which trips
// its own uninitialized-use warnings in this translation unit.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
/// Rows [x, y, z, fx, fy, fz, 0, 0] of eight slots -> the six vectors x, y, z, fx, fy, fz across
/// the eight (an 8 x 8 transpose in three stages of in-lane unpacks and 128-bit lane shuffles).
RPYFMM_DIRECT_AVX512 inline void transpose_slots(const double* const rows[8], __m512d out[6]) {
  __m512d lo[4], hi[4];
  for (int k = 0; k < 4; ++k) {
    const __m512d a = _mm512_load_pd(rows[2 * k]), b = _mm512_load_pd(rows[2 * k + 1]);
    lo[k] = _mm512_unpacklo_pd(a, b);  // [x x | z z | fy fy | 0 0] of slots 2k, 2k+1
    hi[k] = _mm512_unpackhi_pd(a, b);  // [y y | fx fx | fz fz | 0 0]
  }
  constexpr int even = _MM_SHUFFLE(2, 0, 2, 0), odd = _MM_SHUFFLE(3, 1, 3, 1);
  __m512d q[8];
  for (int h = 0; h < 2; ++h) {
    q[4 * h + 0] = _mm512_shuffle_f64x2(lo[2 * h], lo[2 * h + 1], even);  // [x | fy | x | fy]
    q[4 * h + 1] = _mm512_shuffle_f64x2(lo[2 * h], lo[2 * h + 1], odd);   // [z | 0 | z | 0]
    q[4 * h + 2] = _mm512_shuffle_f64x2(hi[2 * h], hi[2 * h + 1], even);  // [y | fz | y | fz]
    q[4 * h + 3] = _mm512_shuffle_f64x2(hi[2 * h], hi[2 * h + 1], odd);   // [fx | 0 | fx | 0]
  }
  out[0] = _mm512_shuffle_f64x2(q[0], q[4], even);  // x
  out[1] = _mm512_shuffle_f64x2(q[2], q[6], even);  // y
  out[2] = _mm512_shuffle_f64x2(q[1], q[5], even);  // z
  out[3] = _mm512_shuffle_f64x2(q[3], q[7], even);  // fx
  out[4] = _mm512_shuffle_f64x2(q[0], q[4], odd);   // fy
  out[5] = _mm512_shuffle_f64x2(q[2], q[6], odd);   // fz
}

/// Table tuples (F_j, G_j, F_j+1, G_j+1) of eight lanes -> the vectors F_j, G_j, F_j+1, G_j+1.
RPYFMM_DIRECT_AVX512 inline void transpose_table(const double* table, const int j[8], __m512d out[4]) {
  __m512d pair[4];
  for (int k = 0; k < 4; ++k)
    pair[k] = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_loadu_pd(table + 4 * j[2 * k])),
                                 _mm256_loadu_pd(table + 4 * j[2 * k + 1]), 1);
  const __m512i first = _mm512_set_epi64(13, 9, 5, 1, 12, 8, 4, 0);     // [F F F F | G G G G]
  const __m512i second = _mm512_set_epi64(15, 11, 7, 3, 14, 10, 6, 2);  // [F' F' F' F' | G' G' G' G']
  const __m512d a = _mm512_permutex2var_pd(pair[0], first, pair[1]);
  const __m512d b = _mm512_permutex2var_pd(pair[2], first, pair[3]);
  const __m512d c = _mm512_permutex2var_pd(pair[0], second, pair[1]);
  const __m512d d = _mm512_permutex2var_pd(pair[2], second, pair[3]);
  constexpr int low = _MM_SHUFFLE(1, 0, 1, 0), high = _MM_SHUFFLE(3, 2, 3, 2);
  out[0] = _mm512_shuffle_f64x2(a, b, low);
  out[1] = _mm512_shuffle_f64x2(a, b, high);
  out[2] = _mm512_shuffle_f64x2(c, d, low);
  out[3] = _mm512_shuffle_f64x2(c, d, high);
}

/// Constants of the AVX-512 rows: the particle's position, the box, the table spacing.
struct RowFrame {
  __m512d pos[3], box[3], inv_box[3];
  __m512d inv_dr;
};

RPYFMM_DIRECT_AVX512 inline RowFrame row_frame(const double* self_row, double inv_dr, const double L[3],
                                               const double inv_L[3]) {
  RowFrame f;
  for (int d = 0; d < 3; ++d) {
    f.pos[d] = _mm512_set1_pd(self_row[d]);
    f.box[d] = _mm512_set1_pd(L[d]);
    f.inv_box[d] = _mm512_set1_pd(inv_L[d]);
  }
  f.inv_dr = _mm512_set1_pd(inv_dr);
  return f;
}

/// The blocks F (I - ee) + G ee of eight pairs: e = (x_s - x_t)/r (0 at r = 0) and F, G from
/// the table, for neighbours whose x, y, z are v[0..2] (transpose_slots).
struct PairLanes {
  __m512d e[3];
  __m512d F, G;
};

RPYFMM_DIRECT_AVX512 inline PairLanes pair_lanes(const RowFrame& fr, const __m512d v[6], const double* table) {
  const __m512d magic = _mm512_set1_pd(6755399441055744.0);  // minimum_image's round-to-nearest
  __m512d dr[3];
  for (int d = 0; d < 3; ++d) {
    const __m512d t = _mm512_sub_pd(fr.pos[d], v[d]);
    const __m512d k = _mm512_sub_pd(_mm512_add_pd(_mm512_mul_pd(t, fr.inv_box[d]), magic), magic);
    dr[d] = _mm512_fnmadd_pd(fr.box[d], k, t);
  }
  const __m512d r2 = _mm512_fmadd_pd(dr[0], dr[0], _mm512_fmadd_pd(dr[1], dr[1], _mm512_mul_pd(dr[2], dr[2])));
  const __m512d inv_r = fmm::detail::rsqrt_or_zero(r2);
  __m512d w = _mm512_mul_pd(_mm512_mul_pd(r2, inv_r), fr.inv_dr);
  const __m256i jv = _mm512_cvttpd_epi32(w);
  w = _mm512_sub_pd(w, _mm512_cvtepi32_pd(jv));
  alignas(32) int j[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(j), jv);
  __m512d tab[4];
  transpose_table(table, j, tab);
  PairLanes p;
  p.F = _mm512_fmadd_pd(w, _mm512_sub_pd(tab[2], tab[0]), tab[0]);
  p.G = _mm512_fmadd_pd(w, _mm512_sub_pd(tab[3], tab[1]), tab[1]);
  for (int d = 0; d < 3; ++d) p.e[d] = _mm512_mul_pd(dr[d], inv_r);
  return p;
}

/// [F (I - ee) + G ee] f, lane by lane, for the force f (three vectors).
RPYFMM_DIRECT_AVX512 inline void block_times(const PairLanes& p, const __m512d f[3], __m512d out[3]) {
  const __m512d proj =
      _mm512_mul_pd(_mm512_sub_pd(p.G, p.F),
                    _mm512_fmadd_pd(p.e[0], f[0], _mm512_fmadd_pd(p.e[1], f[1], _mm512_mul_pd(p.e[2], f[2]))));
  for (int d = 0; d < 3; ++d) out[d] = _mm512_fmadd_pd(p.F, f[d], _mm512_mul_pd(proj, p.e[d]));
}

/// Neighbour rows of chunk q (eight slots; the last chunk padded with the row's own slot, r = 0:
/// a valid table index) transposed into x, y, z, fx, fy, fz across the eight; returns the mask of
/// the real neighbours.
RPYFMM_DIRECT_AVX512 inline __mmask8 load_chunk(const int* nb, std::size_t count, std::size_t q, std::size_t self,
                                                const double* packed, __m512d v[6]) {
  const std::size_t left = count - q;
  const double* rows[8];
  for (std::size_t k = 0; k < 8; ++k) rows[k] = packed + 8 * (k < left ? static_cast<std::size_t>(nb[q + k]) : self);
  transpose_slots(rows, v);
  return left >= 8 ? static_cast<__mmask8>(0xFF) : static_cast<__mmask8>((1u << left) - 1u);
}

/// u[c] += the sum of the eight lanes of s[c], c = 0, 1, 2 (fmm::detail::sum_lanes_pairwise: in
/// registers; through memory, a store and 24 scalar reloads, the real-space product was ~5% slower
/// at 32000 particles).
RPYFMM_DIRECT_AVX512 inline void add_lane_sums(const __m512d s[3], double* u) {
  for (int c = 0; c < 3; ++c) u[c] += fmm::detail::sum_lanes_pairwise(s[c]);
}

/// table_row with AVX-512 intrinsics, eight neighbours at a time, without gathers (which ran
/// at ~20 cycles per pair here): each neighbour's position and force are one 64-byte row of
/// `packed` (x, y, z, fx, fy, fz, 0, 0 per slot), loaded whole and transposed, and the table
/// tuples likewise. 1/r by rsqrt14 and two Newton steps (fmm::detail::rsqrt_or_zero, 0 at r = 0
/// as in table_row). The padding lanes of the last chunk are masked out of the sums.
RPYFMM_DIRECT_AVX512 void packed_row_avx512(const int* nb, std::size_t count, std::size_t self, const double* packed,
                                            const double* table, double inv_dr, const double L[3],
                                            const double inv_L[3], double u[3]) {
  const RowFrame fr = row_frame(packed + 8 * self, inv_dr, L, inv_L);
  __m512d sum[3] = {_mm512_setzero_pd(), _mm512_setzero_pd(), _mm512_setzero_pd()};
  for (std::size_t q = 0; q < count; q += 8) {
    __m512d v[6];
    const __mmask8 m = load_chunk(nb, count, q, self, packed, v);
    const PairLanes p = pair_lanes(fr, v, table);
    __m512d b[3];
    block_times(p, v + 3, b);
    for (int d = 0; d < 3; ++d) sum[d] = _mm512_mask_add_pd(sum[d], m, sum[d], b[d]);
  }
  add_lane_sums(sum, u);
}

/// acc[4 nb[k] + c] += lane k of back[c] (c = 0, 1, 2) for the first `lanes` lanes: lanes ->
/// rows (x, y, z, 0) of four doubles by two 128-bit unpacks per pair of components, then lane
/// shuffles put rows k and k + 2 into the halves of one vector; one neighbour at a time (no two
/// lanes of a chunk name the same slot).
RPYFMM_DIRECT_AVX512 inline void scatter_rows(const __m512d back[3], const int* nb, std::size_t lanes, double* acc) {
  const __m512d zero = _mm512_setzero_pd();
  const __m512d xy_even = _mm512_unpacklo_pd(back[0], back[1]);  // [x0 y0 | x2 y2 | x4 y4 | x6 y6]
  const __m512d xy_odd = _mm512_unpackhi_pd(back[0], back[1]);   // [x1 y1 | x3 y3 | ...]
  const __m512d z_even = _mm512_unpacklo_pd(back[2], zero);      // [z0 0 | z2 0 | ...]
  const __m512d z_odd = _mm512_unpackhi_pd(back[2], zero);
  constexpr int low = _MM_SHUFFLE(1, 0, 1, 0), high = _MM_SHUFFLE(3, 2, 3, 2), mix = _MM_SHUFFLE(3, 1, 2, 0);
  __m512d rows[4];
  rows[0] = _mm512_shuffle_f64x2(xy_even, z_even, low);  // [x0 y0 | x2 y2 | z0 0 | z2 0]
  rows[1] = _mm512_shuffle_f64x2(xy_odd, z_odd, low);
  rows[2] = _mm512_shuffle_f64x2(xy_even, z_even, high);
  rows[3] = _mm512_shuffle_f64x2(xy_odd, z_odd, high);
  for (auto& pair : rows) pair = _mm512_shuffle_f64x2(pair, pair, mix);  // [row k | row k + 2]
  for (std::size_t k = 0; k < lanes; ++k) {
    // lane k sits in rows[(k / 4) * 2 + k % 2], half (k / 2) % 2
    const __m512d pair = rows[(k / 4) * 2 + k % 2];
    const __m256d row = (k / 2) % 2 == 0 ? _mm512_castpd512_pd256(pair) : _mm512_extractf64x4_pd(pair, 1);
    double* a = acc + 4 * static_cast<std::size_t>(nb[k]);
    _mm256_store_pd(a, _mm256_add_pd(_mm256_load_pd(a), row));
  }
}

/// Eight lanes of the pair cache as doubles (T = float: converted).
template <class T>
RPYFMM_DIRECT_AVX512 inline __m512d load_cached(const T* c) {
  if constexpr (std::is_same_v<T, float>)
    return _mm512_cvtps_pd(_mm256_load_ps(c));
  else
    return _mm512_load_pd(c);
}

template <class T>
RPYFMM_DIRECT_AVX512 inline void store_cached(T* c, __m512d v) {
  if constexpr (std::is_same_v<T, float>)
    _mm256_store_ps(c, _mm512_cvtpd_ps(v));
  else
    _mm512_store_pd(c, v);
}

/// One chunk of the pair cache (40 values): F - F(0), G - G(0), e_x, e_y, e_z. F and G are kept
/// as differences from their r = 0 values (the table's first node), which a coincident pair
/// thus gets back exactly in float too: its block stays equal to the self block, and M_r stays
/// exactly singular (positive semidefinite) with coincident particles.
template <class T>
RPYFMM_DIRECT_AVX512 inline void store_pair_lanes(T* c, const PairLanes& p, const __m512d origin[2]) {
  store_cached(c, _mm512_sub_pd(p.F, origin[0]));
  store_cached(c + 8, _mm512_sub_pd(p.G, origin[1]));
  for (int d = 0; d < 3; ++d) store_cached(c + 16 + 8 * d, p.e[d]);
}

template <class T>
RPYFMM_DIRECT_AVX512 inline PairLanes load_pair_lanes(const T* c, const __m512d origin[2]) {
  PairLanes p;
  p.F = _mm512_add_pd(origin[0], load_cached(c));
  p.G = _mm512_add_pd(origin[1], load_cached(c + 8));
  for (int d = 0; d < 3; ++d) p.e[d] = load_cached(c + 16 + 8 * d);
  return p;
}

/// The half-list row (design note 22): for the neighbours nb[0..count) of slot `self` with larger
/// slots, acc[4 self + c] += sum_t B_st f_t and acc[4 t + c] += B_st f_s (B is symmetric: e
/// changes sign with the pair's direction and appears twice). With a cache (design note 23), the
/// lanes of chunk q are stored at cache + 5 q and read back, so that the products that later read
/// them apply the very same blocks (T = float or double; void: no cache).
template <class T>
RPYFMM_DIRECT_AVX512 void packed_half_row_avx512(const int* nb, std::size_t count, std::size_t self,
                                                 const double* packed, const double* table, double inv_dr,
                                                 const double L[3], const double inv_L[3], double* acc, T* cache) {
  const RowFrame fr = row_frame(packed + 8 * self, inv_dr, L, inv_L);
  const __m512d fs[3] = {_mm512_set1_pd(packed[8 * self + 3]), _mm512_set1_pd(packed[8 * self + 4]),
                         _mm512_set1_pd(packed[8 * self + 5])};
  __m512d sum[3] = {_mm512_setzero_pd(), _mm512_setzero_pd(), _mm512_setzero_pd()};
  for (std::size_t q = 0; q < count; q += 8) {
    __m512d v[6];
    const __mmask8 m = load_chunk(nb, count, q, self, packed, v);
    PairLanes p = pair_lanes(fr, v, table);
    if constexpr (!std::is_void_v<T>) {
      const __m512d origin[2] = {_mm512_set1_pd(table[0]), _mm512_set1_pd(table[1])};
      store_pair_lanes(cache + 5 * q, p, origin);
      p = load_pair_lanes(cache + 5 * q, origin);
    }
    __m512d b[3], back[3];
    block_times(p, v + 3, b);
    block_times(p, fs, back);
    for (int d = 0; d < 3; ++d) sum[d] = _mm512_mask_add_pd(sum[d], m, sum[d], b[d]);
    scatter_rows(back, nb + q, std::min<std::size_t>(8, count - q), acc);
  }
  add_lane_sums(sum, acc + 4 * self);
}

/// Rows (fx, fy, fz, 0) of eight slots -> the vectors fx, fy, fz across the eight.
RPYFMM_DIRECT_AVX512 inline void transpose_forces(const double* const rows[8], __m512d f[3]) {
  __m512d a[4];  // [x_k y_k z_k 0 | x_k+4 y_k+4 z_k+4 0]
  for (int k = 0; k < 4; ++k)
    a[k] = _mm512_insertf64x4(_mm512_castpd256_pd512(_mm256_load_pd(rows[k])), _mm256_load_pd(rows[k + 4]), 1);
  const __m512d xz01 = _mm512_unpacklo_pd(a[0], a[1]);  // [x0 x1 | z0 z1 | x4 x5 | z4 z5]
  const __m512d y01 = _mm512_unpackhi_pd(a[0], a[1]);   // [y0 y1 | 0 0 | y4 y5 | 0 0]
  const __m512d xz23 = _mm512_unpacklo_pd(a[2], a[3]);
  const __m512d y23 = _mm512_unpackhi_pd(a[2], a[3]);
  const __m512i first = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);     // [0 1 8 9 4 5 12 13]
  const __m512i second = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);  // [2 3 10 11 6 7 14 15]
  f[0] = _mm512_permutex2var_pd(xz01, first, xz23);
  f[1] = _mm512_permutex2var_pd(y01, first, y23);
  f[2] = _mm512_permutex2var_pd(xz01, second, xz23);
}

/// packed_half_row_avx512 for the later products with the same positions: the blocks come from
/// the pair cache (chunk q at cache + 5 q), the forces from rows of four doubles (fx, fy, fz, 0
/// per slot), and the pair is not evaluated again.
template <class T>
RPYFMM_DIRECT_AVX512 void cached_half_row_avx512(const int* nb, std::size_t count, std::size_t self,
                                                 const double* forces, const T* cache, const double* table,
                                                 double* acc) {
  const __m512d origin[2] = {_mm512_set1_pd(table[0]), _mm512_set1_pd(table[1])};
  const double* own = forces + 4 * self;
  const __m512d fs[3] = {_mm512_set1_pd(own[0]), _mm512_set1_pd(own[1]), _mm512_set1_pd(own[2])};
  __m512d sum[3] = {_mm512_setzero_pd(), _mm512_setzero_pd(), _mm512_setzero_pd()};
  for (std::size_t q = 0; q < count; q += 8) {
    const std::size_t left = count - q;
    const double* rows[8];
    for (std::size_t k = 0; k < 8; ++k) rows[k] = forces + 4 * (k < left ? static_cast<std::size_t>(nb[q + k]) : self);
    __m512d f[3];
    transpose_forces(rows, f);
    const auto m = left >= 8 ? static_cast<__mmask8>(0xFF) : static_cast<__mmask8>((1u << left) - 1u);
    // The cache is streamed once per product: prefetch ~1 KB ahead (1.15-1.2x on this kernel
    // at 64 MB of cache; 0.5-4 KB ahead did about as well).
    const char* ahead = reinterpret_cast<const char*>(cache + 5 * q) + 1024;
    for (std::size_t line = 0; line < 40 * sizeof(T); line += 64) _mm_prefetch(ahead + line, _MM_HINT_T0);
    const PairLanes p = load_pair_lanes(cache + 5 * q, origin);
    __m512d b[3], back[3];
    block_times(p, f, b);
    block_times(p, fs, back);
    for (int d = 0; d < 3; ++d) sum[d] = _mm512_mask_add_pd(sum[d], m, sum[d], b[d]);
    scatter_rows(back, nb + q, std::min<std::size_t>(8, left), acc);
  }
  add_lane_sums(sum, acc + 4 * self);
}

/// The list build's candidate filter, eight candidates at a time: appends to out the slots t0 + q
/// (q < count) with |(xs - x_t, ys - y_t, zs - z_t)|^2 < rc2, where (xs, ys, zs) is the row's
/// position less the run's image shift, in ascending order; returns how many. Rounded as the
/// portable filter rounds in the default (portable x86-64) build ((xs - x_t) - shift per axis;
/// products and sums without fused multiply-adds), so both keep the same pairs; where the
/// compiler may fuse the portable filter's products (-march=native), a pair within a rounding
/// of r_cut may differ, whose block is below the tolerance there anyway. out needs 16 entries
/// of slack past the kept ones (one 512-bit store of 16 slots).
RPYFMM_DIRECT_AVX512 std::size_t pairs_within_avx512(const double* xt, const double* yt, const double* zt,
                                                     std::size_t t0, std::size_t count, const double xs[3],
                                                     const double shift[3], double rc2, int* out) {
  const __m512d x = _mm512_set1_pd(xs[0]), y = _mm512_set1_pd(xs[1]), z = _mm512_set1_pd(xs[2]);
  const __m512d sx = _mm512_set1_pd(shift[0]), sy = _mm512_set1_pd(shift[1]), sz = _mm512_set1_pd(shift[2]);
  const __m512d r2 = _mm512_set1_pd(rc2);
  const __m512i lane = _mm512_set_epi32(0, 0, 0, 0, 0, 0, 0, 0, 7, 6, 5, 4, 3, 2, 1, 0);
  std::size_t used = 0;
  for (std::size_t q = 0; q < count; q += 8) {
    const auto live = static_cast<__mmask8>(count - q >= 8 ? 0xFF : (1u << (count - q)) - 1u);
    const __m512d dx = _mm512_sub_pd(_mm512_sub_pd(x, _mm512_maskz_loadu_pd(live, xt + t0 + q)), sx);
    const __m512d dy = _mm512_sub_pd(_mm512_sub_pd(y, _mm512_maskz_loadu_pd(live, yt + t0 + q)), sy);
    const __m512d dz = _mm512_sub_pd(_mm512_sub_pd(z, _mm512_maskz_loadu_pd(live, zt + t0 + q)), sz);
    const __m512d d2 =
        _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)), _mm512_mul_pd(dz, dz));
    const __mmask8 keep = _mm512_mask_cmp_pd_mask(live, d2, r2, _CMP_LT_OQ);
    const __m512i idx = _mm512_add_epi32(_mm512_set1_epi32(static_cast<int>(t0 + q)), lane);
    _mm512_storeu_si512(out + used, _mm512_maskz_compress_epi32(keep, idx));
    used += static_cast<std::size_t>(__builtin_popcount(keep));
  }
  return used;
}

/// _mm_shuffle_epi8 controls that move the 32-bit lanes set in a 4-bit mask to the front, in
/// order (the rest zeroed): the compaction of pairs_within_avx2.
struct CompactTable {
  alignas(16) std::uint8_t control[16][16];
  constexpr CompactTable() : control{} {
    for (int m = 0; m < 16; ++m) {
      int k = 0;
      for (int lane = 0; lane < 4; ++lane)
        if ((m >> lane) & 1) {
          for (int b = 0; b < 4; ++b) control[m][4 * k + b] = static_cast<std::uint8_t>(4 * lane + b);
          ++k;
        }
      for (int b = 4 * k; b < 16; ++b) control[m][b] = 0x80;
    }
  }
};
constexpr CompactTable kCompact{};

/// pairs_within_avx512 for CPUs with AVX2 but not the AVX-512 kernels (full lists, both
/// directions): four candidates at a time, the kept slots moved to the front by a byte shuffle
/// from a 16-entry table; the slot `skip` (the row's own; any other value: none) is never kept.
/// Compiled for AVX2 without FMA, so rounded as pairs_within_avx512 (and the portable filter,
/// with the same proviso). out needs 4 entries of slack past the kept ones.
__attribute__((target("avx2"))) std::size_t pairs_within_avx2(const double* xt, const double* yt, const double* zt,
                                                              std::size_t t0, std::size_t count, const double xs[3],
                                                              const double shift[3], double rc2, std::size_t skip,
                                                              int* out) {
  const __m256d x = _mm256_set1_pd(xs[0]), y = _mm256_set1_pd(xs[1]), z = _mm256_set1_pd(xs[2]);
  const __m256d sx = _mm256_set1_pd(shift[0]), sy = _mm256_set1_pd(shift[1]), sz = _mm256_set1_pd(shift[2]);
  const __m256d r2 = _mm256_set1_pd(rc2);
  const __m128i lane = _mm_setr_epi32(0, 1, 2, 3);
  std::size_t used = 0;
  for (std::size_t q = 0; q < count; q += 4) {
    const std::size_t left = count - q;
    __m256d vx, vy, vz;
    if (left >= 4) {
      vx = _mm256_loadu_pd(xt + t0 + q);
      vy = _mm256_loadu_pd(yt + t0 + q);
      vz = _mm256_loadu_pd(zt + t0 + q);
    } else {
      const __m256i live =
          _mm256_cmpgt_epi64(_mm256_set1_epi64x(static_cast<long long>(left)), _mm256_setr_epi64x(0, 1, 2, 3));
      vx = _mm256_maskload_pd(xt + t0 + q, live);
      vy = _mm256_maskload_pd(yt + t0 + q, live);
      vz = _mm256_maskload_pd(zt + t0 + q, live);
    }
    const __m256d dx = _mm256_sub_pd(_mm256_sub_pd(x, vx), sx);
    const __m256d dy = _mm256_sub_pd(_mm256_sub_pd(y, vy), sy);
    const __m256d dz = _mm256_sub_pd(_mm256_sub_pd(z, vz), sz);
    const __m256d d2 =
        _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz));
    unsigned keep = static_cast<unsigned>(_mm256_movemask_pd(_mm256_cmp_pd(d2, r2, _CMP_LT_OQ)));
    if (left < 4) keep &= (1u << left) - 1u;
    if (skip - (t0 + q) < 4) keep &= ~(1u << (skip - (t0 + q)));
    const __m128i idx = _mm_add_epi32(_mm_set1_epi32(static_cast<int>(t0 + q)), lane);
    const __m128i control = _mm_load_si128(reinterpret_cast<const __m128i*>(kCompact.control[keep]));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out + used), _mm_shuffle_epi8(idx, control));
    used += static_cast<std::size_t>(__builtin_popcount(keep));
  }
  return used;
}
#pragma GCC diagnostic pop
#endif

}  // namespace

RealSpaceSum::RealSpaceSum(const PseParameters& p, const std::array<double, 3>& box, double viscosity, bool use_table,
                           PairCache cache, std::size_t cache_limit_bytes, bool full_lists)
    : p_(p),
      box_(box),
      m0_(1.0 / (6.0 * std::numbers::pi * viscosity * p.radius)),
      self_(real_space_self(p.xi, p.radius)),
      use_table_(use_table),
      cache_(cache),
      cache_limit_(cache_limit_bytes) {
  full_lists_only_ = full_lists;
  if (use_table_) table_ = PseRealSpaceTable(p.xi, p.radius, p.r_cut, p.tolerance / 10.0);
}

void RealSpaceSum::set_positions(std::span<const double> x) {
  const std::size_t n = x.size() / 3;
  require(n < static_cast<std::size_t>(std::numeric_limits<int>::max()), ErrorCode::invalid_input, "PseRpy",
          "too many particles for 32-bit neighbour indices");
  const double rc2 = p_.r_cut * p_.r_cut;
  std::array<int, 3> nc{};
  bool cells = true;
  for (int d = 0; d < 3; ++d) {
    nc[d] = static_cast<int>(std::floor(box_[d] / p_.r_cut));
    cells = cells && nc[d] >= 3;
  }
  // Slots: particles sorted by cell (counting sort, stable); without cells, the input order.
  std::vector<std::size_t> cell_begin;
  order_.resize(n);
  if (cells) {
    const std::size_t ncell = static_cast<std::size_t>(nc[0]) * nc[1] * nc[2];
    cell_begin.assign(ncell + 1, 0);
    std::vector<std::size_t> id(n);
    // Cell ids in parallel (divisions), the counts serially.
#pragma omp parallel for schedule(static) if (n >= 16384)
    for (std::int64_t ii = 0; ii < static_cast<std::int64_t>(n); ++ii) {
      const auto i = static_cast<std::size_t>(ii);
      int c[3];
      for (int d = 0; d < 3; ++d) c[d] = std::min(static_cast<int>(x[3 * i + d] / box_[d] * nc[d]), nc[d] - 1);
      id[i] = (static_cast<std::size_t>(c[0]) * nc[1] + c[1]) * nc[2] + c[2];
    }
    for (std::size_t i = 0; i < n; ++i) ++cell_begin[id[i] + 1];
    for (std::size_t c = 0; c < ncell; ++c) cell_begin[c + 1] += cell_begin[c];
    std::vector<std::size_t> fill(cell_begin.begin(), cell_begin.end() - 1);
    for (std::size_t i = 0; i < n; ++i) order_[fill[id[i]]++] = i;
  } else {
    for (std::size_t s = 0; s < n; ++s) order_[s] = s;
  }
  for (auto& p : pos_) p.resize(n);
  // One pass (x is read at random, a particle's three coordinates share a cache line), fetching
  // a few slots ahead.
  constexpr std::size_t ahead = 8;
#pragma omp parallel for schedule(static) if (n >= 16384)
  for (std::int64_t ss = 0; ss < static_cast<std::int64_t>(n); ++ss) {
    const auto s = static_cast<std::size_t>(ss);
    if (s + ahead < n) __builtin_prefetch(&x[3 * order_[s + ahead]]);
    const double* xi = &x[3 * order_[s]];
    pos_[0][s] = xi[0];
    pos_[1][s] = xi[1];
    pos_[2][s] = xi[2];
  }
  const std::array<double, 3> inv = {1.0 / box_[0], 1.0 / box_[1], 1.0 / box_[2]};
  const auto& px = pos_[0];
  const auto& py = pos_[1];
  const auto& pz = pos_[2];
  // d2[q] = |x_s - x_{t0 + q} - shift|^2, q < count: the neighbour's periodic image is fixed per
  // neighbour cell (shift 0 or +-L per axis, below); without cells (shift null), minimum image.
  auto squared_distances = [&](std::size_t s, std::size_t t0, std::size_t count, const double* shift,
                               double* __restrict d2) {
    const double xs = px[s], ys = py[s], zs = pz[s];
    const double* __restrict xt = px.data() + t0;
    const double* __restrict yt = py.data() + t0;
    const double* __restrict zt = pz.data() + t0;
    if (shift == nullptr) {
#pragma omp simd
      for (std::size_t q = 0; q < count; ++q) {
        const double dx = minimum_image(xs - xt[q], box_[0], inv[0]);
        const double dy = minimum_image(ys - yt[q], box_[1], inv[1]);
        const double dz = minimum_image(zs - zt[q], box_[2], inv[2]);
        d2[q] = dx * dx + dy * dy + dz * dz;
      }
      return;
    }
    const double sx = shift[0], sy = shift[1], sz = shift[2];
#pragma omp simd
    for (std::size_t q = 0; q < count; ++q) {
      const double dx = (xs - xt[q]) - sx, dy = (ys - yt[q]) - sy, dz = (zs - zt[q]) - sz;
      d2[q] = dx * dx + dy * dy + dz * dz;
    }
  };
  // The 27 neighbour cells of cell c in ascending id order, merged into runs of consecutive ids
  // with the same image shift (a z column of three cells is one run of consecutive slots unless
  // it wraps): slots are numbered cell by cell, so each row then lists its neighbours in
  // ascending slot order without a sort. The shift along an axis is +L where the neighbour cell
  // wrapped past the last layer, -L where it wrapped below the first, else 0: with >= 3 cells of
  // edge >= r_cut per axis, a pair within r_cut has that image as its minimum image (any other
  // image is >= L - 2 h >= h >= r_cut away along the axis), and x_s - x_t -+ L is rounded as
  // minimum_image rounds it. Without cells, one pseudo-cell holds every slot (minimum image).
  struct CellRun {
    std::size_t first, end;  // cells [first, end)
    double shift[3];
  };
  if (!cells) cell_begin = {0, n};
  const std::size_t ncell = cell_begin.size() - 1;
  auto neighbour_runs = [&](std::size_t c, std::array<CellRun, 27>& out) -> int {
    if (!cells) {
      out[0] = {0, 1, {0.0, 0.0, 0.0}};
      return 1;
    }
    const auto nyz = static_cast<std::size_t>(nc[1]) * static_cast<std::size_t>(nc[2]);
    const int c0[3] = {static_cast<int>(c / nyz), static_cast<int>((c / static_cast<std::size_t>(nc[2])) % nc[1]),
                       static_cast<int>(c % static_cast<std::size_t>(nc[2]))};
    std::array<CellRun, 27> one{};
    int k = 0;
    for (int ax = -1; ax <= 1; ++ax)
      for (int ay = -1; ay <= 1; ++ay)
        for (int az = -1; az <= 1; ++az) {
          const int a[3] = {ax, ay, az};
          int id[3];
          CellRun& r = one[static_cast<std::size_t>(k++)];
          for (int d = 0; d < 3; ++d) {
            const int u = c0[d] + a[d];
            id[d] = (u + nc[d]) % nc[d];
            r.shift[d] = u >= nc[d] ? box_[static_cast<std::size_t>(d)]
                         : u < 0    ? -box_[static_cast<std::size_t>(d)]
                                    : 0.0;
          }
          r.first = (static_cast<std::size_t>(id[0]) * nc[1] + id[1]) * nc[2] + id[2];
          r.end = r.first + 1;
        }
    // 27 distinct cells: nc >= 3 along every axis.
    std::sort(one.begin(), one.end(), [](const CellRun& p, const CellRun& q) { return p.first < q.first; });
    int m = 0;
    for (const CellRun& r : one) {
      CellRun* last = m > 0 ? &out[static_cast<std::size_t>(m - 1)] : nullptr;
      if (last != nullptr && last->end == r.first && last->shift[0] == r.shift[0] && last->shift[1] == r.shift[1] &&
          last->shift[2] == r.shift[2]) {
        last->end = r.end;
      } else {
        out[static_cast<std::size_t>(m++)] = r;
      }
    }
    return m;
  };
  // Where the half-list rows will run (AVX-512 with the table on a cell grid), only the pairs
  // t > s are listed (neighbour cells of larger id, and the later slots of the own cell): half
  // the distance checks. Full rows are then derived on demand (full_rows()).
  // The plan follows the instruction-set level at set_positions (lists, cache layout, row kernels).
  avx512_rows_ = simd_level() == SimdLevel::avx512;
  half_lists_ = cells && use_table_ && avx512_rows_ && !full_lists_only_;
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  const bool avx2_filter = !half_lists_ && avx2_window_kernels(1);  // CPU and toggle: window_avx2.hpp
#endif
  full_ready_ = !half_lists_;
  // One pass: blocks of consecutive cells (consecutive slots) fill buffers of their own, which are
  // then concatenated in block order.
  const std::size_t block_cells = std::max<std::size_t>(1, ncell / 512);
  const std::size_t nblock = (ncell + block_cells - 1) / block_cells;
  auto& block_list = block_lists_;
  block_list.resize(nblock);
  begin_.assign(n + 1, 0);
  const auto nb = static_cast<std::int64_t>(nblock);
#pragma omp parallel if (n >= 2048)
  {
    // Per thread: the block's entries go to a buffer that only grows (no zero-fill per
    // candidate cell, no shared vector headers written per candidate: block_list's headers
    // are adjacent in memory, and writing them from two threads at every resize made the
    // build slower with 2 threads than with 1), then are copied out once per block.
    std::array<CellRun, 27> runs{};
    std::vector<double> d2;  // squared distances to one run's slots
    std::vector<int> buf;
#pragma omp for schedule(dynamic, 1)
    for (std::int64_t b = 0; b < nb; ++b) {
      std::size_t used = 0;
      const std::size_t c_end = std::min(ncell, (static_cast<std::size_t>(b) + 1) * block_cells);
      for (std::size_t c = static_cast<std::size_t>(b) * block_cells; c < c_end; ++c) {
        const int m = neighbour_runs(c, runs);
        for (std::size_t s = cell_begin[c]; s < cell_begin[c + 1]; ++s) {
          const std::size_t before = used;
          for (int k = 0; k < m; ++k) {
            const CellRun& run = runs[static_cast<std::size_t>(k)];
            if (half_lists_ && run.end <= c) continue;
            // Half lists: the cells of larger id and the later slots of the own cell.
            const std::size_t t0 = !half_lists_ ? cell_begin[run.first] : run.first > c ? cell_begin[run.first] : s + 1;
            const std::size_t count = cell_begin[run.end] - t0;
            // Distances first (a loop that vectorizes), then a branch-free compaction: about one
            // candidate in six is kept, so a branch per candidate would mostly mispredict.
            if (buf.size() < used + count + 16) buf.resize(2 * (used + count + 16));
            int* out = buf.data();
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
            if (half_lists_) {  // AVX-512 active; t0 > s, so the own slot is never a candidate
              const double xs[3] = {px[s], py[s], pz[s]};
              used += pairs_within_avx512(px.data(), py.data(), pz.data(), t0, count, xs, run.shift, rc2, out + used);
              continue;
            }
            if (cells && avx2_filter) {  // full lists on a CPU with AVX2
              const double xs[3] = {px[s], py[s], pz[s]};
              used += pairs_within_avx2(px.data(), py.data(), pz.data(), t0, count, xs, run.shift, rc2, s, out + used);
              continue;
            }
#endif
            if (d2.size() < count) d2.resize(count);
            squared_distances(s, t0, count, cells ? run.shift : nullptr, d2.data());
            for (std::size_t q = 0; q < count; ++q) {
              out[used] = static_cast<int>(t0 + q);
              used += static_cast<std::size_t>(d2[q] < rc2) & static_cast<std::size_t>(t0 + q != s);
            }
          }
          begin_[s + 1] = used - before;
        }
      }
      block_list[static_cast<std::size_t>(b)].assign(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(used));
    }
  }
  for (std::size_t s = 0; s < n; ++s) begin_[s + 1] += begin_[s];
  list_.resize(begin_[n]);
#pragma omp parallel for schedule(static) if (n >= 2048)
  for (std::int64_t b = 0; b < nb; ++b) {
    const auto& part = block_list[static_cast<std::size_t>(b)];
    const std::size_t first_slot = cell_begin[static_cast<std::size_t>(b) * block_cells];
    std::copy(part.begin(), part.end(), list_.begin() + static_cast<std::ptrdiff_t>(begin_[first_slot]));
  }
  // Half lists: the tail of each (ascending) row past its own slot (the whole row when only
  // those were listed).
  upper_.resize(n);
  for (std::size_t s = 0; s < n; ++s) {
    if (half_lists_) {
      upper_[s] = begin_[s];
      continue;
    }
    const auto row_begin = list_.begin() + static_cast<std::ptrdiff_t>(begin_[s]);
    const auto row_end = list_.begin() + static_cast<std::ptrdiff_t>(begin_[s + 1]);
    upper_[s] =
        begin_[s] + static_cast<std::size_t>(std::upper_bound(row_begin, row_end, static_cast<int>(s)) - row_begin);
  }
  for (auto& colour : half_blocks_) colour.clear();
  half_ = cells;
  if (half_) plan_half_blocks(nc, cell_begin);
  // Pair cache: where the AVX-512 half rows run (table, cell grid), chunks of eight pairs per
  // half row, five lanes each; where the portable rows run (no AVX-512, table), five values per
  // entry of the full rows. Kept where it fits in the limit, else released.
  cache_rows_ = !avx512_rows_;
  chunk_begin_.assign(n + 1, 0);
  for (std::size_t s = 0; s < n; ++s) chunk_begin_[s + 1] = chunk_begin_[s] + (begin_[s + 1] - upper_[s] + 7) / 8;
  const std::size_t value_bytes = cache_ == PairCache::single_precision ? sizeof(float) : sizeof(double);
  cache_bytes_ = cache_rows_ ? 5 * value_bytes * begin_[n] : 40 * value_bytes * chunk_begin_[n];
  cache_on_ = cache_ != PairCache::off && use_table_ && (cache_rows_ || half_) && cache_bytes_ <= cache_limit_;
  cache_ready_ = false;
  if (cache_on_) {
    // Grown with 25% headroom and never value-initialized (the filling product writes every
    // chunk): the pair count changes a little at every step, and a std::vector would copy and
    // zero-fill tens of MB whenever it grows.
    const std::size_t need = cache_bytes_ / sizeof(double) + 8;
    if (cache_capacity_ < need) {
      cache_store_.reset();
      cache_capacity_ = need + need / 4;
      cache_store_ = std::make_unique_for_overwrite<double[]>(cache_capacity_);
    }
  } else {
    cache_store_.reset();
    cache_capacity_ = 0;
  }
}

void* RealSpaceSum::cache_data() const {
  double* c = cache_store_.get();
  return c + (8 - (reinterpret_cast<std::uintptr_t>(c) / sizeof(double)) % 8) % 8;  // 64-byte aligned
}

void RealSpaceSum::plan_half_blocks(const std::array<int, 3>& nc, const std::vector<std::size_t>& cell_begin) {
  // Slot s writes to the slots t > s of the 27 cells around it, i.e. to cells of larger id:
  // layer x + 1 (any y, z), or x with y + 1 (any z), or x, y with z + 1; by the periodic wrap
  // also the last layer from the first one along each axis (x = nc_x - 1 from x = 0, and so
  // on). A block of layers [a, b) along x or y thus writes within [a, b] along x and within
  // [a - 1, b] along y (cyclically): it reaches only the first layer of the next block and the
  // last layer of the previous one. x and y, where they have >= 4 layers, are cut into an even
  // number of blocks, each >= 2 layers wide (an axis of 3 layers stays whole); a block's colour
  // is its parity along the cut axes. Two blocks of one colour are then at least one block
  // apart along a cut axis, where their footprints miss each other (design note 22). z is not
  // cut: a block then sweeps whole cell columns in slot order, which keeps the neighbours' rows
  // in cache (cutting z too, for more blocks a colour, made the product 1.2-1.3x slower).
  auto axis_blocks = [](int layers) {
    if (layers < 4) return std::vector<int>{0, layers};
    int count = layers / 2;
    if (count % 2 == 1) --count;  // even, >= 2; widths layers / count >= 2
    std::vector<int> start(static_cast<std::size_t>(count) + 1);
    for (int k = 0; k <= count; ++k) start[static_cast<std::size_t>(k)] = k * layers / count;
    return start;
  };
  const auto xs = axis_blocks(nc[0]), ys = axis_blocks(nc[1]);
  const auto ny = static_cast<std::size_t>(nc[1]), nz = static_cast<std::size_t>(nc[2]);
  for (std::size_t i = 0; i + 1 < xs.size(); ++i)
    for (std::size_t j = 0; j + 1 < ys.size(); ++j) {
      // The cells (x, y0 ... y1 - 1, all z) are consecutive ids: one slot range per x layer.
      std::vector<SlotRange> block;
      for (int x = xs[i]; x < xs[i + 1]; ++x) {
        const std::size_t first = cell_begin[(static_cast<std::size_t>(x) * ny + static_cast<std::size_t>(ys[j])) * nz];
        const std::size_t last =
            cell_begin[(static_cast<std::size_t>(x) * ny + static_cast<std::size_t>(ys[j + 1])) * nz];
        if (last > first) block.push_back({first, last});
      }
      if (!block.empty()) half_blocks_[2 * (i % 2) + (j % 2)].push_back(std::move(block));
    }
}

namespace {

/// row(s, r) for every half row s and rhs r: colours one after another, the blocks of one colour
/// in parallel (design note 22).
template <class Blocks, class Row>
void sweep_half_rows(const Blocks& colours, std::size_t n, std::size_t nrhs, Row&& row) {
  for (const auto& colour : colours) {
    const auto nblock = static_cast<std::int64_t>(colour.size());
#pragma omp parallel for schedule(dynamic, 1) if (n * nrhs >= 512)
    for (std::int64_t b = 0; b < nblock; ++b)
      for (const auto& range : colour[static_cast<std::size_t>(b)])
        for (std::size_t s = range.begin; s < range.end; ++s)
          for (std::size_t r = 0; r < nrhs; ++r) row(s, r);
  }
}

}  // namespace

void RealSpaceSum::apply_half_avx512(const double* packed, const double* table, double inv_dr, const double L[3],
                                     const double inv_L[3], std::size_t nrhs, double* acc) const {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  const std::size_t n = order_.size();
  const bool fill = cache_on_ && !cache_rows_ && !cache_ready_;
  auto sweep = [&](auto* cache) {  // void*: no cache
    using T = std::remove_pointer_t<decltype(cache)>;
    sweep_half_rows(half_blocks_, n, nrhs, [&](std::size_t s, std::size_t r) {
      T* chunk = nullptr;
      if constexpr (!std::is_void_v<T>) chunk = cache + 40 * chunk_begin_[s];
      packed_half_row_avx512(list_.data() + upper_[s], begin_[s + 1] - upper_[s], s, packed + 8 * r * n, table, inv_dr,
                             L, inv_L, acc + 4 * r * n, chunk);
    });
  };
  if (!fill)
    sweep(static_cast<void*>(nullptr));
  else if (cache_ == PairCache::single_precision)
    sweep(static_cast<float*>(cache_data()));
  else
    sweep(static_cast<double*>(cache_data()));
  cache_ready_ = cache_ready_ || fill;
#else
  (void)packed, (void)table, (void)inv_dr, (void)L, (void)inv_L, (void)nrhs, (void)acc;
#endif
}

void RealSpaceSum::apply_cached_avx512(const double* forces, std::size_t nrhs, double* acc) const {
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  const std::size_t n = order_.size();
  auto sweep = [&](const auto* cache) {
    sweep_half_rows(half_blocks_, n, nrhs, [&](std::size_t s, std::size_t r) {
      cached_half_row_avx512(list_.data() + upper_[s], begin_[s + 1] - upper_[s], s, forces + 4 * r * n,
                             cache + 40 * chunk_begin_[s], table_.data().data(), acc + 4 * r * n);
    });
  };
  if (cache_ == PairCache::single_precision)
    sweep(static_cast<const float*>(cache_data()));
  else
    sweep(static_cast<const double*>(cache_data()));
#else
  (void)forces, (void)nrhs, (void)acc;
#endif
}

RealSpaceSum::Rows RealSpaceSum::full_rows() const {
  if (!half_lists_) return {begin_.data(), list_.data()};
  if (!full_ready_) {
    // Row t = its lower part {s < t : t in half row s}, ascending, then its half row.
    const std::size_t n = order_.size();
    full_begin_.assign(n + 1, 0);
    for (std::size_t s = 0; s < n; ++s) {
      full_begin_[s + 1] += begin_[s + 1] - begin_[s];
      for (std::size_t q = begin_[s]; q < begin_[s + 1]; ++q) ++full_begin_[static_cast<std::size_t>(list_[q]) + 1];
    }
    for (std::size_t s = 0; s < n; ++s) full_begin_[s + 1] += full_begin_[s];
    full_list_.resize(full_begin_[n]);
    std::vector<std::size_t> fill(full_begin_.begin(), full_begin_.end() - 1);
    for (std::size_t s = 0; s < n; ++s) {  // row s's lower part is complete: it comes from rows < s
      for (std::size_t q = begin_[s]; q < begin_[s + 1]; ++q) full_list_[fill[s]++] = list_[q];
      for (std::size_t q = begin_[s]; q < begin_[s + 1]; ++q)
        full_list_[fill[static_cast<std::size_t>(list_[q])]++] = static_cast<int>(s);
    }
    full_ready_ = true;
  }
  return {full_begin_.data(), full_list_.data()};
}

void RealSpaceSum::input_order_lists(std::vector<std::size_t>& begin, std::vector<int>& list) const {
  const std::size_t n = order_.size();
  const Rows rows = full_rows();
  std::vector<std::size_t> slot_of(n);
  for (std::size_t s = 0; s < n; ++s) slot_of[order_[s]] = s;
  begin.assign(n + 1, 0);
  for (std::size_t i = 0; i < n; ++i) begin[i + 1] = begin[i] + (rows.begin[slot_of[i] + 1] - rows.begin[slot_of[i]]);
  list.resize(begin[n]);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t s = slot_of[i];
    auto out = list.begin() + static_cast<std::ptrdiff_t>(begin[i]);
    for (std::size_t q = rows.begin[s]; q < rows.begin[s + 1]; ++q)
      *out++ = static_cast<int>(order_[static_cast<std::size_t>(rows.list[q])]);
    std::sort(list.begin() + static_cast<std::ptrdiff_t>(begin[i]), out);
  }
}

RealSpaceSum::SlotLists RealSpaceSum::slot_lists() const {
  const std::size_t n = order_.size();
  const Rows rows = full_rows();
  return {order_, {rows.begin, n + 1}, {rows.list, rows.begin[n]}};
}

void RealSpaceSum::apply(const double* forces, double* out, std::size_t nrhs, bool accumulate) const {
  // Where the pair cache is kept, the first product after set_positions fills it and every
  // product (this one included) applies the blocks as kept, rounded to the cache's precision: the
  // operator is the same whatever was called before (docs/reproducibility.md).
  apply_mapped(forces, out, nrhs, accumulate, order_.data());
}

void RealSpaceSum::apply_slots(const double* forces, double* out, std::size_t nrhs) const {
  apply_mapped(forces, out, nrhs, false, nullptr);
}

void RealSpaceSum::to_slots(const double* in, double* out) const {
  const std::size_t n = order_.size();
  for (std::size_t s = 0; s < n; ++s)
    for (std::size_t d = 0; d < 3; ++d) out[3 * s + d] = in[3 * order_[s] + d];
}

void RealSpaceSum::from_slots(const double* in, double* out) const {
  const std::size_t n = order_.size();
  for (std::size_t s = 0; s < n; ++s)
    for (std::size_t d = 0; d < 3; ++d) out[3 * order_[s] + d] = in[3 * s + d];
}

void RealSpaceSum::apply_mapped(const double* forces, double* out, std::size_t nrhs, bool accumulate,
                                const std::size_t* map) const {
  // U_i = M0 [ F(0) F_i + sum_{j in r_cut} (F (I - rr) + G rr) F_j ]   ([PSE] eq. 10, A1-A4)
  const std::size_t n = order_.size();
  auto index = [map](std::size_t s) { return map != nullptr ? map[s] : s; };
  const std::size_t stride = 3 * n;
  const std::array<double, 3> inv = {1.0 / box_[0], 1.0 / box_[1], 1.0 / box_[2]};
  const auto ni = static_cast<std::int64_t>(n);
  const bool par = n * nrhs >= 512;
  auto store = [&](std::size_t r, std::size_t i, const double* u) {
    for (std::size_t d = 0; d < 3; ++d) {
      double& o = out[r * stride + 3 * i + d];
      o = accumulate ? o + m0_ * u[d] : m0_ * u[d];
    }
  };
  // For every slot s and rhs r: u = F(0) f_s (self term, force(s, r, d) in slot order), then
  // row(s, r, u) adds the pair sum, then u is stored.
  auto for_each_row = [&](auto&& force, auto&& row) {
#pragma omp parallel for schedule(dynamic, 64) if (par)
    for (std::int64_t ss = 0; ss < ni; ++ss) {
      const auto s = static_cast<std::size_t>(ss);
      for (std::size_t r = 0; r < nrhs; ++r) {
        double u[3] = {self_ * force(s, r, 0), self_ * force(s, r, 1), self_ * force(s, r, 2)};
        row(s, r, u);
        store(r, index(s), u);
      }
    }
  };
  const double* table = use_table_ ? table_.data().data() : nullptr;
  const double inv_dr = use_table_ ? 1.0 / table_.dr() : 0.0;
  const double L[3] = {box_[0], box_[1], box_[2]};
  const double inv_L[3] = {inv[0], inv[1], inv[2]};
#if defined(RPYFMM_HAVE_DIRECT_AVX512)
  if (use_table_ && avx512_rows_) {
    // Rows per slot and rhs, filled straight from the input forces: x, y, z, fx, fy, fz, 0, 0 (8
    // doubles, 64-byte aligned) where the pairs are evaluated, or fx, fy, fz, 0 (4 doubles) where
    // the pair cache holds them (later products with these positions). With half lists, also the
    // zeroed sums.
    const bool half = half_;
    const bool cached = half && cache_on_ && !cache_rows_ && cache_ready_;
    const std::size_t width = cached ? 4 : 8, force_at = cached ? 0 : 3;
    // (Never shrunk: growing back would zero-fill the tail at every switch of width.)
    if (packed_.size() < width * (n * nrhs + 1)) packed_.resize(width * (n * nrhs + 1));
    double* packed = packed_.data();
    packed += (width - (reinterpret_cast<std::uintptr_t>(packed) / sizeof(double)) % width) % width;
    if (half) acc_.resize(4 * n * nrhs + 4);
    double* acc = acc_.data();  // rows of 4 doubles, 32-byte aligned
    if (half) acc += (4 - (reinterpret_cast<std::uintptr_t>(acc) / sizeof(double)) % 4) % 4;
#pragma omp parallel for schedule(static) if (par)
    for (std::int64_t ss = 0; ss < ni; ++ss) {
      const auto s = static_cast<std::size_t>(ss);
      const std::size_t i = index(s);
      for (std::size_t r = 0; r < nrhs; ++r) {
        double* row = packed + width * (r * n + s);
        for (std::size_t d = 0; d < 3; ++d) {
          if (!cached) row[d] = pos_[d][s];
          row[force_at + d] = forces[r * stride + 3 * i + d];
        }
        std::fill(row + force_at + 3, row + width, 0.0);
        if (half) std::fill_n(acc + 4 * (r * n + s), 4, 0.0);
      }
    }
    auto packed_force = [&](std::size_t s, std::size_t r, std::size_t d) {
      return packed[width * (r * n + s) + force_at + d];
    };
    if (half) {
      if (cached) {
        apply_cached_avx512(packed, nrhs, acc);
      } else {
        apply_half_avx512(packed, table, inv_dr, L, inv_L, nrhs, acc);
      }
      for_each_row(packed_force, [&](std::size_t s, std::size_t r, double* u) {
        for (std::size_t d = 0; d < 3; ++d) u[d] += acc[4 * (r * n + s) + d];
      });
      return;
    }
    const Rows rows = full_rows();
    for_each_row(packed_force, [&](std::size_t s, std::size_t r, double* u) {
      packed_row_avx512(rows.list + rows.begin[s], rows.begin[s + 1] - rows.begin[s], s, packed + 8 * r * n, table,
                        inv_dr, L, inv_L, u);
    });
    return;
  }
#endif
  const Rows rows = full_rows();
  // Forces in slot order: work_[(3 r + d) n + s] = F_r[3 order_[s] + d].
  work_.resize(3 * n * nrhs);
#pragma omp parallel for schedule(static) if (par)
  for (std::int64_t s = 0; s < ni; ++s) {
    const std::size_t i = index(static_cast<std::size_t>(s));
    for (std::size_t r = 0; r < nrhs; ++r)
      for (std::size_t d = 0; d < 3; ++d)
        work_[(3 * r + d) * n + static_cast<std::size_t>(s)] = forces[r * stride + 3 * i + d];
  }
  auto slot_force = [&](std::size_t s, std::size_t r, std::size_t d) { return work_[(3 * r + d) * n + s]; };
  if (use_table_) {
    const bool row_cache = cache_on_ && cache_rows_;
    const bool cached = row_cache && cache_ready_, fill = row_cache && !cache_ready_;
    auto rows_with = [&](auto c) {  // c: RowCache<T>, or nullptr without the cache
      for_each_row(slot_force, [&](std::size_t s, std::size_t r, double* u) {
        const double* f = work_.data() + 3 * r * n;
        const double xs[3] = {pos_[0][s], pos_[1][s], pos_[2][s]};
        const SlotArrays arrays{{pos_[0].data(), pos_[1].data(), pos_[2].data()}, {f, f + n, f + 2 * n}};
        const int* nb = rows.list + rows.begin[s];
        const std::size_t count = rows.begin[s + 1] - rows.begin[s];
        if constexpr (std::is_same_v<decltype(c), std::nullptr_t>) {
          table_row(nb, count, xs, arrays, table, inv_dr, L, inv_L, u);
        } else if (cached) {
          cached_row(nb, count, arrays, table, c, rows.begin[s], u);
        } else {
          fill_row(nb, count, xs, arrays, table, inv_dr, L, inv_L, c, rows.begin[s], u);
        }
      });
    };
    if (!cached && !fill) {
      rows_with(nullptr);
    } else if (cache_ == PairCache::single_precision) {
      rows_with(RowCache<float>{static_cast<float*>(cache_data()), rows.begin[n]});
    } else {
      rows_with(RowCache<double>{static_cast<double*>(cache_data()), rows.begin[n]});
    }
    cache_ready_ = cache_ready_ || fill;
    return;
  }
  // Closed forms evaluated per pair (PseOptions::real_space_table = false: the reference the
  // table is measured against).
  for_each_row(slot_force, [&](std::size_t s, std::size_t r, double* u) {
    const double* f = work_.data() + 3 * r * n;
    for (std::size_t q = rows.begin[s]; q < rows.begin[s + 1]; ++q) {
      const auto t = static_cast<std::size_t>(rows.list[q]);
      const double d[3] = {minimum_image(pos_[0][s] - pos_[0][t], box_[0], inv[0]),
                           minimum_image(pos_[1][s] - pos_[1][t], box_[1], inv[1]),
                           minimum_image(pos_[2][s] - pos_[2][t], box_[2], inv[2])};
      const double ft[3] = {f[t], f[n + t], f[2 * n + t]};
      const double dist = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (dist == 0.0) {  // coincident particles: F(0) = G(0), the block is F(0) I
        for (int c = 0; c < 3; ++c) u[c] += self_ * ft[c];
        continue;
      }
      const FG v = real_space_fg(dist, p_.xi, p_.radius);
      pair_block_add(d[0], d[1], d[2], dist, v.f, v.g, ft, u);
    }
  });
}

}  // namespace rpyfmm::rpy::pse::detail
