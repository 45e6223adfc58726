// rpyfmm::mpi::SfcPartition: Morton keys against a serial reference (a bit-by-bit interleave on the
// whole set), Hilbert keys by their defining properties (a bijection of the grid whose prefixes are
// the octree's cells and whose consecutive cells are face neighbours), the cuts on either curve
// against the serial rule on the whole sorted set (contiguous ranges covering every particle once,
// the weight bound), independence of the input's distribution over the ranks, the exchange to the
// owners and back bit for bit, edge cases and collective failure.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/partition.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::Column;
using rpyfmm::mpi::SfcCurve;
using rpyfmm::mpi::SfcKey;
using rpyfmm::mpi::SfcPartition;
using namespace rpyfmm_mpi_test;

namespace {

// The Morton key by the definition, one bit at a time: bit b of the cell index on axis d becomes
// bit 3b + (2 - d) of the key.
std::uint64_t reference_key(const std::uint32_t cell[3]) {
  std::uint64_t key = 0;
  for (int b = 0; b < 21; ++b) {
    for (int d = 0; d < 3; ++d) key |= static_cast<std::uint64_t>((cell[d] >> b) & 1u) << (3 * b + 2 - d);
  }
  return key;
}

// The keys of the whole set (3N positions) along `curve`, with the cube taken serially over all of
// `cube_of` (x itself by default) and the cells clamped to the cube (Hilbert keys of the cells by
// hilbert_key, tested on its own below).
std::vector<std::uint64_t> reference_keys(const std::vector<double>& x, SfcCurve curve,
                                          const std::vector<double>* cube_of = nullptr) {
  const std::size_t n = x.size() / 3;
  const std::vector<double>& c_set = cube_of != nullptr ? *cube_of : x;
  const std::size_t n_cube = c_set.size() / 3;
  double lo[3], hi[3];
  for (int d = 0; d < 3; ++d) {
    lo[d] = hi[d] = n_cube > 0 ? c_set[static_cast<std::size_t>(d)] : 0.0;
    for (std::size_t i = 0; i < n_cube; ++i) {
      lo[d] = std::min(lo[d], c_set[3 * i + d]), hi[d] = std::max(hi[d], c_set[3 * i + d]);
    }
  }
  double half = 0.0;
  for (int d = 0; d < 3; ++d) half = std::max(half, 0.5 * hi[d] - 0.5 * lo[d]);
  std::vector<std::uint64_t> keys(n);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint32_t cell[3];
    for (int d = 0; d < 3; ++d) {
      const double c = half > 0.0 ? std::floor((0.5 * x[3 * i + d] - 0.5 * lo[d]) / half * 2097152.0) : 0.0;
      cell[d] = static_cast<std::uint32_t>(std::clamp(c, 0.0, 2097151.0));
    }
    keys[i] = curve == SfcCurve::morton ? reference_key(cell) : rpyfmm::mpi::hilbert_key(cell[0], cell[1], cell[2]);
  }
  return keys;
}

// Every rank's vector, concatenated in rank order, on every rank.
template <class T>
std::vector<T> all_gather(const std::vector<T>& local) {
  const int ranks = world_size();
  int mine = static_cast<int>(local.size() * sizeof(T));
  std::vector<int> counts(static_cast<std::size_t>(ranks)), displs(static_cast<std::size_t>(ranks));
  MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  int total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) displs[r] = total, total += counts[r];
  std::vector<T> all(static_cast<std::size_t>(total) / sizeof(T));
  MPI_Allgatherv(local.data(), mine, MPI_BYTE, all.data(), counts.data(), displs.data(), MPI_BYTE, MPI_COMM_WORLD);
  return all;
}

// The q_i of the sorted set in `unit`: round(w_i / unit), 1 each without weights or for all 0.
std::vector<std::uint64_t> reference_q(const std::vector<SfcKey>& sorted, const std::vector<double>& weights,
                                       double unit) {
  std::vector<std::uint64_t> q(sorted.size());
  bool all_zero = true;
  for (double w : weights) all_zero = all_zero && w == 0.0;
  for (std::size_t s = 0; s < sorted.size(); ++s) {
    const double w = weights.empty() ? 1.0 : weights[sorted[s].index];
    q[s] = all_zero && !weights.empty() ? 1 : static_cast<std::uint64_t>(std::llround(w / unit));
  }
  return q;
}

// ceil(r Q / P) in integers: r (Q div P) + ceil(r (Q mod P) / P).
std::uint64_t reference_target(std::uint64_t total, std::size_t r, std::size_t parts) {
  return r * (total / parts) + (r * (total % parts) + parts - 1) / parts;
}

