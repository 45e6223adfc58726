// The host-side plan of the CUDA spreading and interpolation (rpy/src/pse/cuda_window_plan.hpp),
// tested without a device: the bin grid's shape and shared memory, and the automatic bin edge
// against the choices measured best on an H200 (132 multiprocessors, 227 KiB of opt-in shared
// memory per block; measured 2026-12-04, CUDA 13.0: 10 for 8-byte subgrids at Table I's sizes,
// one block per particle at 8000 particles on 64^3). The spreading sums in 64-bit fixed point
// (cuda_window.cuh), so the subgrids take 8 bytes per point for float grids too.
#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "../../rpy/src/pse/cuda_window_plan.hpp"

using namespace rpyfmm::rpy::pse::cuda_window;

namespace {

constexpr int kH200Multiprocessors = 132;
constexpr std::size_t kH200Shared = 232448;

WindowParams cube(int n, int P) {
  WindowParams w{};
  for (int d = 0; d < 3; ++d) {
    w.n[d] = n;
    w.P[d] = P;
  }
  w.ng = static_cast<std::size_t>(n) * n * n;
  return w;
}

int automatic(int n, std::size_t np) {
  return choose_bin_edge(cube(n, 7), np, 0, kH200Multiprocessors, kH200Shared);
}

}  // namespace

TEST(PseBinPlan, BinGridShapeAndSharedMemory) {
  WindowParams w{};
  w.n[0] = 27, w.n[1] = 33, w.n[2] = 12;
  w.P[0] = w.P[1] = w.P[2] = 10;
  const BinGrid g = make_bin_grid(w, 16);
  EXPECT_EQ(g.B[0], 16);
  EXPECT_EQ(g.nb[0], 2);  // 16 + 11: the last bin shorter
  EXPECT_EQ(g.nb[1], 3);  // 16 + 16 + 1
  EXPECT_EQ(g.B[2], 12);  // clipped to the grid: one bin, its subgrid wraps onto itself
  EXPECT_EQ(g.nb[2], 1);
  EXPECT_EQ(g.m[2], 12 + 9);
  EXPECT_EQ(g.sub, 25 * 25 * 21);
  EXPECT_EQ(g.bins(), 6u);
  // 16 warps' weights (3 max_support doubles each) and three subgrids of 8-byte sums.
  EXPECT_EQ(g.shared_bytes(), 16u * 3 * 10 * 8 + 3u * 25 * 25 * 21 * 8);
}

TEST(PseBinPlan, AutomaticEdgeMatchesTheMeasuredBest) {
  // Edge 12's subgrids (18^3 points, 137 KiB) exceed the two blocks per multiprocessor; 10's fit.
  EXPECT_EQ(automatic(320, 1000000), 10);
  EXPECT_EQ(automatic(200, 250000), 10);
  EXPECT_EQ(automatic(100, 32000), 10);
  EXPECT_EQ(automatic(64, 8000), 0);  // few particles per bin: per particle
  // Few multiprocessors' worth of bins is not enough parallel work: a smaller edge (here none:
  // the smaller edges' subgrids hold more than half the window points).
  EXPECT_LT(choose_bin_edge(cube(100, 7), 32000, 0, 1000, kH200Shared), 10);
  // A device with 48 KiB per block: subgrids fit up to edge 6, whose subgrids hold 79% of the
  // window points (> half): one block per particle.
  EXPECT_LE(make_bin_grid(cube(320, 7), 6).shared_bytes(), 48u * 1024);
  EXPECT_GT(make_bin_grid(cube(320, 7), 8).shared_bytes(), 48u * 1024);
  EXPECT_EQ(choose_bin_edge(cube(320, 7), 1000000, 0, kH200Multiprocessors, 48 * 1024), 0);
}

