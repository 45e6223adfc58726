// Sums of the exact rotational pair couplings of rpy_rotation_kernel.hpp (docs/theory/rpy.md,
// section 7; Wajnryb, Mizerski, Zuk & Szymczak 2013) over sources in structure-of-arrays form, for
// one target at a time: DirectRpy's rotational blocks (all sources) and FmmRpy's near field
// (gathered sources).
//
// For d = x_i - x_q the three sums of target i, times eta and grouped by the power of length they
// carry (for the units of length_units.hpp):
//   ut_i += c_ut(i, q) (T_q x e),  wf_i += c_ut(q, i) (F_q x e),  rr_i += (h I + k e e^T) T_q.
#pragma once

#include <cstddef>

namespace rpyfmm::rpy::detail {

/// Gathered sources in structure-of-arrays form; radius a == nullptr means equal radii (the
/// target's).
struct RotationSources {
  std::size_t m = 0;
  const double *x = nullptr, *y = nullptr, *z = nullptr, *a = nullptr;
  const std::size_t* id = nullptr;
  const double *fx = nullptr, *fy = nullptr, *fz = nullptr;
  const double *tx = nullptr, *ty = nullptr, *tz = nullptr;
};

struct RotationTarget {
  double x, y, z, a;
  std::size_t i;
  double f[3], t[3];  // the target's own force and torque (symmetric blocks)
};

struct RotationSums {
  double ut[3], wf[3], rr[3];
};

/// Per-source accumulators of the reverse direction (q <- i), in the sums' layout.
struct RotationAccumulators {
  double *ut[3], *wf[3], *rr[3];
};

/// out = the three sums of the target over the sources; the self pair (id[q] == target.i) skipped.
void near_rotation_sum(const RotationSources& src, const RotationTarget& target, RotationSums& out);

/// Both directions between the target and sources of another leaf (never the target itself):
/// out = the target's sums, and each source's sums from the target added to acc.
void near_rotation_sum_symmetric(const RotationSources& src, const RotationTarget& target,
                                 const RotationAccumulators& acc, RotationSums& out);

}  // namespace rpyfmm::rpy::detail
