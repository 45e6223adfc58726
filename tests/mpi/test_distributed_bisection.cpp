// The block preconditioner's blocks by the distributed median bisection (mpi/src/
// distributed_bisection.hpp; docs/mpi.md, "Brownian displacements"): exactly the serial
// rpy::bisect_blocks of the whole set (order and offsets) for uniform, clustered, tie-heavy and tiny
// sets, numbered at random or in slabs (parts held by one rank, split there alone), several block
// sizes and every split of the particles over the ranks; the owners by the
// serial rule; the owned members' positions and radii; and collective failures on bad input.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "distributed_bisection.hpp"
#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/rpy/block_factors.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::Communicator;
using rpyfmm::mpi::detail::distributed_bisection;
using rpyfmm::mpi::detail::DistributedBlocks;
using namespace rpyfmm_mpi_test;

namespace {

constexpr const char* kWhere = "test_distributed_bisection";

// Collective: every rank's values, concatenated in rank order.
std::vector<std::uint64_t> all_gathered(const std::vector<std::uint64_t>& mine) {
  const int count = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<std::size_t>(world_size())), displs(counts.size(), 0);
  MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  for (std::size_t r = 1; r < counts.size(); ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<std::uint64_t> all(static_cast<std::size_t>(displs.back() + counts.back()));
  MPI_Allgatherv(mine.data(), count, MPI_UINT64_T, all.data(), counts.data(), displs.data(), MPI_UINT64_T,
                 MPI_COMM_WORLD);
  return all;
}

// The whole partition from the ranks' owned blocks: each rank lists (block, members...) per owned
// block, every rank assembles the blocks in block order.
rpyfmm::rpy::BlockPartition assembled(const DistributedBlocks& d) {
  std::vector<std::uint64_t> mine;
  for (std::size_t k = 0; k < d.owned.size(); ++k) {
    mine.push_back(d.owned[k]);
    mine.push_back(d.owned_offsets[k + 1] - d.owned_offsets[k]);
    mine.insert(mine.end(), d.members.begin() + static_cast<std::ptrdiff_t>(d.owned_offsets[k]),
                d.members.begin() + static_cast<std::ptrdiff_t>(d.owned_offsets[k + 1]));
  }
  const std::vector<std::uint64_t> all = all_gathered(mine);
  std::vector<std::vector<std::size_t>> blocks(d.blocks());
  for (std::size_t at = 0; at < all.size(); at += 2 + all[at + 1]) {
    EXPECT_LT(all[at], blocks.size());
    EXPECT_TRUE(blocks.at(all[at]).empty()) << "block " << all[at] << " owned by two ranks";
    blocks.at(all[at]).assign(all.begin() + static_cast<std::ptrdiff_t>(at + 2),
                              all.begin() + static_cast<std::ptrdiff_t>(at + 2 + all[at + 1]));
  }
  rpyfmm::rpy::BlockPartition p;
  for (const std::vector<std::size_t>& b : blocks) {
    p.order.insert(p.order.end(), b.begin(), b.end());
    p.offsets.push_back(p.order.size());
  }
  return p;
}

// The owner of every serial block: the rank holding most of its members, the lowest on a tie.
std::vector<int> serial_owners(const rpyfmm::rpy::BlockPartition& serial, const std::vector<std::size_t>& counts) {
  std::vector<int> rank_of;
  for (std::size_t r = 0; r < counts.size(); ++r) rank_of.insert(rank_of.end(), counts[r], static_cast<int>(r));
  std::vector<int> owners;
  for (std::size_t b = 0; b < serial.blocks(); ++b) {
    std::vector<std::size_t> held(counts.size(), 0);
    for (std::size_t k = serial.offsets[b]; k < serial.offsets[b + 1]; ++k) ++held[rank_of[serial.order[k]]];
    owners.push_back(static_cast<int>(std::max_element(held.begin(), held.end()) - held.begin()));
  }
  return owners;
}

// Collective: the distributed blocks of the whole set `x` (3 per particle, the same on every rank)
// split over the ranks by `counts` against rpy::bisect_blocks on x, exactly.
void expect_serial_blocks(const std::vector<double>& x, const std::vector<std::size_t>& counts, std::size_t max_block,
                          const std::string& what) {
  const std::size_t n = x.size() / 3;
  const auto me = static_cast<std::size_t>(world_rank());
  std::size_t offset = 0;
  for (std::size_t r = 0; r < me; ++r) offset += counts[r];
  std::vector<double> radii(n);
  for (std::size_t g = 0; g < n; ++g) radii[g] = 0.5 + 1e-3 * static_cast<double>(g);
  const DistributedBlocks d =
      distributed_bisection(Communicator(MPI_COMM_WORLD), offset, share(x, 3, offset, counts[me]),
                            share(radii, 1, offset, counts[me]), max_block, kWhere);
  const rpyfmm::rpy::BlockPartition serial = rpyfmm::rpy::bisect_blocks(x, max_block);
  const std::string label = what + ", max_block " + std::to_string(max_block) + ", rank " + std::to_string(me);
  ASSERT_EQ(d.global_offsets, serial.offsets) << label;
  const rpyfmm::rpy::BlockPartition whole = assembled(d);
  EXPECT_EQ(whole.offsets, serial.offsets) << label;
  EXPECT_EQ(whole.order, serial.order) << label;
  EXPECT_EQ(d.owner, serial_owners(serial, counts)) << label;
  for (std::size_t k = 0; k < d.members.size(); ++k) {
    const std::size_t g = d.members[k];
    ASSERT_LT(g, n) << label;
    for (std::size_t c = 0; c < 3; ++c) EXPECT_EQ(d.positions[3 * k + c], x[3 * g + c]) << label;
    EXPECT_EQ(d.radii[k], radii[g]) << label;
  }
}

// Collective: expect_serial_blocks for every split of the particles over the ranks, each block size.
void expect_serial_blocks_every_split(const std::vector<double>& x, std::initializer_list<std::size_t> max_blocks,
                                      const std::string& what) {
  const std::size_t n = x.size() / 3;
  const auto ranks = static_cast<std::size_t>(world_size());
  for (const std::size_t max_block : max_blocks) {
    for (const Split split : kSplits)
      expect_serial_blocks(x, split_counts(n, ranks, split), max_block, what + ", split " + std::to_string(int(split)));
    // Random shares (the same on every rank: one seed).
    std::mt19937_64 rng(n + max_block);
    std::vector<std::size_t> counts(ranks, 0);
    for (std::size_t g = 0; g < n; ++g) ++counts[rng() % ranks];
    expect_serial_blocks(x, counts, max_block, what + ", random shares");
  }
}

// N points on a lattice of `side`^3 sites (spacing 1, many equal coordinates along every axis),
// several on one site where N > side^3, a site's zero coordinates as -0.0 or +0.0 alternately
// (equal under <, so ordered by index).
std::vector<double> lattice(std::size_t n, std::size_t side) {
  std::vector<double> x(3 * n);
  for (std::size_t g = 0; g < n; ++g) {
    const std::size_t site = (g * 7919) % (side * side * side);
    const std::size_t ijk[3] = {site % side, (site / side) % side, site / (side * side)};
    for (std::size_t c = 0; c < 3; ++c) {
      x[3 * g + c] = static_cast<double>(ijk[c]);
      if (ijk[c] == 0 && g % 2 == 1) x[3 * g + c] = -0.0;
    }
  }
  return x;
}

// Two far clusters of n / 2 points each, Gaussian of width 1 around (0, 0, 0) and (1e4, 50, -3).
std::vector<double> two_clusters(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::vector<double> x(3 * n);
  const double far[3] = {1e4, 50.0, -3.0};
  for (std::size_t g = 0; g < n; ++g)
    for (std::size_t c = 0; c < 3; ++c) x[3 * g + c] = normal(rng) + (g % 2 == 0 ? 0.0 : far[c]);
  return x;
}

// The points renumbered by their first coordinate (by index on a tie): contiguous shares are then
// slabs, so most parts of the deeper levels lie on one rank and are split there alone.
std::vector<double> in_slabs(const std::vector<double>& x) {
  std::vector<std::size_t> order(x.size() / 3);
  for (std::size_t g = 0; g < order.size(); ++g) order[g] = g;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) { return x[3 * i] < x[3 * j]; });
  std::vector<double> sorted(x.size());
  for (std::size_t g = 0; g < order.size(); ++g) std::copy_n(x.data() + 3 * order[g], 3, sorted.data() + 3 * g);
  return sorted;
}

}  // namespace

