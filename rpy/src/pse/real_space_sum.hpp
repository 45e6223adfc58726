// rpyfmm — PSE real-space product U = M_r F on the CPU: neighbour lists from a
// cell list (cells of edge >= r_cut, minimum image), rows computed in parallel
// (each thread writes only its own rows: no races, deterministic). Private.
//
// Particles are renumbered internally in cell order ("slots"): positions are kept by slot
// (structure of arrays), the neighbour lists hold slots, and apply() gathers the forces into
// slot order once, so that a row reads its neighbours' positions and forces from a few nearby
// cache lines instead of from all over the input arrays (design note 16).
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

  /// Cell order and neighbour lists (CSR over slots, ascending) for positions wrapped into the box.
  void set_positions(std::span<const double> x);
  /// U (+)= M_r F for nrhs right-hand sides (3N each, stored one after another).
  void apply(const double* forces, double* out, std::size_t nrhs, bool accumulate) const;

  [[nodiscard]] const PseRealSpaceTable& table() const { return table_; }
  /// The neighbour lists in input numbering (CSR, j ascending), as the CUDA kernel reads them.
  void input_order_lists(std::vector<std::size_t>& begin, std::vector<int>& list) const;
  [[nodiscard]] double self() const { return self_; }
  [[nodiscard]] double mobility_unit() const { return m0_; }

 private:
  PseParameters p_;
  std::array<double, 3> box_;
  double m0_;    // 1 / (6 pi mu a)
  double self_;  // F(0)
  bool use_table_;
  PseRealSpaceTable table_;
  std::vector<std::size_t> order_;          // slot -> input index (particles sorted by cell)
  std::array<std::vector<double>, 3> pos_;  // positions by slot, one array per axis
  std::vector<std::size_t> begin_;          // per slot: range in list_
  std::vector<int> list_;                   // neighbour slots within r_cut (r > 0 or coincident)
  mutable std::vector<double> work_;        // forces gathered into slot order (3 arrays per rhs)
  mutable std::vector<double> packed_;      // AVX-512 kernel: x, y, z, fx, fy, fz, 0, 0 per slot and rhs
};

}  // namespace rpyfmm::rpy::pse::detail
