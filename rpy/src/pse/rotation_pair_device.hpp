// rpyfmm — the rotational PSE real-space blocks per pair and per row, for host and device
// (docs/theory/pse.md Sec. 5; rotation_real_space.hpp): the CPU rows (rotation_real_space_sum.cpp)
// and the CUDA rows (cuda_rotation.cuh) add the same per-pair terms; the CUDA rows' accumulation and
// store are here too, so that the host tests run them. Private.
#pragma once

#include <cmath>

#include "kernels_common.hpp"  // minimum_image, RPYFMM_HOST_DEVICE

namespace rpyfmm::rpy::pse::detail {

/// PseRotationTable's interpolation data: nodes (c, h, k) three per node, 1 / dr and the units of
/// c and of h, k.
struct RotationTableView {
  const double* nodes;
  double inv_dr, unit_c, unit_hk;
};

/// The terms of neighbour q at displacement d = x_i - x_q (minimum image, |d| < r_cut) with force f
/// and torque t, times the viscosity: u = c (t x e), w = c (f x e) + h t + k (e . t) e, e = d / |d|
/// (Fiore & Swan 2018; the free-space structure of Wajnryb et al. 2013). A coincident neighbour
/// (d = 0) gets e = 0 and the table's r = 0 node: w = h(0) t, the self block's form. Plain double
/// arguments and results, table loads indexed from the table's base: inlined into the CPU row's
/// loop body, GCC still turns the loop into vector gathers.
struct RotationPairTerms {
  double ux, uy, uz, wx, wy, wz;
};

RPYFMM_HOST_DEVICE inline RotationPairTerms rotation_pair_terms(double dx, double dy, double dz, double fx, double fy,
                                                                double fz, double tx, double ty, double tz,
                                                                const RotationTableView& tv) {
  const double r2 = dx * dx + dy * dy + dz * dz;
  const double r = std::sqrt(r2);
  const double inv_r = r2 > 0.0 ? 1.0 / r : 0.0;
  double at = r * tv.inv_dr;
  const int node = static_cast<int>(at);
  at -= static_cast<double>(node);
  const int b = 3 * node;
  const double* tab = tv.nodes;
  const double c = tv.unit_c * (tab[b] + at * (tab[b + 3] - tab[b]));
  const double h = tv.unit_hk * (tab[b + 1] + at * (tab[b + 4] - tab[b + 1]));
  const double k = tv.unit_hk * (tab[b + 2] + at * (tab[b + 5] - tab[b + 2]));
  const double ex = dx * inv_r, ey = dy * inv_r, ez = dz * inv_r;
  const double et = k * (ex * tx + ey * ty + ez * tz);
  return {c * (ty * ez - tz * ey),
          c * (tz * ex - tx * ez),
          c * (tx * ey - ty * ex),
          c * (fy * ez - fz * ey) + h * tx + et * ex,
          c * (fz * ex - fx * ez) + h * ty + et * ey,
          c * (fx * ey - fy * ex) + h * tz + et * ez};
}

/// One rotational real-space product in slot order (3 doubles per particle): u += (1 / eta)
/// M_r^{UT} (s_t t) and w = s_w (1 / eta) (M_r^{WF} f + M_r^{WT} (s_t t)), with the self block h(0) on
/// the diagonal. s_t = s_w = 1 for a product; s_t = s_w = a for the split sampler's S M_r S
/// (S = diag(I, a I)). The CUDA rows (cuda_rotation.cuh) sum one particle per thread with it.
struct RotationRows {
  const double* x;
  const double* f;
  const double* t;
  double* u;
  double* w;
  RotationTableView table;
  double self;  ///< h(0) times eta (PseRotationTable::self)
  double inv_mu;
  double torque_scale, angular_scale;
  double L[3], inv_L[3];
};

/// The minimum-image displacement x_i - x_j of slots i (at xi) and j.
RPYFMM_HOST_DEVICE inline void rotation_displacement(const RotationRows& r, int j, const double xi[3], double d[3]) {
  for (int c = 0; c < 3; ++c) d[c] = minimum_image(xi[c] - r.x[3 * j + c], r.L[c], r.inv_L[c]);
}

/// acc (u then w) += the terms of neighbour slot j of the particle at xi.
RPYFMM_HOST_DEVICE inline void rotation_pair_add(const RotationRows& r, int j, const double xi[3], double acc[6]) {
  double d[3];
  rotation_displacement(r, j, xi, d);
  const double s = r.torque_scale;
  const RotationPairTerms p = rotation_pair_terms(d[0], d[1], d[2], r.f[3 * j], r.f[3 * j + 1], r.f[3 * j + 2],
                                                  s * r.t[3 * j], s * r.t[3 * j + 1], s * r.t[3 * j + 2], r.table);
  acc[0] += p.ux;
  acc[1] += p.uy;
  acc[2] += p.uz;
  acc[3] += p.wx;
  acc[4] += p.wy;
  acc[5] += p.wz;
}

/// Row i's sums stored: u added, w set (see RotationRows), with the self block.
RPYFMM_HOST_DEVICE inline void rotation_row_store(const RotationRows& r, int i, const double acc[6]) {
  for (int c = 0; c < 3; ++c) {
    r.u[3 * i + c] += r.inv_mu * acc[c];
    r.w[3 * i + c] = r.angular_scale * r.inv_mu * (r.self * r.torque_scale * r.t[3 * i + c] + acc[3 + c]);
  }
}

}  // namespace rpyfmm::rpy::pse::detail