// The serial cut rule on the whole set: sorted by (key, index), q_i = w_i / unit (exact: the unit is
// a power of two and w_i a double), rank r starting at the first particle with a weight of at least
// ceil(r Q / P) before it. Returns the number of particles of each rank.
std::vector<std::uint64_t> reference_counts(const std::vector<SfcKey>& sorted, const std::vector<double>& weights,
                                            double unit, std::size_t parts) {
  const std::vector<std::uint64_t> q = reference_q(sorted, weights, unit);
  const std::uint64_t total = std::accumulate(q.begin(), q.end(), std::uint64_t{0});
  std::vector<std::uint64_t> start(parts + 1, sorted.size());
  start[0] = 0;
  for (std::size_t r = 1; r < parts; ++r) {
    const std::uint64_t target = reference_target(total, r, parts);
    std::uint64_t before = 0;
    std::size_t s = 0;
    while (s < sorted.size() && before < target) before += q[s++];
    start[r] = s;
  }
  std::vector<std::uint64_t> counts(parts);
  for (std::size_t r = 0; r < parts; ++r) counts[r] = start[r + 1] - start[r];
  return counts;
}

// Partitions the global set (3N positions, N weights or none) given to the ranks as `split` along
// `curve`, checks it against the serial references and the exchange both ways, and returns this
// rank's owned list.
std::vector<SfcKey> check_partition(const std::vector<double>& x, const std::vector<double>& weights, Split split,
                                    SfcCurve curve) {
  const std::size_t n = x.size() / 3;
  const Partition part = partition_of(n, split);
  const std::vector<double> local_x = share(x, 3, part.offset, part.n);
  const std::vector<double> local_w = weights.empty() ? std::vector<double>{} : share(weights, 1, part.offset, part.n);
  const SfcPartition p(MPI_COMM_WORLD, local_x, local_w, curve);
  EXPECT_EQ(p.curve(), curve);
  EXPECT_EQ(p.global_size(), n);
  EXPECT_EQ(p.input_size(), part.n);

  // Keys: the serial reference's, each global index once, and the owned lists in rank order are the
  // whole set sorted by (key, index): contiguous ranges that cover every particle once.
  const std::vector<std::uint64_t> keys = reference_keys(x, curve);
  std::vector<SfcKey> sorted(n);
  for (std::size_t i = 0; i < n; ++i) sorted[i] = SfcKey{keys[i], i};
  std::sort(sorted.begin(), sorted.end());
  const std::vector<SfcKey> owned(p.owned().begin(), p.owned().end());
  const std::vector<SfcKey> all = all_gather(owned);
  EXPECT_TRUE(all == sorted) << "the ranks' ranges are not the sorted global set";
  EXPECT_EQ(p.owned_counts()[static_cast<std::size_t>(world_rank())], owned.size());

  // Cuts: the serial rule's counts, and the bound max part <= ceil(Q / P) + max q_i.
  const auto parts = static_cast<std::size_t>(world_size());
  const std::vector<std::uint64_t> expected = reference_counts(sorted, weights, p.weight_unit(), parts);
  EXPECT_TRUE(std::equal(expected.begin(), expected.end(), p.owned_counts().begin(), p.owned_counts().end()));
  const auto units = p.owned_weight_units();
  const std::uint64_t total = std::accumulate(units.begin(), units.end(), std::uint64_t{0});
  const std::uint64_t largest = *std::max_element(units.begin(), units.end());
  EXPECT_LE(largest, (total + parts - 1) / parts + p.max_weight_units());
  if (total > 0) {
    EXPECT_DOUBLE_EQ(p.imbalance(), static_cast<double>(largest) * static_cast<double>(parts) / total);
  }
  for (std::size_t r = 1; r < p.splitters().size(); ++r) EXPECT_LE(p.splitters()[r - 1], p.splitters()[r]);

  // Exchange: positions, radii-like and two more columns (with -0, a subnormal and a NaN payload)
  // arrive at the owners in owned order, bit for bit; and go back unchanged.
  std::vector<double> local_a(part.n), local_v(2 * part.n);
  for (std::size_t i = 0; i < part.n; ++i) {
    const double g = static_cast<double>(part.offset + i);
    local_a[i] = g;
    local_v[2 * i] = i % 3 == 0 ? -0.0 : (i % 3 == 1 ? 4.9e-324 : std::numeric_limits<double>::quiet_NaN());
    local_v[2 * i + 1] = -g;
  }
  const Column columns[] = {{local_x, 3}, {local_a, 1}, {local_v, 2}};
  const std::vector<std::vector<double>> there = p.to_owners(columns);
  EXPECT_EQ(there.size(), 3u);
  std::size_t wrong = 0;
  for (std::size_t j = 0; j < owned.size(); ++j) {
    const std::size_t g = owned[j].index;
    wrong += bitwise_mismatches(share(there[0], 3, j, 1), share(x, 3, g, 1));
    wrong += there[1][j] != static_cast<double>(g);
    wrong += there[2][2 * j + 1] != -static_cast<double>(g);
  }
  EXPECT_EQ(wrong, 0u) << "columns at the owners";
  const Column back_columns[] = {{there[0], 3}, {there[1], 1}, {there[2], 2}};
  const std::vector<std::vector<double>> back = p.to_origin(back_columns);
  EXPECT_EQ(bitwise_mismatches(back[0], local_x), 0u);
  EXPECT_EQ(bitwise_mismatches(back[1], local_a), 0u);
  EXPECT_EQ(bitwise_mismatches(back[2], local_v), 0u);
  return owned;
}

