// The pieces of DistributedLaplaceFmm's locally essential tree on one process (mpi/src, not
// collective): the tree of cells over particles sorted by Morton or Hilbert key (each cell one
// octree cell of its level on both curves), the cover of a region, the walk
// that chooses what is sent (every particle exactly once, the acceptance and order rules), and the
// Chebyshev anterpolation (interpolation at the nodes, moments, the far-field error against
// rho^-p; docs/mpi.md, "Error rule").
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "cell_tree.hpp"
#include "chebyshev.hpp"
#include "essential_tree.hpp"
#include "rpyfmm/mpi/partition.hpp"

namespace {

using rpyfmm::mpi::detail::Box;
using rpyfmm::mpi::detail::Cell;
using rpyfmm::mpi::detail::CellTree;
using rpyfmm::mpi::detail::Cube;

// n points in the unit cube, a third of them in a cube of side 0.01, sorted by key along `curve`.
struct Sorted {
  std::vector<double> x;
  std::vector<std::uint64_t> keys;
};

constexpr rpyfmm::mpi::KeyCube kUnitCube{{0.0, 0.0, 0.0}, 0.5};

Sorted sorted_cloud(std::size_t n, std::uint64_t seed, rpyfmm::mpi::SfcCurve curve = rpyfmm::mpi::SfcCurve::morton) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> x(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t d = 0; d < 3; ++d) x[3 * i + d] = i < n / 3 ? 0.6 + 0.01 * u(rng) : u(rng);
  }
  const std::vector<std::uint64_t> keys = rpyfmm::mpi::sfc_keys(kUnitCube, x, curve);
  std::vector<std::size_t> order(n);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return keys[a] < keys[b]; });
  Sorted s;
  for (std::size_t i : order) {
    s.keys.push_back(keys[i]);
    for (std::size_t d = 0; d < 3; ++d) s.x.push_back(x[3 * i + d]);
  }
  return s;
}

bool inside(const Box& b, const double* p) {
  for (std::size_t d = 0; d < 3; ++d) {
    if (p[d] < b.lo[d] || p[d] > b.hi[d]) return false;
  }
  return true;
}

// The octree cell of level `level` holding point p (its grid cell on each axis, the key's cells).
std::array<std::uint32_t, 3> octree_cell(const double* p, int level) {
  std::array<std::uint32_t, 3> c{};
  for (std::size_t d = 0; d < 3; ++d) {
    c[d] = rpyfmm::mpi::morton_cell(p[d], kUnitCube.origin[d], kUnitCube.half_side) >>
           (rpyfmm::mpi::kMortonBitsPerAxis - level);
  }
  return c;
}

void expect_cells_partition_their_parents(rpyfmm::mpi::SfcCurve curve) {
  const Sorted s = sorted_cloud(3000, 1, curve);
  const CellTree tree = rpyfmm::mpi::detail::build_cell_tree(s.keys, s.x, 32);
  ASSERT_FALSE(tree.cells.empty());
  EXPECT_EQ(tree.cells[0].begin, 0u);
  EXPECT_EQ(tree.cells[0].end, 3000u);
  for (const Cell& c : tree.cells) {
    for (std::size_t i = c.begin; i < c.end; ++i) {
      EXPECT_TRUE(inside(c.box, &s.x[3 * i]));
      // One octree cell of the cell's level holds all its particles (the keys' prefix property).
      EXPECT_EQ(octree_cell(&s.x[3 * i], c.level), octree_cell(&s.x[3 * c.begin], c.level));
    }
    if (c.leaf()) {
      EXPECT_TRUE(c.size() <= 32 || c.level == rpyfmm::mpi::kMortonBitsPerAxis);
      continue;
    }
    std::size_t at = c.begin;  // children: contiguous ranges covering the parent, one level down
    for (std::uint32_t k = 0; k < c.child_count; ++k) {
      const Cell& child = tree.cells[c.first_child + k];
      EXPECT_EQ(child.begin, at);
      EXPECT_EQ(child.level, c.level + 1);
      EXPECT_GT(child.size(), 0u);
      at = child.end;
    }
    EXPECT_EQ(at, c.end);
  }
  // The cover: at most the boxes asked for, every particle inside one of them.
  const std::vector<Box> cover = rpyfmm::mpi::detail::region_cover(tree, 16);
  EXPECT_LE(cover.size(), 16u);
  for (std::size_t i = 0; i < 3000; ++i) {
    EXPECT_TRUE(std::any_of(cover.begin(), cover.end(), [&](const Box& b) { return inside(b, &s.x[3 * i]); }));
  }
}

