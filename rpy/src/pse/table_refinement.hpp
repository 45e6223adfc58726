// rpyfmm — PSE: the spacing of a real-space table for linear interpolation within a tolerance,
// shared by the translational (real_space.cpp) and rotational (rotation_real_space.cpp) tables.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::pse::detail {

/// A table of m components at the nodes r = j dr, j = 0 .. nodes - 1 (m values per node).
struct RefinedTable {
  double dr = 0.0;
  std::size_t nodes = 0;
  std::vector<double> values;
};

/// Tabulates m components of a function of r on [0, r_cut] for linear interpolation within eps:
/// from the spacing dr0 (a curvature bound's estimate) the spacing is halved until, at every
/// midpoint, each component differs from the mean of its two nodes by at most eps.
/// sample(dr, n) returns the components at r = j dr / 2, j = 0 .. 2n (m per point: even j the
/// nodes, odd j the midpoints); the table keeps the n + 1 nodes. Refuses (out_of_memory, naming
/// `where`) a table of max_entries nodes or more.
template <class Sample>
RefinedTable refine_linear_table(double dr0, double r_cut, double eps, std::size_t m, std::size_t max_entries,
                                 const char* where, const char* max_entries_text, Sample&& sample) {
  for (double dr = dr0;; dr *= 0.5) {
    const auto n = static_cast<std::size_t>(std::ceil(r_cut / dr)) + 1;  // cells 0..n-1 cover [0, n dr)
    if (n >= max_entries) {
      fail(ErrorCode::out_of_memory, where,
           "table for tolerance " + format_number(eps) + " would need more than " + max_entries_text + " entries");
    }
    const std::vector<double> v = sample(dr, n);
    double worst = 0.0;
    for (std::size_t j = 1; j < 2 * n; j += 2)
      for (std::size_t c = 0; c < m; ++c)
        worst = std::max(worst, std::abs(0.5 * (v[m * (j - 1) + c] + v[m * (j + 1) + c]) - v[m * j + c]));
    if (worst <= eps) {
      RefinedTable t{dr, n + 1, std::vector<double>(m * (n + 1))};
      for (std::size_t j = 0; j <= n; ++j) std::copy_n(&v[2 * m * j], m, &t.values[m * j]);
      return t;
    }
  }
}

}  // namespace rpyfmm::rpy::pse::detail
