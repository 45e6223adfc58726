// rpyfmm — the rotational blocks of the PSE real-space part on the CPU (rotation_real_space.hpp;
// docs/theory/pse.md Sec. 5): U += M_r^{UT} T and W += M_r^{WF} F + M_r^{WT} T over the
// translational sum's neighbour lists (the UF block stays RealSpaceSum's). Private.
#pragma once

#include <array>
#include <span>
#include <vector>

#include "real_space_sum.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"
#include "rpyfmm/rpy/pse/rotation_real_space.hpp"

namespace rpyfmm::rpy::pse::detail {

class RotationRealSpaceSum {
 public:
  /// Tabulates the coefficients for the plan's xi, radius and r_cut (table tolerance tolerance / 10,
  /// as the translational table).
  RotationRealSpaceSum(const PseParameters& p, const std::array<double, 3>& box, double viscosity);

  /// U += M_r^{UT} T, W += M_r^{WF} F + M_r^{WT} T (3N each, input order) for positions x (wrapped
  /// into the box) with the neighbour lists `lists` of the same positions. Each particle's row is
  /// summed by one thread, in the vector lanes of its instruction-set level: the result does not
  /// depend on the thread count or on earlier calls.
  void apply(const RealSpaceSum::SlotLists& lists, std::span<const double> x, const double* forces,
             const double* torques, double* velocities, double* angular) const;

  [[nodiscard]] const PseRotationTable& table() const { return table_; }

 private:
  std::array<double, 3> box_;
  double inv_mu_;
  PseRotationTable table_;
  mutable std::vector<double> work_;  // positions, forces and torques gathered into slot order
};

}  // namespace rpyfmm::rpy::pse::detail
