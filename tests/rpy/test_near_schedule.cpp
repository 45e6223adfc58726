// FmmRpy's near-field schedule (rpy/src/near_schedule.hpp) on synthetic leaf-pair lists: every
// directed pair is evaluated exactly once, symmetric pairs once for both directions, and no two
// tasks of one colour write the same leaf (the condition for race-free, thread-count-invariant
// parallel evaluation).
#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include "near_schedule.hpp"

using rpyfmm::rpy::detail::make_near_schedule;
using rpyfmm::rpy::detail::NearSchedule;
using Pair = std::pair<std::uint32_t, std::uint32_t>;

namespace {

// Leaves on a k x k x k grid; U-list-like pairs between leaves at Chebyshev distance <= 1 (the
// leaf itself included), plus one-directional pairs (a, a + 2 along x) for every third leaf,
// like the exported W/X pairs of an adaptive tree.
std::vector<Pair> grid_pairs(int k) {
  auto id = [k](int i, int j, int l) { return static_cast<std::uint32_t>((i * k + j) * k + l); };
  std::vector<Pair> pairs;
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j)
      for (int l = 0; l < k; ++l) {
        for (int di = -1; di <= 1; ++di)
          for (int dj = -1; dj <= 1; ++dj)
            for (int dl = -1; dl <= 1; ++dl) {
              const int a = i + di, b = j + dj, c = l + dl;
              if (a >= 0 && a < k && b >= 0 && b < k && c >= 0 && c < k) pairs.emplace_back(id(i, j, l), id(a, b, c));
            }
        if (id(i, j, l) % 3 == 0 && i + 2 < k) pairs.emplace_back(id(i, j, l), id(i + 2, j, l));
      }
  return pairs;
}

// How many times the schedule evaluates each directed pair (target leaf, source leaf).
std::map<Pair, int> evaluations(const NearSchedule& s) {
  std::map<Pair, int> count;
  for (std::size_t t = 0; t < s.num_tasks(); ++t) {
    for (std::size_t q = s.one_begin[t]; q < s.one_begin[t + 1]; ++q) ++count[{s.leaf[t], s.one_sided[q]}];
    for (std::size_t q = s.sym_begin[t]; q < s.sym_begin[t + 1]; ++q) {
      ++count[{s.leaf[t], s.symmetric[q]}];
      ++count[{s.symmetric[q], s.leaf[t]}];
    }
  }
  return count;
}

void expect_each_pair_once(const NearSchedule& s, const std::vector<Pair>& pairs) {
  const auto count = evaluations(s);
  EXPECT_EQ(count.size(), pairs.size());
  for (const Pair& p : pairs) {
    const auto it = count.find(p);
    ASSERT_NE(it, count.end()) << "pair " << p.first << " <- " << p.second << " never evaluated";
    EXPECT_EQ(it->second, 1) << "pair " << p.first << " <- " << p.second;
  }
}

}  // namespace

TEST(NearSchedule, SymmetricScheduleEvaluatesEachPairOnceAndColoursAreRaceFree) {
  const int k = 7;
  const auto pairs = grid_pairs(k);
  const NearSchedule s = make_near_schedule(pairs, static_cast<std::size_t>(k * k * k), true);
  expect_each_pair_once(s, pairs);
  EXPECT_FALSE(s.symmetric.empty());
  // One-directional extras stay one-sided; so does every self pair.
  for (std::size_t t = 0; t < s.num_tasks(); ++t)
    for (std::size_t q = s.sym_begin[t]; q < s.sym_begin[t + 1]; ++q) EXPECT_NE(s.symmetric[q], s.leaf[t]);
  // Race freedom: the leaves written by the tasks of one colour are disjoint.
  for (std::size_t c = 0; c < s.num_colours(); ++c) {
    std::set<std::uint32_t> written;
    for (std::size_t t = s.colour_begin[c]; t < s.colour_begin[c + 1]; ++t) {
      EXPECT_TRUE(written.insert(s.leaf[t]).second) << "colour " << c << " writes leaf " << s.leaf[t] << " twice";
      for (std::size_t q = s.sym_begin[t]; q < s.sym_begin[t + 1]; ++q)
        EXPECT_TRUE(written.insert(s.symmetric[q]).second)
            << "colour " << c << " writes leaf " << s.symmetric[q] << " twice";
    }
  }
  // Every task is scheduled once; a uniform grid needs a bounded number of colours (a leaf's
  // write set spans its 3^3 block, so at most 5^3 tasks can conflict with it).
  std::set<std::uint32_t> task_leaves(s.leaf.begin(), s.leaf.end());
  EXPECT_EQ(task_leaves.size(), s.num_tasks());
  EXPECT_EQ(s.num_tasks(), static_cast<std::size_t>(k * k * k));
  EXPECT_LE(s.num_colours(), 125u);
  EXPECT_GE(s.num_colours(), 8u);  // neighbouring tasks must differ
}

TEST(NearSchedule, WithoutSymmetryEveryPairIsOneSidedInOneColour) {
  const auto pairs = grid_pairs(4);
  const NearSchedule s = make_near_schedule(pairs, 64, false);
  expect_each_pair_once(s, pairs);
  EXPECT_TRUE(s.symmetric.empty());
  EXPECT_EQ(s.num_colours(), 1u);
  EXPECT_EQ(s.num_tasks(), 64u);
}

TEST(NearSchedule, EmptyAndSingleLeaf) {
  const NearSchedule none = make_near_schedule({}, 0, true);
  EXPECT_EQ(none.num_tasks(), 0u);
  EXPECT_EQ(none.num_colours(), 0u);
  const NearSchedule one = make_near_schedule({{0, 0}}, 1, true);
  ASSERT_EQ(one.num_tasks(), 1u);
  EXPECT_EQ(one.num_colours(), 1u);
  EXPECT_EQ(one.one_sided, std::vector<std::uint32_t>{0});
}
