// The host-side plan of the CUDA spreading and interpolation (rpy/src/pse/cuda_window_plan.hpp),
// tested without a device: the bin grid's shape and shared memory, and the automatic bin edge
// against the choices measured best on an H200 (132 multiprocessors, 227 KiB of opt-in shared
// memory per block; measured 2026-12-04, CUDA 13.0: 10 for 8-byte subgrids at Table I's sizes,
// one block per particle at 8000 particles on 64^3). The spreading sums in 64-bit fixed point
// (cuda_window.cuh), so the subgrids take 8 bytes per point for float grids too.
#include <gtest/gtest.h>

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