// N particles: uniform, or clustered (a few dense clumps and far points), as 3N positions.
std::vector<double> uniform_positions(std::size_t n, double lo, double hi, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<double> x(3 * n);
  for (double& c : x) c = u(rng);
  return x;
}

// Weights spread over three decades, some 0, as measured per-leaf costs might be.
std::vector<double> spread_weights(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 3.0);
  std::vector<double> w(n);
  for (std::size_t i = 0; i < n; ++i) w[i] = i % 17 == 0 ? 0.0 : std::pow(10.0, u(rng));
  return w;
}

// Checks every split on `curve` and that they all give the same owned list on this rank.
void check_all_splits(const std::vector<double>& x, const std::vector<double>& weights,
                      SfcCurve curve = SfcCurve::morton) {
  const std::vector<SfcKey> first = check_partition(x, weights, Split::even, curve);
  for (Split s : kSplits) {
    EXPECT_TRUE(check_partition(x, weights, s, curve) == first) << "split " << static_cast<int>(s);
  }
}

// The cell of level `level` of the 2^21 grid cell (ix, iy, iz) as one number, and the key's prefix
// of that level.
std::uint64_t coarse_cell(const std::uint32_t cell[3], int level) {
  std::uint64_t c = 0;
  for (int d = 0; d < 3; ++d) c = c << 21 | cell[d] >> (21 - level);
  return c;
}
std::uint64_t prefix(std::uint64_t key, int level) {
  return level == 0 ? 0 : key >> (3 * (21 - level));
}

}  // namespace

TEST(MpiPartition, MortonKeyInterleavesTheBits) {
  EXPECT_EQ(rpyfmm::mpi::morton_key(1, 0, 0), 4u);
  EXPECT_EQ(rpyfmm::mpi::morton_key(0, 1, 0), 2u);
  EXPECT_EQ(rpyfmm::mpi::morton_key(0, 0, 1), 1u);
  EXPECT_EQ(rpyfmm::mpi::morton_key(2097151, 2097151, 2097151), (std::uint64_t{1} << 63) - 1);
  std::mt19937_64 rng(5);
  for (int k = 0; k < 1000; ++k) {
    const std::uint32_t cell[3] = {static_cast<std::uint32_t>(rng() & 0x1fffff),
                                   static_cast<std::uint32_t>(rng() & 0x1fffff),
                                   static_cast<std::uint32_t>(rng() & 0x1fffff)};
    ASSERT_EQ(rpyfmm::mpi::morton_key(cell[0], cell[1], cell[2]), reference_key(cell));
  }
}

TEST(MpiPartition, HilbertKeyPrefixesAreTheOctreeCells) {
  // For random cells of the 2^21 grid and several levels l, two cells share the key prefix of 3l
  // bits exactly when they lie in the same cell of level l: the prefix is a function of the coarse
  // cell and the coarse cell one of the prefix.
  std::mt19937_64 rng(21);
  std::vector<std::array<std::uint32_t, 3>> cells(3000);
  for (std::size_t i = 0; i < cells.size(); ++i) {
    // Half of them near one corner of a coarse cell, so that deep levels share prefixes too.
    const std::uint32_t mask = i % 2 == 0 ? 0x1fffffu : 0x1fu;
    for (std::uint32_t& c : cells[i]) c = static_cast<std::uint32_t>(rng()) & mask;
  }
  for (int level : {0, 1, 2, 3, 5, 8, 13, 17, 20, 21}) {
    std::map<std::uint64_t, std::uint64_t> cell_of_prefix, prefix_of_cell;
    std::size_t wrong = 0;
    for (const auto& cell : cells) {
      const std::uint64_t p = prefix(rpyfmm::mpi::hilbert_key(cell[0], cell[1], cell[2]), level);
      const std::uint64_t c = coarse_cell(cell.data(), level);
      wrong += cell_of_prefix.try_emplace(p, c).first->second != c;
      wrong += prefix_of_cell.try_emplace(c, p).first->second != p;
    }
    EXPECT_EQ(wrong, 0u) << "level " << level;
    EXPECT_EQ(cell_of_prefix.size(), prefix_of_cell.size()) << "level " << level;
  }
}