TEST(MpiDistributedBisection, UniformSetIsTheSerialBisectionExactly) {
  const std::vector<double> x = uniform_particles(700, 10.0, 1.0, 1.0, 5).x;
  expect_serial_blocks_every_split(x, {1, 3, 8, 50}, "uniform 700");
  expect_serial_blocks_every_split(in_slabs(x), {1, 3, 8, 50}, "uniform 700 in slabs");
}

TEST(MpiDistributedBisection, ClusteredSetsAreTheSerialBisectionExactly) {
  expect_serial_blocks_every_split(two_clusters(600, 17), {2, 7, 64}, "two clusters 600");
  expect_serial_blocks_every_split(in_slabs(two_clusters(600, 17)), {2, 7, 64}, "two clusters 600 in slabs");
  expect_serial_blocks_every_split(clustered_particles(120, 40, 23).x, {4, 16}, "clustered 160");
}

TEST(MpiDistributedBisection, TieHeavySetsAreTheSerialBisectionExactly) {
  // 512 sites of an 8^3 lattice, 900 points: each coordinate value is shared by over 100 points,
  // and some points coincide, so most splits are decided by the index.
  expect_serial_blocks_every_split(lattice(900, 8), {1, 5, 32}, "lattice 900 on 8^3");
  expect_serial_blocks_every_split(in_slabs(lattice(900, 8)), {1, 5, 32}, "lattice 900 on 8^3 in slabs");
  // Every point at one place: the order is the index alone.
  expect_serial_blocks_every_split(std::vector<double>(3 * 200, 1.25), {3, 16}, "200 coincident");
}