TEST(EssentialTree, CellsPartitionTheirParentsAndBoundTheirParticles) {
  expect_cells_partition_their_parents(rpyfmm::mpi::SfcCurve::morton);
  expect_cells_partition_their_parents(rpyfmm::mpi::SfcCurve::hilbert);
}

TEST(EssentialTree, EveryParticleIsSentOnceAndCompressedCellsAreFarAndWorthIt) {
  const Sorted s = sorted_cloud(4000, 2);
  const CellTree tree = rpyfmm::mpi::detail::build_cell_tree(s.keys, s.x, 16);
  // Regions: a slab beside the cloud, a box inside it, and two boxes far away.
  const std::vector<std::vector<Box>> regions = {
      {Box{{1.0, 0.0, 0.0}, {1.2, 1.0, 1.0}}},
      {Box{{0.4, 0.4, 0.4}, {0.5, 0.5, 0.5}}},
      {Box{{5.0, 5.0, 5.0}, {6.0, 6.0, 6.0}}, Box{{-9.0, 0.0, 0.0}, {-8.0, 1.0, 1.0}}}};
  for (double tolerance : {1e-3, 1e-6, 1e-9}) {
    for (const std::vector<Box>& region : regions) {
      const rpyfmm::mpi::detail::Acceptance acceptance{tolerance, 2.0, 32, 0};
      const rpyfmm::mpi::detail::EssentialCells sent = rpyfmm::mpi::detail::essential_cells(tree, region, acceptance);
      // The root test that decides the regions' neighbours (essential_exchange.cpp): where it
      // compresses the root, the walk sends that one cell at that order and nothing else.
      const int root_order = rpyfmm::mpi::detail::compressed_order(rpyfmm::mpi::detail::cell_cube(tree.cells[0]),
                                                                   tree.cells[0].size(), region, acceptance);
      const bool root_only = sent.halo.empty() && sent.compressed.size() == 1 && sent.compressed[0].cell == 0;
      EXPECT_EQ(root_order > 0, root_only);
      if (root_only) {
        EXPECT_EQ(sent.compressed[0].order, root_order);
      }
      std::vector<int> times(4000, 0);
      for (std::uint32_t c : sent.halo) {
        EXPECT_TRUE(tree.cells[c].leaf());
        for (std::size_t i = tree.cells[c].begin; i < tree.cells[c].end; ++i) ++times[i];
      }
      for (const rpyfmm::mpi::detail::Compressed& c : sent.compressed) {
        const Cell& cell = tree.cells[c.cell];
        const Cube cube = rpyfmm::mpi::detail::cell_cube(cell);
        double nearest = 1e300;
        for (const Box& b : region) nearest = std::min(nearest, rpyfmm::mpi::detail::distance(cube, b));
        EXPECT_GE(nearest, 2.0 * cube.half);
        EXPECT_EQ(c.order, rpyfmm::mpi::detail::order_at(tolerance, nearest / cube.half, 32));
        EXPECT_GT(cell.size(), static_cast<std::size_t>(c.order * c.order * c.order));
        for (std::size_t i = cell.begin; i < cell.end; ++i) ++times[i];
      }
      EXPECT_TRUE(std::all_of(times.begin(), times.end(), [](int t) { return t == 1; }));
    }
  }
  // The far region gets the whole cloud as one cell; an empty region gets nothing.
  const rpyfmm::mpi::detail::Acceptance loose{1e-3, 2.0, 32, 0};
  const auto far = rpyfmm::mpi::detail::essential_cells(tree, std::vector<Box>{Box{{90, 90, 90}, {91, 91, 91}}}, loose);
  ASSERT_EQ(far.compressed.size(), 1u);
  EXPECT_EQ(far.compressed[0].cell, 0u);
  EXPECT_EQ(far.compressed[0].order,
            rpyfmm::mpi::detail::compressed_order(rpyfmm::mpi::detail::cell_cube(tree.cells[0]), tree.cells[0].size(),
                                                  std::vector<Box>{Box{{90, 90, 90}, {91, 91, 91}}}, loose));
  EXPECT_TRUE(far.halo.empty());
  EXPECT_TRUE(rpyfmm::mpi::detail::essential_cells(tree, {}, loose).halo.empty());
  // No cell closer than min_distance to the region is compressed: the slab beside the cloud at
  // min_distance 0.3 gets only cells at least 0.3 away, and every particle still once.
  const rpyfmm::mpi::detail::Acceptance kept{1e-3, 2.0, 32, 0, 0.3};
  const auto beside = rpyfmm::mpi::detail::essential_cells(tree, regions[0], kept);
  EXPECT_FALSE(beside.compressed.empty());
  std::size_t particles = 0;
  for (std::uint32_t c : beside.halo) particles += tree.cells[c].size();
  for (const rpyfmm::mpi::detail::Compressed& c : beside.compressed) {
    const Cube cube = rpyfmm::mpi::detail::cell_cube(tree.cells[c.cell]);
    EXPECT_GE(rpyfmm::mpi::detail::distance(cube, regions[0][0]), 0.3);
    particles += tree.cells[c.cell].size();
  }
  EXPECT_EQ(particles, 4000u);
}