TEST(MpiPartition, HilbertKeyVisitsTheGridByFaceNeighbours) {
  // On the full grid of 2^k cells per axis (the level-k cells, k = 1 .. 4), the keys' prefixes of 3k
  // bits are a bijection onto 0 .. 8^k - 1, and cells consecutive along it share a face (the
  // Hilbert property; Morton order breaks it from k = 1 on, checked as a control).
  for (int k = 1; k <= 4; ++k) {
    const std::uint32_t side = 1u << k;
    std::vector<std::array<std::uint32_t, 3>> by_key(std::size_t{side} * side * side, {side, side, side});
    std::size_t morton_jumps = 0;
    std::array<std::uint32_t, 3> previous_morton{};
    for (std::uint32_t x = 0; x < side; ++x) {
      for (std::uint32_t y = 0; y < side; ++y) {
        for (std::uint32_t z = 0; z < side; ++z) {
          const int shift = 21 - k;
          const std::uint64_t key = rpyfmm::mpi::hilbert_key(x << shift, y << shift, z << shift);
          const std::uint64_t p = prefix(key, k);
          ASSERT_LT(p, by_key.size());
          EXPECT_EQ(by_key[p][0], side) << "key prefix " << p << " twice at k = " << k;
          by_key[p] = {x, y, z};
        }
      }
    }
    for (std::size_t j = 1; j < by_key.size(); ++j) {
      std::uint32_t steps = 0;
      for (int d = 0; d < 3; ++d) {
        steps += by_key[j][d] > by_key[j - 1][d] ? by_key[j][d] - by_key[j - 1][d] : by_key[j - 1][d] - by_key[j][d];
      }
      EXPECT_EQ(steps, 1u) << "cells " << j - 1 << " and " << j << " along the curve at k = " << k;
    }
    // The control: Morton order (key j decoded by the reference interleave) jumps.
    for (std::uint64_t j = 0; j < by_key.size(); ++j) {
      std::array<std::uint32_t, 3> cell{};
      for (int b = 0; b < k; ++b) {
        for (int d = 0; d < 3; ++d) cell[d] |= static_cast<std::uint32_t>((j >> (3 * b + 2 - d)) & 1u) << b;
      }
      std::uint32_t steps = 0;
      for (int d = 0; d < 3; ++d)
        steps += cell[d] > previous_morton[d] ? cell[d] - previous_morton[d] : previous_morton[d] - cell[d];
      morton_jumps += j > 0 && steps != 1;
      previous_morton = cell;
    }
    EXPECT_GT(morton_jumps, 0u);
  }
  // The curve starts at the origin's cell.
  EXPECT_EQ(rpyfmm::mpi::hilbert_key(0, 0, 0), 0u);
}

TEST(MpiPartition, UniformSetWithUnitWeights) {
  check_all_splits(uniform_positions(1001, -2.0, 3.0, 1), {});
  check_all_splits(uniform_positions(1001, -2.0, 3.0, 1), {}, SfcCurve::hilbert);
}

TEST(MpiPartition, ClusteredSetWithSpreadWeights) {
  const Particles p = clustered_particles(500, 80, 2);
  check_all_splits(p.x, spread_weights(p.size(), 3));
  check_all_splits(p.x, spread_weights(p.size(), 3), SfcCurve::hilbert);
}

TEST(MpiPartition, WeightBoundHoldsInTheInputUnits) {
  // max part <= W / P + max w_i, up to the fixed point's rounding (at most unit / 2 per particle,
  // N unit / 2 in all) and the rounding of the double sum W here (N 2^-52 W): the tolerance.
  const std::vector<double> x = uniform_positions(800, 0.0, 1.0, 4);
  const std::vector<double> w = spread_weights(800, 5);
  const Partition part = partition_of(800, Split::geometric);
  const SfcPartition p(MPI_COMM_WORLD, share(x, 3, part.offset, part.n), share(w, 1, part.offset, part.n));
  const double total = std::accumulate(w.begin(), w.end(), 0.0);
  const double largest_w = *std::max_element(w.begin(), w.end());
  const double tolerance = 800 * p.weight_unit() / 2 + 800 * 0x1p-52 * total;
  const std::vector<double> parts = p.owned_weights();
  EXPECT_NEAR(std::accumulate(parts.begin(), parts.end(), 0.0), total, tolerance);
  for (double part_weight : parts) EXPECT_LE(part_weight, total / world_size() + largest_w + tolerance);
  EXPECT_LE(p.imbalance(), 1.0 + world_size() * (largest_w + tolerance) / total);
}

TEST(MpiPartition, OneDominantWeight) {
  // One particle carries almost all the weight: its part is at the bound, the others share the rest.
  std::vector<double> w(400, 1.0);
  w[123] = 1e6;
  check_all_splits(uniform_positions(400, 0.0, 1.0, 11), w);
  check_all_splits(uniform_positions(400, 0.0, 1.0, 11), w, SfcCurve::hilbert);
}

