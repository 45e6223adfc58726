// rpyfmm — one pair of the rotational PSE real-space blocks, for host and device (docs/theory/pse.md
// section 5; rotation_real_space.hpp): the CPU rows (rotation_real_space_sum.cpp) and the CUDA rows
// (cuda_rotation.cuh) add the same terms. Private.
#pragma once

#include <cmath>

#include "rpyfmm/rpy/random.hpp"  // RPYFMM_HOST_DEVICE

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

}  // namespace rpyfmm::rpy::pse::detail