TEST(EssentialTree, OrderRule) {
  // The smallest p >= 2 with rho^-p <= eps / 10, rho = eta + sqrt(1 + eta^2) (docs/mpi.md).
  EXPECT_EQ(rpyfmm::mpi::detail::order_at(1e-3, 2.0, 32), 7);
  EXPECT_EQ(rpyfmm::mpi::detail::order_at(1e-6, 2.0, 32), 12);
  EXPECT_EQ(rpyfmm::mpi::detail::order_at(1e-9, 2.0, 32), 16);
  EXPECT_EQ(rpyfmm::mpi::detail::order_at(1e-6, 20.0, 32), 5);
  EXPECT_EQ(rpyfmm::mpi::detail::order_at(1e-15, 1.0, 32), 32);  // capped
  for (double eps : {1e-3, 1e-6, 1e-9}) {
    for (double eta : {1.0, 2.0, 3.5, 10.0, 100.0}) {
      const int p = rpyfmm::mpi::detail::order_at(eps, eta, 32);
      const double rho = eta + std::sqrt(1.0 + eta * eta);
      EXPECT_LE(std::pow(rho, -p), eps / 10);
      if (p > 2) {
        EXPECT_GT(std::pow(rho, -(p - 1)), eps / 10);
      }
    }
  }
}