TEST(MpiPartition, SubnormalWeights) {
  // Weights near 1e-310: the fixed point's unit underflows, the owned weights stay exact sums.
  std::vector<double> w = spread_weights(200, 12);
  for (double& v : w) v *= 1e-313;
  const std::vector<double> x = uniform_positions(200, 0.0, 1.0, 13);
  const Partition part = partition_of(200, Split::even);
  const SfcPartition p(MPI_COMM_WORLD, share(x, 3, part.offset, part.n), share(w, 1, part.offset, part.n));
  const std::vector<double> parts = p.owned_weights();
  // Subnormal weights are multiples of 2^-1074 below 2^-1029, so q_i = w_i exactly in the unit, the
  // owned sums have at most 53 significant bits and are exact, as is the long double sum here:
  // tolerance 0.
  long double total = 0;
  for (double v : w) total += v;
  EXPECT_EQ(static_cast<long double>(std::accumulate(parts.begin(), parts.end(), 0.0L)), total);
}

TEST(MpiPartition, CoincidentPointsAreOrderedByGlobalIndex) {
  std::vector<double> x(3 * 37);
  for (std::size_t i = 0; i < 37; ++i) x[3 * i] = 1.5, x[3 * i + 1] = -2.0, x[3 * i + 2] = 7.0;
  check_all_splits(x, {});
  // Half of them at a second point: two keys, ties within each.
  for (std::size_t i = 0; i < 37; i += 2) x[3 * i + 2] = 8.0;
  check_all_splits(x, spread_weights(37, 6));
  check_all_splits(x, spread_weights(37, 6), SfcCurve::hilbert);
}

TEST(MpiPartition, ZeroWeightsEverywhereCountAsOne) {
  check_all_splits(uniform_positions(50, 0, 1, 7), std::vector<double>(50, 0.0));
}

TEST(MpiPartition, SingleParticleAndNoParticle) {
  check_all_splits({0.25, -1.0, 3.0}, {});
  const SfcPartition p(MPI_COMM_WORLD, {}, {});
  EXPECT_EQ(p.global_size(), 0u);
  EXPECT_EQ(p.owned_size(), 0u);
  EXPECT_EQ(p.imbalance(), 1.0);
  const Column none[] = {{{}, 3}};
  EXPECT_TRUE(p.to_owners(none)[0].empty());
}

TEST(MpiPartition, ExtremeSpreads) {
  check_all_splits(uniform_positions(300, -1e300, 1e300, 8), {});
  std::vector<double> x = uniform_positions(300, -1.0, 1.0, 9);
  for (double& c : x) c *= std::numeric_limits<double>::max();  // a spread that overflows a double
  check_all_splits(x, {});
  for (double& c : x) c = 1.0 + c / std::numeric_limits<double>::max() * 1e-13;  // a few ulps of 1
  check_all_splits(x, {});
  for (double& c : x) c = (c - 1.0) * 1e-295;  // tiny, partly subnormal
  check_all_splits(x, {});
  check_all_splits(x, {}, SfcCurve::hilbert);
}

TEST(MpiPartition, BadInputFailsEveryRank) {
  const int last = world_size() - 1;
  const std::string on_last = "rank " + std::to_string(last) + " of " + std::to_string(world_size());
  std::vector<double> x = uniform_positions(3, 0, 1, 10), w(3, 1.0);
  auto make = [&](const std::vector<double>& xi, const std::vector<double>& wi) {
    const SfcPartition p(MPI_COMM_WORLD, xi, wi);
  };
  std::vector<double> nan_x = x;
  nan_x[4] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { make(world_rank() == last ? nan_x : x, w); }, ErrorCode::invalid_input,
                          on_last + ": rpyfmm::mpi::SfcPartition: local positions entry (1, 1) is NaN");
  std::vector<double> inf_x = x;
  inf_x[0] = -std::numeric_limits<double>::infinity();
  expect_collective_error([&] { make(world_rank() == 0 ? inf_x : x, w); }, ErrorCode::invalid_input,
                          "rank 0 of " + std::to_string(world_size()) +
                              ": rpyfmm::mpi::SfcPartition: local positions entry (0, 0) is infinite");
  expect_collective_error(
      [&] {
        make(x, world_rank() == last ? std::vector<double>{1, -1, 1} : w);
      },
      ErrorCode::invalid_input,
      on_last + ": rpyfmm::mpi::SfcPartition: weight of local particle 1 must be finite and >= 0");
  expect_collective_error(
      [&] {
        make(x, world_rank() == last ? std::vector<double>{1, 1} : w);
      },
      ErrorCode::invalid_input, "local weights has 2 entries, expected 3");
  expect_collective_error(
      [&] {
        make(world_rank() == last ? std::vector<double>{1, 2} : x, {});
      },
      ErrorCode::invalid_input, "not a multiple of 3");
  expect_collective_error(
      [&] {
        const SfcPartition p(MPI_COMM_WORLD, x, w, world_rank() == last ? static_cast<SfcCurve>(2) : SfcCurve::hilbert);
      },
      ErrorCode::invalid_argument,
      on_last + ": rpyfmm::mpi::SfcPartition: curve must be SfcCurve::morton or SfcCurve::hilbert, got 2");
  if (world_size() > 1) {
    expect_collective_error(
        [&] { const SfcPartition p(MPI_COMM_WORLD, x, w, world_rank() == 0 ? SfcCurve::hilbert : SfcCurve::morton); },
        ErrorCode::invalid_argument, "rpyfmm::mpi::SfcPartition: the ranks pass different curves");
  }

  // Columns: a wrong size on the last rank, and different widths on different ranks.
  const SfcPartition p(MPI_COMM_WORLD, x, w);
  std::vector<double> short_column(world_rank() == last ? 2 : 3);
  const Column bad_size[] = {{short_column, 1}};
  expect_collective_error([&] { (void)p.to_owners(bad_size); }, ErrorCode::invalid_input,
                          on_last + ": rpyfmm::mpi::SfcPartition::to_owners: column 0 has 2 entries, expected 3");
  if (world_size() > 1) {
    std::vector<double> wide(world_rank() == 0 ? 6 : 3);
    const Column widths[] = {{wide, world_rank() == 0 ? 2u : 1u}};
    expect_collective_error([&] { (void)p.to_owners(widths); }, ErrorCode::invalid_argument,
                            "different numbers or widths of columns");
  }
  // The partition still works afterwards.
  const Column ok[] = {{x, 3}};
  EXPECT_EQ(bitwise_mismatches(p.to_origin(std::vector<Column>{{p.to_owners(ok)[0], 3}})[0], x), 0u);
}