TEST(PseBinPlan, RequestedEdges) {
  const WindowParams w = cube(320, 7);
  EXPECT_EQ(choose_bin_edge(w, 1000000, -1, kH200Multiprocessors, kH200Shared), 0);
  EXPECT_EQ(choose_bin_edge(w, 1000000, 8, kH200Multiprocessors, kH200Shared), 8);
  EXPECT_EQ(choose_bin_edge(w, 10, 14, kH200Multiprocessors, kH200Shared), 14);  // as asked
  // (16 + 6)^3 and (64 + 6)^3 subgrids do not fit: 0, which PseRpyCuda turns into an error.
  EXPECT_EQ(choose_bin_edge(w, 1000000, 16, kH200Multiprocessors, kH200Shared), 0);
  EXPECT_EQ(choose_bin_edge(w, 1000000, 64, kH200Multiprocessors, kH200Shared), 0);
}

// The fixed-point arithmetic of the CUDA spreading (cuda_window_plan.hpp): the shift keeps every
// sum below 2^62 yet within a factor 8 of it (each of the three ilogb bounds overestimates its
// log2 by less than 1), for factors from subnormal to near-overflow.
TEST(PseFixedPoint, ShiftBoundsTheSums) {
  for (const double c3 : {1e-300, 2.5e-3, 1.0, 0.06349, 7e5}) {
    for (const double m : {4.9e-324, 1e-200, 0.37, 1.0, 3e7, 1e300}) {
      for (const double count : {1.0, 27.0, 1e6, 8e9}) {
        const int s = fixed_point_shift(c3, m, count);
        const long double log2_bound = std::log2l(c3) + std::log2l(m) + std::log2l(count) + s;
        EXPECT_LT(log2_bound, 62.0L) << c3 << " " << m << " " << count;
        EXPECT_GE(log2_bound, 59.0L) << c3 << " " << m << " " << count;
      }
    }
  }
  EXPECT_EQ(fixed_point_shift(1.0, std::numeric_limits<double>::infinity(), 10.0), INT_MIN);
  EXPECT_EQ(fixed_point_shift(1.0, std::numeric_limits<double>::quiet_NaN(), 10.0), INT_MIN);
  EXPECT_EQ(fixed_point_shift(1.0, 0.0, 10.0), 0);
  EXPECT_TRUE(std::isnan(from_fixed(to_fixed(1.0, 0), INT_MIN)));
}

// A window longer than the grid along an axis covers a point more than once: P = 10 on 8 points
// twice, on 16 points once.
TEST(PseFixedPoint, ContributionsPerPoint) {
  WindowParams w = cube(16, 10);
  EXPECT_EQ(contributions_per_point(w, 1000), 1000.0);
  w.n[2] = 8;
  EXPECT_EQ(contributions_per_point(w, 1000), 2000.0);
  w.n[0] = 4;
  EXPECT_EQ(contributions_per_point(w, 1000), 6000.0);  // ceil(10 / 4) = 3
}

// Sums of fixed-point contributions do not depend on the order (integer addition, two's
// complement), and differ from the exact sum by at most half a unit 2^-shift per contribution.
TEST(PseFixedPoint, SumsDoNotDependOnOrder) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0), sym(-1.0, 1.0);
  const double c3 = 0.0634;
  const std::size_t n = 5000;
  std::vector<double> v(n);
  double max_abs = 0.0;
  for (auto& x : v) {
    const double f = 3.0 * sym(rng);
    max_abs = std::max(max_abs, std::abs(f));
    x = c3 * unit(rng) * f;  // c3 w f, 0 <= w <= 1
  }
  const int shift = fixed_point_shift(c3, max_abs, static_cast<double>(n));
  unsigned long long forward = 0, shuffled = 0;
  long double exact = 0.0L;
  for (const double x : v) {
    forward += to_fixed(x, shift);
    exact += x;
  }
  std::vector<std::size_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  for (const std::size_t i : order) shuffled += to_fixed(v[i], shift);
  EXPECT_EQ(forward, shuffled);
  const double sum = from_fixed(forward, shift);
  EXPECT_LE(std::abs(static_cast<long double>(sum) - exact),
            0.5L * n * std::ldexp(1.0L, -shift) + 1e-16L * std::abs(exact));
  // A negative sum comes back negative (the unsigned word wraps as a signed one).
  EXPECT_LT(from_fixed(to_fixed(-0.75, 10) + to_fixed(-0.5, 10), 10), -1.24);
}