TEST(Chebyshev, AnterpolationInterpolatesAtNodesAndKeepsMoments) {
  const Cube cube{{0.3, -0.2, 1.1}, 0.25};
  for (int p : {1, 2, 5, 9}) {
    const std::size_t nodes = static_cast<std::size_t>(p * p * p);
    std::vector<double> x(3 * nodes), q(nodes);
    rpyfmm::mpi::detail::chebyshev_nodes(cube, p, x);
    // A unit charge at node k gives Q = e_k: S_p(t_m, t_k) = delta_mk.
    for (std::size_t k = 0; k < nodes; k += std::max<std::size_t>(1, nodes / 7)) {
      std::vector<double> out(nodes);
      const double one = 1.0;
      rpyfmm::mpi::detail::anterpolate(cube, p, std::span<const double>(x).subspan(3 * k, 3), &one, 1, 1, out);
      for (std::size_t m = 0; m < nodes; ++m) EXPECT_NEAR(out[m], m == k ? 1.0 : 0.0, 1e-12) << p << " " << k;
    }
    // Random charges in the cube: the total charge, and for p >= 2 the dipole, are kept.
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<double> y(3 * 50), c(2 * 50);
    for (std::size_t i = 0; i < 50; ++i) {
      for (std::size_t d = 0; d < 3; ++d) y[3 * i + d] = cube.center[d] + cube.half * u(rng);
    }
    for (double& v : c) v = u(rng);
    std::vector<double> out(2 * nodes);
    rpyfmm::mpi::detail::anterpolate(cube, p, y, c.data(), 50, 2, out);
    for (std::size_t d = 0; d < 2; ++d) {
      double total = 0.0, kept = 0.0;
      for (std::size_t i = 0; i < 50; ++i) total += c[d * 50 + i];
      for (std::size_t m = 0; m < nodes; ++m) kept += out[d * nodes + m];
      EXPECT_NEAR(kept, total, 1e-12);
      if (p < 2) continue;
      for (std::size_t a = 0; a < 3; ++a) {
        double dipole = 0.0, kept_dipole = 0.0;
        for (std::size_t i = 0; i < 50; ++i) dipole += c[d * 50 + i] * y[3 * i + a];
        for (std::size_t m = 0; m < nodes; ++m) kept_dipole += out[d * nodes + m] * x[3 * m + a];
        EXPECT_NEAR(kept_dipole, dipole, 1e-12);
      }
    }
  }
}

TEST(Chebyshev, FarFieldErrorBelowRhoToTheMinusP) {
  // Positive charges in the cube, targets at distance eta h from it (on the axes and diagonals):
  // the potential of the equivalent charges within rho^-p of the particles' (relative).
  const Cube cube{{0.0, 0.0, 0.0}, 1.0};
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0), w(0.0, 1.0);
  std::vector<double> y(3 * 400), q(400);
  for (double& v : y) v = u(rng);
  for (double& v : q) v = w(rng);
  for (double eta : {2.0, 4.0}) {
    const double rho = eta + std::sqrt(1.0 + eta * eta);
    for (int p = 2; p <= 12; p += 2) {
      const std::size_t nodes = static_cast<std::size_t>(p * p * p);
      std::vector<double> x(3 * nodes), Q(nodes);
      rpyfmm::mpi::detail::chebyshev_nodes(cube, p, x);
      rpyfmm::mpi::detail::anterpolate(cube, p, y, q.data(), 400, 1, Q);
      double worst = 0.0;
      const double dirs[][3] = {{1, 0, 0}, {0, -1, 0}, {0, 0, 1}, {1, 1, 1}, {-1, 1, 0}};
      for (const auto& dir : dirs) {
        // The point of the ray at distance eta from the cube [-1, 1]^3.
        const double norm = std::sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
        double t = 1.0;
        for (int it = 0; it < 200; ++it) {
          double g2 = 0.0;
          for (int d = 0; d < 3; ++d) g2 += std::pow(std::max(0.0, std::abs(t * dir[d] / norm) - 1.0), 2);
          t += eta - std::sqrt(g2);
        }
        const double target[3] = {t * dir[0] / norm, t * dir[1] / norm, t * dir[2] / norm};
        double exact = 0.0, approx = 0.0;
        for (std::size_t i = 0; i < 400; ++i) {
          exact += q[i] / std::hypot(target[0] - y[3 * i], target[1] - y[3 * i + 1], target[2] - y[3 * i + 2]);
        }
        for (std::size_t m = 0; m < nodes; ++m) {
          approx += Q[m] / std::hypot(target[0] - x[3 * m], target[1] - x[3 * m + 1], target[2] - x[3 * m + 2]);
        }
        worst = std::max(worst, std::abs(approx - exact) / exact);
      }
      EXPECT_LE(worst, std::pow(rho, -p)) << "eta " << eta << " p " << p;
    }
  }
}

}  // namespace