namespace {

// The serial rule's cuts as splitters, from the whole set sorted by (key, index) with its q_i: cut r
// is the smallest position key · N + index with a weight of at least ceil(r Q / P) before it, so
// one past the particle at which the running sum reaches the target ((0, 0) for target 0).
std::vector<SfcKey> reference_splitters(const std::vector<SfcKey>& sorted, const std::vector<std::uint64_t>& q,
                                        std::size_t parts) {
  const std::uint64_t n = sorted.size();
  const std::uint64_t total = std::accumulate(q.begin(), q.end(), std::uint64_t{0});
  std::vector<SfcKey> cuts;
  for (std::size_t r = 1; r < parts; ++r) {
    const std::uint64_t target = reference_target(total, r, parts);
    std::uint64_t before = 0;
    std::size_t s = 0;
    while (target > 0 && before + q[s] < target) before += q[s++];
    if (target == 0) {
      cuts.push_back(SfcKey{0, 0});
    } else {
      cuts.push_back(sorted[s].index + 1 == n ? SfcKey{sorted[s].key + 1, 0}
                                              : SfcKey{sorted[s].key, sorted[s].index + 1});
    }
  }
  return cuts;
}

// The most rounds of a search with at least `ways` ways per round on [0, 2^63 N): ceil-divisions of
// the width by `ways` until it is 1.
int round_bound(std::uint64_t n, std::size_t ways) {
  int bits = 63;
  while (bits < 127 && (std::uint64_t{1} << (bits - 63)) < n) ++bits;  // 63 + ceil(log2 N)
  __extension__ using Wide = unsigned __int128;
  int rounds = 0;
  for (Wide w = static_cast<Wide>(1) << bits; w > 1; w = (w + ways - 1) / ways) ++rounds;
  return rounds;
}

// The budgets of sums per round to try: bisection (1: below one sum per cut), 2 per cut (3 ways), a
// budget just short of and at 255 per cut (255 and 256 ways) and the default.
std::vector<std::size_t> budgets() {
  const auto cuts = static_cast<std::size_t>(std::max(world_size() - 1, 1));
  return {1, 2 * cuts, 255 * cuts - 1, 255 * cuts, rpyfmm::mpi::kCutSumsPerRound};
}

// Partitions the global set (3N positions, N weights or none) split as `split` along `curve` with
// each of `sums` per round: the splitters are the serial rule's for every budget, and the rounds
// within the bound of the fewest ways (the ways with all P - 1 cuts open); the bisection's rounds
// are at least 63 + floor(log2 N) (each round at most halves the width).
void check_cuts(const std::vector<double>& x, const std::vector<double>& weights, Split split, SfcCurve curve,
                const std::vector<std::size_t>& sums) {
  const std::size_t n = x.size() / 3;
  const Partition part = partition_of(n, split);
  const std::vector<double> local_x = share(x, 3, part.offset, part.n);
  const std::vector<double> local_w = weights.empty() ? std::vector<double>{} : share(weights, 1, part.offset, part.n);
  const std::vector<std::uint64_t> keys = reference_keys(x, curve);
  std::vector<SfcKey> sorted(n);
  for (std::size_t i = 0; i < n; ++i) sorted[i] = SfcKey{keys[i], i};
  std::sort(sorted.begin(), sorted.end());
  const auto parts = static_cast<std::size_t>(world_size());
  for (std::size_t budget : sums) {
    const SfcPartition p(MPI_COMM_WORLD, local_x, local_w, curve, budget);
    const std::vector<SfcKey> expected =
        reference_splitters(sorted, reference_q(sorted, weights, p.weight_unit()), parts);
    EXPECT_TRUE(std::equal(expected.begin(), expected.end(), p.splitters().begin(), p.splitters().end()))
        << "N " << n << ", budget " << budget << ", split " << static_cast<int>(split);
    const std::size_t ways =
        parts == 1 ? 2 : std::max<std::size_t>(2, 1 + std::min<std::size_t>(budget / (parts - 1), 255));
    EXPECT_LE(p.cut_rounds(), round_bound(n, ways)) << "budget " << budget;
    const bool searched = parts > 1 && expected.back() != SfcKey{0, 0};
    if (!searched) {
      EXPECT_EQ(p.cut_rounds(), 0);
    }
    int floor_log2_n = 0;
    while (n >> (floor_log2_n + 1) != 0) ++floor_log2_n;
    if (searched && ways == 2) {
      EXPECT_GE(p.cut_rounds(), 63 + floor_log2_n) << "budget " << budget;
    }
  }
}

// check_cuts with every budget on both curves for the splits that leave ranks empty or not.
void check_cuts_everywhere(const std::vector<double>& x, const std::vector<double>& weights) {
  for (SfcCurve curve : {SfcCurve::morton, SfcCurve::hilbert}) {
    for (Split split : {Split::even, Split::first_empty, Split::last_only})
      check_cuts(x, weights, split, curve, budgets());
  }
}

}  // namespace

