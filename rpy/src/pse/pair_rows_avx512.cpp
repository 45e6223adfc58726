// rpyfmm — the AVX-512 rows of the PSE real-space product ([PSE] eq. 10 with App. A via the
// linear table; docs/theory/pse.md): full rows, half rows (each pair once for both of its rows),
// and half rows from the pair cache.
#include "pair_rows_avx512.hpp"

#if defined(RPYFMM_HAVE_DIRECT_AVX512)

#include <algorithm>
#include <cstddef>
#include <type_traits>

namespace rpyfmm::rpy::pse::detail {

namespace {

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

}  // namespace

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

namespace {

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

}  // namespace

/// The half-list row (docs/theory/pse.md): for the neighbours nb[0..count) of slot `self` with larger
/// slots, acc[4 self + c] += sum_t B_st f_t and acc[4 t + c] += B_st f_s (B is symmetric: e
/// changes sign with the pair's direction and appears twice). With a pair cache, the
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

namespace {

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

}  // namespace

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

template void packed_half_row_avx512<void>(const int*, std::size_t, std::size_t, const double*, const double*, double,
                                           const double[3], const double[3], double*, void*);
template void packed_half_row_avx512<float>(const int*, std::size_t, std::size_t, const double*, const double*, double,
                                            const double[3], const double[3], double*, float*);
template void packed_half_row_avx512<double>(const int*, std::size_t, std::size_t, const double*, const double*, double,
                                             const double[3], const double[3], double*, double*);
template void cached_half_row_avx512<float>(const int*, std::size_t, std::size_t, const double*, const float*,
                                            const double*, double*);
template void cached_half_row_avx512<double>(const int*, std::size_t, std::size_t, const double*, const double*,
                                             const double*, double*);

#pragma GCC diagnostic pop

}  // namespace rpyfmm::rpy::pse::detail

#endif  // RPYFMM_HAVE_DIRECT_AVX512
