// Sums of the exact grand-mobility pair blocks over sources in structure-of-arrays form, for one
// target at a time: the translational block of rpy_kernel.hpp and the rotational couplings of
// rpy_rotation_kernel.hpp (docs/theory/rpy.md, section 7; Wajnryb, Mizerski, Zuk & Szymczak 2013).
// DirectRpy sums all sources, FmmRpy's near field the gathered sources of adjacent leaves.
//
// For d = x_i - x_q, e = d / r, times eta:
//   U_i += M^tt_iq F_q + c_ut(i, q) (T_q x e),   W_i += c_ut(q, i) (F_q x e) + (h I + k e e^T) T_q.
// Length units (length_units.hpp): with lengths in units 2^s the blocks carry 1/L (tt), 1/L^2
// (ut, wf) and 1/L^3 (rr); callers pass torques scaled by 2^-s, so that U and W come out as
// 2^s U_true and 2^(2s) W_true (one power of two each, applied by the caller).
#pragma once

#include <cstddef>

namespace rpyfmm::rpy::detail {

/// Sources in structure-of-arrays form; radius a == nullptr means equal radii (the target's).
struct GrandSources {
  std::size_t m = 0;
  const double *x = nullptr, *y = nullptr, *z = nullptr, *a = nullptr;
  const std::size_t* id = nullptr;
  const double *fx = nullptr, *fy = nullptr, *fz = nullptr;
  const double *tx = nullptr, *ty = nullptr, *tz = nullptr;
};

struct GrandTarget {
  double x, y, z, a;
  std::size_t i;
  double f[3], t[3];  // the target's own force and torque (symmetric blocks)
};

/// Velocity and angular velocity sums of one target (times eta).
struct GrandSums {
  double u[3], w[3];
};

/// Per-source accumulators of the reverse direction (q <- i).
struct GrandAccumulators {
  double *u[3], *w[3];
};

/// out = the target's sums over the sources; the self pair (id[q] == target.i) skipped.
void grand_pair_sum(const GrandSources& src, const GrandTarget& target, GrandSums& out);

/// The same without the translational block: U gets c_ut (T x e) only (DirectRpy, whose
/// translational product has its own kernels).
void rotation_pair_sum(const GrandSources& src, const GrandTarget& target, GrandSums& out);

/// Both directions between the target and sources of another leaf (never the target itself):
/// out = the target's sums, and each source's sums from the target added to acc.
void grand_pair_sum_symmetric(const GrandSources& src, const GrandTarget& target, const GrandAccumulators& acc,
                              GrandSums& out);

}  // namespace rpyfmm::rpy::detail