TEST(MpiPartitionCuts, UniformAndClusteredSets) {
  check_cuts_everywhere(uniform_positions(1001, -2.0, 3.0, 31), {});
  const Particles p = clustered_particles(400, 60, 32);
  check_cuts_everywhere(p.x, {});
  check_cuts_everywhere(p.x, spread_weights(p.size(), 33));
}

TEST(MpiPartitionCuts, ZeroAndHugeWeights) {
  // Weights of 1e300 beside 1 and 0 (the small ones round to q = 0 in the unit of the largest), then
  // all 0 (counting as 1 each).
  std::vector<double> w = spread_weights(300, 34);
  for (std::size_t i = 0; i < w.size(); i += 29) w[i] = 1e300;
  const std::vector<double> x = uniform_positions(300, 0.0, 1.0, 35);
  check_cuts_everywhere(x, w);
  check_cuts_everywhere(x, std::vector<double>(300, 0.0));
}

TEST(MpiPartitionCuts, DuplicatedPositions) {
  // 60 particles on three points: the cuts fall between equal keys, by global index.
  std::vector<double> x(3 * 60);
  for (std::size_t i = 0; i < 60; ++i) x[3 * i] = static_cast<double>(i % 3), x[3 * i + 1] = 0.5, x[3 * i + 2] = -1.0;
  check_cuts_everywhere(x, {});
  check_cuts_everywhere(x, spread_weights(60, 36));
}

TEST(MpiPartitionCuts, FewerParticlesThanRanks) {
  check_cuts_everywhere({}, {});
  check_cuts_everywhere({0.1, 0.2, 0.3}, {});
  check_cuts_everywhere({0.1, 0.2, 0.3, -4.0, 5.0, 6.0}, {2.0, 0.0});
}

TEST(MpiPartitionCuts, BudgetMustBePositiveAndAgree) {
  const std::vector<double> x = uniform_positions(3, 0, 1, 37);
  const int last = world_size() - 1;
  expect_collective_error(
      [&] { const SfcPartition p(MPI_COMM_WORLD, x, {}, SfcCurve::morton, world_rank() == last ? 0 : 8); },
      ErrorCode::invalid_argument,
      "rank " + std::to_string(last) + " of " + std::to_string(world_size()) +
          ": rpyfmm::mpi::SfcPartition: cut_sums_per_round must be >= 1, got 0");
  if (world_size() > 1) {
    expect_collective_error(
        [&] { const SfcPartition p(MPI_COMM_WORLD, x, {}, SfcCurve::morton, world_rank() == 0 ? 7 : 8); },
        ErrorCode::invalid_argument, "rpyfmm::mpi::SfcPartition: the ranks pass different cut_sums_per_round");
  }
}

