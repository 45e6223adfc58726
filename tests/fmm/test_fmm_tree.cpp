// Octree and list invariants (CGR 1999 §2; docs/theory/fmm.md, "The tree and the four lists") on uniform, clustered and
// surface inputs: every point in exactly one leaf, nested ranges, U symmetric, b in W(c) <=> c in X(b), W/X separation,
// V sizes <= 189, and the partition invariant: for every target leaf, U, W, and the V/X lists of its
// ancestors (each with its subtree) cover every source exactly once.
#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "fmm_test_util.hpp"
#include "rpyfmm/fmm/detail/octree.hpp"

using rpyfmm::fmm::detail::Octree;
using rpyfmm::fmm::detail::OctreeParams;

namespace {
void check_tree(const std::vector<double>& src, const std::vector<double>& tgt, std::size_t cap) {
  Octree t;
  OctreeParams prm;
  prm.leaf_capacity = cap;
  t.build(src, tgt, prm);
  const auto& B = t.boxes();
  const std::size_t n = src.size() / 3;
  // every source in exactly one leaf; leaves respect capacity unless unsplittable
  std::vector<int> count(n, 0);
  for (int b : t.leaves())
    for (std::size_t j = B[b].src_begin; j < B[b].src_end; ++j) ++count[t.source_order()[j]];
  for (std::size_t j = 0; j < n; ++j) ASSERT_EQ(count[j], 1) << j;
  // points lie in their leaf box (up to rounding)
  for (int b : t.leaves()) {
    const auto c = t.center(b);
    const double h = 0.5 * t.side(B[b].level) * (1 + 1e-12);
    for (std::size_t j = B[b].src_begin; j < B[b].src_end; ++j)
      for (int k = 0; k < 3; ++k) ASSERT_LE(std::abs(t.sorted_sources()[3 * j + k] - c[k]), h);
  }
  // children ranges nested in the parent's
  for (int b = 1; b < int(B.size()); ++b) {
    const auto& P = B[B[b].parent];
    ASSERT_TRUE(B[b].src_begin >= P.src_begin && B[b].src_end <= P.src_end);
    ASSERT_TRUE(B[b].tgt_begin >= P.tgt_begin && B[b].tgt_end <= P.tgt_end);
    ASSERT_GT(B[b].nsrc() + B[b].ntgt(), 0u);  // empty boxes are skipped
  }
  // U symmetric, W/X transpose, W/X geometry
  for (int b : t.leaves()) {
    for (int u : t.ulist().of(b)) {
      ASSERT_TRUE(B[u].leaf);
      ASSERT_TRUE(u == b || t.adjacent(u, b));
      const auto ul = t.ulist().of(u);
      ASSERT_TRUE(std::binary_search(ul.begin(), ul.end(), b));
    }
    for (int w : t.wlist().of(b)) {
      const auto xl = t.xlist().of(w);
      ASSERT_TRUE(std::binary_search(xl.begin(), xl.end(), b));  // b in X(w)  <=>  w in W(b)
      ASSERT_FALSE(t.adjacent(w, b));
      ASSERT_TRUE(t.adjacent(B[w].parent, b));
      ASSERT_GT(B[w].level, B[b].level);
    }
  }
  for (int c = 0; c < int(B.size()); ++c)
    for (int x : t.xlist().of(c)) {
      const auto wl = t.wlist().of(x);
      ASSERT_TRUE(std::binary_search(wl.begin(), wl.end(), c));
    }
  // partition invariant, by brute force over sources
  auto mark_subtree = [&](int b, std::vector<int>& cov) {
    for (std::size_t j = B[b].src_begin; j < B[b].src_end; ++j) ++cov[j];
  };
  for (int b : t.leaves()) {
    std::vector<int> cov(n, 0);
    for (int u : t.ulist().of(b)) mark_subtree(u, cov);
    for (int w : t.wlist().of(b)) mark_subtree(w, cov);
    for (int a = b; a >= 0; a = B[a].parent) {
      for (int x : t.xlist().of(a)) mark_subtree(x, cov);
      if (B[a].parent < 0) continue;
      int vcount = 0;
      for (int c : t.colleagues().of(B[a].parent))
        for (int ch : B[c].child)
          if (ch >= 0 && !t.adjacent(ch, a)) {
            mark_subtree(ch, cov);
            ++vcount;
          }
      ASSERT_LE(vcount, 189);
    }
    for (std::size_t j = 0; j < n; ++j) ASSERT_EQ(cov[j], 1) << "leaf " << b << " source " << j;
  }
}
}  // namespace

TEST(FmmTree, InvariantsUniform) {
  check_tree(fmmtest::cube(1500, 1), {}, 8);
}
TEST(FmmTree, InvariantsClustered) {
  check_tree(fmmtest::plummer(1500, 2), {}, 8);
}
TEST(FmmTree, InvariantsSphereSurface) {
  check_tree(fmmtest::sphere(1500, 3), {}, 8);
}
TEST(FmmTree, InvariantsTwoClustersAndLine) {
  check_tree(fmmtest::two_clusters(800, 4), {}, 4);
  check_tree(fmmtest::line(800, 5), {}, 4);
}
TEST(FmmTree, InvariantsSeparateTargets) {
  check_tree(fmmtest::plummer(800, 6), fmmtest::cube(700, 7), 8);
}
TEST(FmmTree, DuplicatesStopSplitting) {
  std::vector<double> x;
  for (int k = 0; k < 50; ++k) x.insert(x.end(), {0.1, 0.2, 0.3});
  x.insert(x.end(), {0.9, 0.9, 0.9});
  Octree t;
  OctreeParams prm;
  prm.leaf_capacity = 4;
  t.build(x, {}, prm);
  EXPECT_LE(t.nlevels(), 3);  // root, its two occupied children and nothing deeper than needed
}
TEST(FmmTree, SinglePoint) {
  Octree t;
  t.build(std::vector<double>{1.0, 2.0, 3.0}, {}, OctreeParams{});
  EXPECT_EQ(t.boxes().size(), 1u);
  EXPECT_EQ(t.leaves().size(), 1u);
}
