// rpyfmm::mpi::DistributedLaplaceFmm's regions exchanged between neighbouring ranks only
// (docs/mpi.md, "Distributed Laplace FMM"): the plan and every evaluation bit for bit the same as
// with every rank's cover gathered on every rank (gather_all_regions, the reference), on uniform
// sets, a cluster inside one rank's share, far-apart clusters and a chain of clusters, at the
// sources and at separate targets; and the neighbours and cover bytes that communication()
// reports, exactly where the geometry fixes them.
#include <gtest/gtest.h>
#include <mpi.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"

using rpyfmm::mpi::DistributedFmmOptions;
using rpyfmm::mpi::DistributedLaplaceFmm;
using rpyfmm::mpi::FmmCommunication;
using namespace rpyfmm_mpi_test;
namespace fmm = rpyfmm::fmm;

namespace {

constexpr std::size_t kNd = 2;
constexpr unsigned kOutputs = fmm::potential | fmm::gradient;
constexpr std::uint64_t kBoxBytes = 48;  // a box of a cover: lo and hi, 6 doubles

// `clusters` unit cubes of `per` uniform points each, the k-th at x = k × spacing: the Morton
// order visits them in turn, so with P = clusters ranks (even split of the curve) each rank owns one.
std::vector<double> cluster_row(std::size_t clusters, std::size_t per, double spacing, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> x;
  for (std::size_t k = 0; k < clusters; ++k) {
    for (std::size_t i = 0; i < per; ++i)
      x.insert(x.end(), {spacing * static_cast<double>(k) + u(rng), u(rng), u(rng)});
  }
  return x;
}

std::vector<double> charges(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> q(kNd * n);
  for (double& v : q) v = u(rng);
  return q;
}

// This rank's even share of the points (3 per point) and their charges (kNd x n).
struct Input {
  std::vector<double> x, q, targets;
};
Input input_of(const std::vector<double>& x, const std::vector<double>& targets, std::uint64_t seed) {
  const std::size_t n = x.size() / 3;
  const std::vector<double> q = charges(n, seed);
  const Partition p = partition_of(n, Split::even);
  Input in{share(x, 3, p.offset, p.n), {}, {}};
  for (std::size_t d = 0; d < kNd; ++d) {
    const auto first = q.begin() + static_cast<std::ptrdiff_t>(d * n + p.offset);
    in.q.insert(in.q.end(), first, first + static_cast<std::ptrdiff_t>(p.n));
  }
  if (!targets.empty()) {
    const Partition t = partition_of(targets.size() / 3, Split::geometric);
    in.targets = share(targets, 3, t.offset, t.n);
  }
  return in;
}

struct Evaluated {
  std::vector<double> results;
  FmmCommunication stats;
  std::size_t essential = 0;
};
Evaluated evaluate(DistributedFmmOptions options, bool gather_all, const Input& in) {
  options.gather_all_regions = gather_all;
  DistributedLaplaceFmm f(MPI_COMM_WORLD, options);
  f.set_points(in.x, in.targets);
  Evaluated e{std::vector<double>(kNd * f.local_target_size() * fmm::result_width), {}, f.essential_size()};
  f.evaluate(in.q, kNd, kOutputs, e.results);
  e.stats = f.communication();
  return e;
}

// Every rank's value of v, by rank.
std::vector<std::uint64_t> all_ranks(std::uint64_t v) {
  std::vector<std::uint64_t> all(static_cast<std::size_t>(world_size()));
  MPI_Allgather(&v, 1, MPI_UINT64_T, all.data(), 1, MPI_UINT64_T, MPI_COMM_WORLD);
  return all;
}

// The neighbour plan against the gathered one: the same essential sets and results bit for bit,
// no more cover bytes, and every cover sent received once.
void expect_same_plan(const DistributedFmmOptions& options, const Input& in, const std::string& what) {
  const Evaluated gathered = evaluate(options, true, in);
  const Evaluated neighbours = evaluate(options, false, in);
  EXPECT_EQ(neighbours.essential, gathered.essential) << what;
  EXPECT_EQ(neighbours.stats.halo_received, gathered.stats.halo_received) << what;
  EXPECT_EQ(neighbours.stats.cells_received, gathered.stats.cells_received) << what;
  EXPECT_EQ(neighbours.stats.nodes_received, gathered.stats.nodes_received) << what;
  EXPECT_EQ(neighbours.stats.halo_sent, gathered.stats.halo_sent) << what;
  EXPECT_EQ(neighbours.stats.cells_sent, gathered.stats.cells_sent) << what;
  EXPECT_EQ(neighbours.stats.nodes_sent, gathered.stats.nodes_sent) << what;
  EXPECT_EQ(bitwise_mismatches(neighbours.results, gathered.results), 0u) << what;
  EXPECT_LE(neighbours.stats.region_bytes_received, gathered.stats.region_bytes_received) << what;
  EXPECT_LE(neighbours.stats.region_neighbours, gathered.stats.region_neighbours) << what;
  EXPECT_EQ(neighbours.stats.region_boxes, gathered.stats.region_boxes) << what;
  std::uint64_t received = 0, sent = 0, bytes = 0, sent_bytes = 0;
  const std::vector<std::uint64_t> boxes = all_ranks(neighbours.stats.region_boxes);
  const std::vector<std::uint64_t> sent_to = all_ranks(neighbours.stats.region_sent_to);
  for (std::size_t r = 0; r < boxes.size(); ++r) sent_bytes += kBoxBytes * boxes[r] * sent_to[r];
  for (std::uint64_t v : all_ranks(neighbours.stats.region_neighbours)) received += v;
  for (std::uint64_t v : sent_to) sent += v;
  for (std::uint64_t v : all_ranks(neighbours.stats.region_bytes_received)) bytes += v;
  EXPECT_EQ(received, sent) << what;
  EXPECT_EQ(bytes, sent_bytes) << what;
}

// The options compared: the default rule, a fixed order at a loose tolerance, and a min_leaf_side
// that keeps near cells from being compressed.
std::vector<std::pair<std::string, DistributedFmmOptions>> option_sets() {
  DistributedFmmOptions rule;
  rule.fmm.tolerance = 1e-6;
  DistributedFmmOptions fixed;
  fixed.fmm.tolerance = 1e-3;
  fixed.chebyshev_order = 3;
  DistributedFmmOptions near = rule;
  near.fmm.min_leaf_side = 0.6;
  return {{"rule", rule}, {"fixed order", fixed}, {"min_leaf_side", near}};
}

}  // namespace