namespace {

// Partitions the sources x (given as `source_split`, along `curve`), then the targets y (given as
// `target_split`) by their cuts (aligned_with), and checks the targets' partition against the
// serial rule: keys in the sources' cube, clamped to it; every target owned once, by the rank
// whose splitters' keys hold its key, in (key, index) order; the exchange both ways bit for bit.
// Returns this rank's owned targets.
std::vector<SfcKey> check_aligned(const std::vector<double>& x, const std::vector<double>& y, Split source_split,
                                  Split target_split, SfcCurve curve) {
  const Partition sp = partition_of(x.size() / 3, source_split);
  const SfcPartition sources(MPI_COMM_WORLD, share(x, 3, sp.offset, sp.n), {}, curve);
  const std::size_t m = y.size() / 3;
  const Partition tp = partition_of(m, target_split);
  const std::vector<double> local_y = share(y, 3, tp.offset, tp.n);
  const SfcPartition targets = SfcPartition::aligned_with(sources, local_y);
  EXPECT_EQ(targets.curve(), curve);
  EXPECT_EQ(targets.global_size(), m);
  EXPECT_EQ(targets.input_size(), tp.n);
  EXPECT_TRUE(std::ranges::equal(targets.splitters(), sources.splitters()));

  const std::vector<std::uint64_t> keys = reference_keys(y, curve, &x);
  std::vector<SfcKey> sorted(m);
  for (std::size_t i = 0; i < m; ++i) sorted[i] = SfcKey{keys[i], i};
  std::sort(sorted.begin(), sorted.end());
  const std::vector<SfcKey> owned(targets.owned().begin(), targets.owned().end());
  EXPECT_TRUE(all_gather(owned) == sorted) << "the owned targets in rank order are not the sorted set";
  const auto r = static_cast<std::size_t>(world_rank());
  const auto cuts = sources.splitters();
  std::size_t outside = 0;
  for (const SfcKey& k : owned) {
    outside += (r > 0 && k.key < cuts[r - 1].key) || (r < cuts.size() && k.key >= cuts[r].key);
  }
  EXPECT_EQ(outside, 0u) << "owned targets outside this rank's sources' key range";
  EXPECT_EQ(targets.owned_counts()[r], owned.size());
  EXPECT_EQ(targets.owned_weight_units()[r], owned.size());

  const Column columns[] = {{local_y, 3}};
  const std::vector<double> there = targets.to_owners(columns)[0];
  std::size_t wrong = 0;
  for (std::size_t j = 0; j < owned.size(); ++j)
    wrong += bitwise_mismatches(share(there, 3, j, 1), share(y, 3, owned[j].index, 1));
  EXPECT_EQ(wrong, 0u) << "target positions at the owners";
  const Column back[] = {{there, 3}};
  EXPECT_EQ(bitwise_mismatches(targets.to_origin(back)[0], local_y), 0u);
  return owned;
}

void check_aligned_all_splits(const std::vector<double>& x, const std::vector<double>& y, SfcCurve curve) {
  const std::vector<SfcKey> first = check_aligned(x, y, Split::even, Split::even, curve);
  for (Split s : kSplits) {
    for (Split t : kSplits) {
      EXPECT_TRUE(check_aligned(x, y, s, t, curve) == first)
          << "splits " << static_cast<int>(s) << ", " << static_cast<int>(t);
    }
  }
}

}  // namespace

TEST(MpiPartitionAligned, TargetsInsideAndOutsideTheSourcesCube) {
  // Sources in the unit cube; targets: inside it, a clump around one corner partly outside it, and
  // far outside on every side (clamped to the boundary cells), on both curves.
  const std::vector<double> x = uniform_positions(400, 0.0, 1.0, 40);
  std::vector<double> y = uniform_positions(300, 0.0, 1.0, 41);
  const std::vector<double> clump = uniform_positions(200, 0.9, 1.1, 42);
  const std::vector<double> far = uniform_positions(100, -50.0, 50.0, 43);
  y.insert(y.end(), clump.begin(), clump.end());
  y.insert(y.end(), far.begin(), far.end());
  for (SfcCurve curve : {SfcCurve::morton, SfcCurve::hilbert}) check_aligned_all_splits(x, y, curve);
}

TEST(MpiPartitionAligned, FewSourcesNoTargetsAndCoincidentSources) {
  // Fewer sources than ranks (ranks with empty ranges get no target), no target at all, and
  // sources that all coincide (a cube of side 0: every target keyed 0).
  const std::vector<double> y = uniform_positions(50, -1.0, 2.0, 44);
  check_aligned_all_splits({0.1, 0.2, 0.3}, y, SfcCurve::morton);
  check_aligned_all_splits(uniform_positions(20, 0.0, 1.0, 45), {}, SfcCurve::morton);
  std::vector<double> same(3 * 10, 0.5);
  check_aligned_all_splits(same, y, SfcCurve::hilbert);
}

TEST(MpiPartitionAligned, BadTargetsFailEveryRank) {
  const SfcPartition sources(MPI_COMM_WORLD, uniform_positions(5, 0, 1, 46));
  const int last = world_size() - 1;
  const std::string on_last = "rank " + std::to_string(last) + " of " + std::to_string(world_size());
  std::vector<double> y = uniform_positions(3, 0, 1, 47), nan_y = y;
  nan_y[5] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { (void)SfcPartition::aligned_with(sources, world_rank() == last ? nan_y : y); },
                          ErrorCode::invalid_input,
                          on_last + ": rpyfmm::mpi::SfcPartition: local positions entry (1, 2) is NaN");
  expect_collective_error(
      [&] {
        (void)SfcPartition::aligned_with(sources, world_rank() == last ? std::vector<double>{1.0, 2.0} : y);
      },
      ErrorCode::invalid_input, on_last + ": rpyfmm::mpi::SfcPartition: local positions have 2 entries");
}