TEST(MpiDistributedBisection, TinySetsAreTheSerialBisectionExactly) {
  // N = 0, N = 1 and N <= max_block: one block (or none); ranks with no particles in every split
  // with more ranks than particles.
  for (const std::size_t n : {0, 1, 2, 3, 5})
    expect_serial_blocks_every_split(uniform_particles(n, 4.0, 1.0, 1.0, 9 + n).x, {1, 2, 8},
                                     "tiny " + std::to_string(n));
}

TEST(MpiDistributedBisection, BadInputFailsOnEveryRank) {
  const Communicator comm(MPI_COMM_WORLD);
  const std::vector<double> x = uniform_particles(40, 4.0, 1.0, 1.0, 3).x;
  const Partition part = partition_of(40, Split::even);
  const std::vector<double> mine = share(x, 3, part.offset, part.n);
  const std::vector<double> radii(part.n, 1.0);
  // One position too few on the last rank.
  const bool last = world_rank() == world_size() - 1;
  const std::vector<double> short_x(mine.begin(), mine.end() - (last && !mine.empty() ? 1 : 0));
  expect_collective_error(
      [&] { static_cast<void>(distributed_bisection(comm, part.offset, short_x, radii, 8, kWhere)); },
      ErrorCode::invalid_argument, "positions hold");
  // A share that does not start where the ranks before end.
  expect_collective_error(
      [&] { static_cast<void>(distributed_bisection(comm, part.offset + 1, mine, radii, 8, kWhere)); },
      ErrorCode::invalid_argument, "the share starts at particle");
}
