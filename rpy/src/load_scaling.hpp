// rpyfmm — what every product shares (private): the power-of-two load scaling of the forces and
// the check that a product of finite inputs stayed finite. Used by MobilityOperator's products and
// by DirectRpy::apply_rows, whose rows must be scaled exactly as apply()'s.
#pragma once

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::detail {

// Loads (forces, torques) whose largest entry lies outside [2^-100, 2^100] are applied as 2^-k F with that entry in
// [1, 2), then scaled back: M is linear and scaling by a power of two is exact, so ordinary forces
// keep their bitwise results, while forces near 1e308 (whose pair terms d (d . F) overflowed although
// M F does not), beyond single precision (PSE's grids and pair cache for tolerances >= 1e-5) or near
// 1e-300 (digits lost in those grids) are evaluated as accurately as ordinary ones. 0: no scaling.
// Forces and torques share one power of two (M [F; T] is linear in both together).
inline int load_scale_exponent(std::initializer_list<std::span<const double>> loads) {
  double largest = 0.0;
  for (const auto load : loads)
    for (double f : load) largest = std::max(largest, std::abs(f));
  if (largest == 0.0 || (largest >= 0x1p-100 && largest <= 0x1p100)) return 0;
  return std::ilogb(largest);
}

// The largest load of [F; T] with the torques measured as forces, T / l with l = 2^ilogb(largest radius)
// (a torque is a force times a length): its load_scale_exponent is the products' with rotation. Lengths
// and torques of 2^(+-400) with forces of order one then need no scaling, where scaling by the torques
// alone would push W (~ T / a^3) out of range inside the product.
inline double largest_rotation_load(std::span<const double> forces, std::span<const double> torques,
                                    double largest_radius) {
  const int length = std::ilogb(largest_radius);
  double largest = 0.0;
  for (double f : forces) largest = std::max(largest, std::abs(f));
  for (double t : torques) largest = std::max(largest, std::abs(std::ldexp(t, -length)));
  return largest;
}

// Finite inputs whose product overflows (forces so large, or radii so small, that M F is beyond
// double precision) give Inf or NaN: refused, naming the first entry, rather than returned.
inline void require_finite_result(std::span<const double> out, const std::string& where, const char* name,
                                  const char* input) {
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (std::isfinite(out[i])) continue;
    fail(ErrorCode::numerical_failure, where,
         std::string(name) + " entry (" + std::to_string(i / 3) + ", " + std::to_string(i % 3) + ") is " +
             (std::isnan(out[i]) ? "NaN" : "infinite") + ": the product overflows double precision (scale the " +
             input + " down and the result up)");
  }
}

}  // namespace rpyfmm::rpy::detail
