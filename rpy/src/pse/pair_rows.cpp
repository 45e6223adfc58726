// rpyfmm — the portable rows of the PSE real-space product ([PSE] eq. 10 with App. A;
// docs/theory/pse.md).
#include "pair_rows.hpp"

#include <cmath>

#include "kernels_common.hpp"
#include "rpyfmm/core/simd_dispatch.hpp"
#include "rpyfmm/rpy/pse/real_space.hpp"

namespace rpyfmm::rpy::pse::detail {

namespace {

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

}  // namespace

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

namespace {

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

}  // namespace

// Entry points, each compiled per instruction-set level (simd_dispatch), instantiated for the
// float and the double cache.
template <class T>
void fill_row(const int* nb, std::size_t count, const double xi[3], const SlotArrays& s, const double* table,
              double inv_dr, const double L[3], const double inv_L[3], RowCache<T> c, std::size_t first, double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY {
    keep_row_body(nb, count, xi, s, table, inv_dr, L, inv_L, c, first);
    cached_row_body(nb, count, s, table, c, first, u);
  });
}

template <class T>
void cached_row(const int* nb, std::size_t count, const SlotArrays& s, const double* table, RowCache<T> c,
                std::size_t first, double u[3]) {
  simd_dispatch([=]() RPYFMM_SIMD_BODY { cached_row_body(nb, count, s, table, c, first, u); });
}

template void fill_row(const int*, std::size_t, const double[3], const SlotArrays&, const double*, double,
                       const double[3], const double[3], RowCache<float>, std::size_t, double[3]);
template void fill_row(const int*, std::size_t, const double[3], const SlotArrays&, const double*, double,
                       const double[3], const double[3], RowCache<double>, std::size_t, double[3]);
template void cached_row(const int*, std::size_t, const SlotArrays&, const double*, RowCache<float>, std::size_t,
                         double[3]);
template void cached_row(const int*, std::size_t, const SlotArrays&, const double*, RowCache<double>, std::size_t,
                         double[3]);

void closed_form_row(const int* nb, std::size_t count, const double xi[3], const SlotArrays& s, const double L[3],
                     const double inv_L[3], double self, double xi_ewald, double radius, double u[3]) {
  for (std::size_t q = 0; q < count; ++q) {
    const auto t = static_cast<std::size_t>(nb[q]);
    const double d[3] = {minimum_image(xi[0] - s.x[0][t], L[0], inv_L[0]),
                         minimum_image(xi[1] - s.x[1][t], L[1], inv_L[1]),
                         minimum_image(xi[2] - s.x[2][t], L[2], inv_L[2])};
    const double ft[3] = {s.f[0][t], s.f[1][t], s.f[2][t]};
    const double dist = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (dist == 0.0) {  // coincident particles: F(0) = G(0), the block is F(0) I
      for (int c = 0; c < 3; ++c) u[c] += self * ft[c];
      continue;
    }
    const FG v = real_space_fg(dist, xi_ewald, radius);
    pair_block_add(d[0], d[1], d[2], dist, v.f, v.g, ft, u);
  }
}

}  // namespace rpyfmm::rpy::pse::detail
