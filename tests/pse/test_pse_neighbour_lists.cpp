// PSE real-space neighbour lists (private RealSpaceSum): where the AVX-512 half-list rows run,
// only the pairs t > s are listed and the full rows (the portable rows, the closed forms) are
// derived from them; the CUDA backend asks for full lists instead. Both ways must give every pair within
// r_cut exactly once per row, against an O(N^2) minimum-image search written here.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "../../rpy/src/pse/real_space_sum.hpp"
#include "ewald_reference.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

using namespace rpyfmm::rpy::pse;

TEST(PseNeighbourLists, InputOrderListsMatchBruteForce) {
  // Half lists (AVX-512 filter) then derived full rows; full lists asked for by the constructor
  // (full_lists, as the CUDA backend does) where the AVX-512 kernels run; full lists by the AVX2
  // filter; full lists by the portable filter (each where the machine has the level).
  struct Filter {
    rpyfmm::SimdLevel level;
    bool full;
  };
  for (const auto& [level, full] : {Filter{rpyfmm::SimdLevel::avx512, false}, Filter{rpyfmm::SimdLevel::avx512, true},
                                    Filter{rpyfmm::SimdLevel::avx2, false}, Filter{rpyfmm::SimdLevel::scalar, false}}) {
    if (level > rpyfmm::detected_simd_level()) continue;
    const bool avx512 = level == rpyfmm::SimdLevel::avx512, avx2 = level == rpyfmm::SimdLevel::avx2;
    for (const std::array<double, 3>& L :
         {std::array<double, 3>{21.0, 17.5, 26.0}, std::array<double, 3>{9.0, 30.0, 13.0},
          std::array<double, 3>{7.5, 7.5, 7.5}}) {
      const rpyfmm::ScopedSimdLevel scope(level);
      auto x = pse_test::random_points(700, L, 19);
      for (int d = 0; d < 3; ++d) x[3 * 3 + d] = x[3 * 400 + d];  // coincident pair
      PseOptions o;
      o.xi = 1.0;
      o.r_cut = 2.45;  // cell grids 8 x 7 x 10, 3 x 12 x 5 and 3 x 3 x 3
      const PseParameters p = choose_parameters(o, 1.0, L, 700);
      detail::RealSpaceSum sum(p, L, 1.0, true, detail::PairCache::off, 0, full);
      sum.set_positions(x);
      std::vector<std::size_t> begin;
      std::vector<int> list;
      sum.input_order_lists(begin, list);
      ASSERT_EQ(begin.size(), 701u);
      std::size_t pairs = 0;
      for (std::size_t i = 0; i < 700; ++i) {
        std::vector<int> expected;
        for (std::size_t j = 0; j < 700; ++j) {
          if (j == i) continue;
          double r2 = 0.0;
          for (int d = 0; d < 3; ++d) {
            double dd = x[3 * i + d] - x[3 * j + d];
            dd -= L[d] * std::round(dd / L[d]);
            r2 += dd * dd;
          }
          if (r2 < o.r_cut * o.r_cut) expected.push_back(static_cast<int>(j));
        }
        const std::vector<int> got(list.begin() + static_cast<std::ptrdiff_t>(begin[i]),
                                   list.begin() + static_cast<std::ptrdiff_t>(begin[i + 1]));
        EXPECT_EQ(got, expected) << "particle " << i
                                 << (avx512 && full ? ", full lists asked for"
                                     : avx512       ? ", half lists"
                                     : avx2         ? ", AVX2 filter"
                                                    : ", portable");
        pairs += expected.size();
      }
      EXPECT_GT(pairs, 700u);  // the boxes are dense enough to have neighbours
    }
  }
}