TEST(DistributedFmmRegions, SamePlanAsEveryCoverGathered) {
  const std::vector<double> uniform = uniform_particles(2000, 1.0, 1.0, 1.0, 61).x;
  const std::vector<double> clustered = clustered_particles(600, 1400, 62).x;
  const std::vector<double> far_pair = cluster_row(2, 1000, 1000.0, 63);
  const std::vector<double> chain = cluster_row(4, 500, 1.5, 64);
  // Targets in the first cluster only: ranks whose sources lie in the other see only far regions.
  const std::vector<double> first_cluster = cluster_row(1, 700, 1.0, 65);
  const std::vector<std::pair<std::string, Input>> inputs = {
      {"uniform", input_of(uniform, {}, 71)},
      {"cluster inside one share", input_of(clustered, {}, 72)},
      {"two far clusters", input_of(far_pair, {}, 73)},
      {"a chain of four clusters", input_of(chain, {}, 74)},
      {"two far clusters, targets in one", input_of(far_pair, first_cluster, 75)},
      {"a chain, uniform targets", input_of(chain, uniform, 76)},
  };
  for (const auto& [name, in] : inputs) {
    for (const auto& [rule, options] : option_sets()) expect_same_plan(options, in, name + ", " + rule);
  }
}

TEST(DistributedFmmRegions, NeighboursWhereTheGeometryFixesThem) {
  DistributedFmmOptions options;
  options.fmm.tolerance = 1e-6;
  const auto ranks = static_cast<std::size_t>(world_size());
  const auto me = static_cast<std::size_t>(world_rank());
  // Uniform in a unit cube on at most 4 ranks: every rank's root cube (half-side about 0.5, around
  // a quarter or more of the cube) is within one side of every other rank's region, so every rank
  // walks for every other one and the covers travel as in the all-gather.
  {
    const Input in = input_of(uniform_particles(2000, 1.0, 1.0, 1.0, 81).x, {}, 82);
    const Evaluated e = evaluate(options, false, in);
    const std::vector<std::uint64_t> boxes = all_ranks(e.stats.region_boxes);
    std::uint64_t others = 0;
    for (std::size_t r = 0; r < ranks; ++r) others += r == me ? 0 : boxes[r];
    EXPECT_EQ(e.stats.region_neighbours, ranks - 1);
    EXPECT_EQ(e.stats.region_sent_to, ranks - 1);
    EXPECT_EQ(e.stats.region_bytes_received, kBoxBytes * others);
    EXPECT_EQ(e.stats.region_bytes_received, evaluate(options, true, in).stats.region_bytes_received);
  }
  // Two unit cubes 1000 apart, one per pair of ranks (2 and 4 ranks): a root cell at ratio ~2000
  // from the other pair's region is compressed whole (order 2, 1000 sources > 8 nodes), so each
  // rank exchanges covers with its pair's other rank only.
  if (ranks == 2 || ranks == 4) {
    const Evaluated e = evaluate(options, false, input_of(cluster_row(2, 1000, 1000.0, 83), {}, 84));
    const std::vector<std::uint64_t> boxes = all_ranks(e.stats.region_boxes);
    const std::uint64_t mates = ranks == 4 ? 1 : 0;
    EXPECT_EQ(e.stats.region_neighbours, mates);
    EXPECT_EQ(e.stats.region_sent_to, mates);
    EXPECT_EQ(e.stats.region_bytes_received, ranks == 4 ? kBoxBytes * boxes[me ^ 1u] : 0u);
  }
  // Four unit cubes at x = 0, 1.5, 3, 4.5 on 4 ranks, one each (the key cube starts at the lowest
  // corner, so its first two levels split x at 2.75, 1.375 and 4.125, between the cubes). Adjacent
  // cubes are 0.5 apart, under a side (eta ~1 < 2): they walk each other's cells. The next but one
  // are at least 2 apart, eta ~4 and more: order 8 at most (rho = 4 + sqrt(17), rho^-8 < 1e-7),
  // 512 nodes < 800 sources, so the root cell is compressed whole and no cover travels.
  if (ranks == 4) {
    const Evaluated e = evaluate(options, false, input_of(cluster_row(4, 800, 1.5, 85), {}, 86));
    const std::vector<std::uint64_t> boxes = all_ranks(e.stats.region_boxes);
    std::uint64_t expected = 0, count = 0;
    for (std::size_t r = 0; r < ranks; ++r) {
      if (r + 1 == me || me + 1 == r) {
        expected += kBoxBytes * boxes[r];
        ++count;
      }
    }
    EXPECT_EQ(e.stats.region_neighbours, count);
    EXPECT_EQ(e.stats.region_sent_to, count);
    EXPECT_EQ(e.stats.region_bytes_received, expected);
  }
}
