// rpyfmm — PSE real-space product U = M_r F on the CPU: neighbour lists from a
// cell list (cells of edge >= r_cut, minimum image), rows computed in parallel
// (each thread writes only its own rows: no races, deterministic). Private.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <vector>

#include "rpyfmm/rpy/pse/pse_parameters.hpp"
#include "rpyfmm/rpy/pse/real_space.hpp"

namespace rpyfmm::rpy::pse::detail {

class RealSpaceSum {
 public:
  RealSpaceSum(const PseParameters& p, const std::array<double, 3>& box, double viscosity, bool use_table);

  /// Neighbour lists (CSR, j ascending) for positions wrapped into the box.
  void set_positions(std::span<const double> x);
  /// U (+)= M_r F for nrhs right-hand sides (3N each, stored one after another).
  void apply(const double* forces, double* out, std::size_t nrhs, bool accumulate) const;

  [[nodiscard]] const PseRealSpaceTable& table() const { return table_; }
  [[nodiscard]] const std::vector<std::size_t>& neighbour_begin() const { return begin_; }
  [[nodiscard]] const std::vector<int>& neighbours() const { return list_; }
  [[nodiscard]] double self() const { return self_; }
  [[nodiscard]] double mobility_unit() const { return m0_; }

 private:
  PseParameters p_;
  std::array<double, 3> box_;
  double m0_;    // 1 / (6 pi mu a)
  double self_;  // F(0)
  bool use_table_;
  PseRealSpaceTable table_;
  std::vector<double> x_;
  std::vector<std::size_t> begin_;
  std::vector<int> list_;
  std::vector<std::size_t> order_;  // particles sorted by cell: the order apply() visits them in
};

}  // namespace rpyfmm::rpy::pse::detail
