// The block preconditioner's blocks kept by the operator between sampler calls (rpyfmm/mpi/sqrt.hpp,
// rpyfmm/mpi/sampler_blocks.hpp; docs/mpi.md, "Brownian displacements"): repeated samples bit for
// bit the first and the serial DirectRpy::apply_sqrt whatever is called in between (products, other
// samplers, other block sizes, the sampler with rotation, set_positions to the same, other or bad
// positions), the statistics saying "reused" exactly where the blocks of the configuration were
// built before, and the blocks' exchanges counted: the build's bytes against the distributed
// bisection's and each exchange's bytes against the formulas of BlockPreconditionerStats, the
// particles moved against the serial blocks' owners counted here.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "distributed_bisection.hpp"
#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "rpyfmm/rpy/block_factors.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "sqrt_test_support.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::BlockPreconditionerStats;
using rpyfmm::mpi::DistributedDirectRpy;
using rpyfmm::mpi::DistributedFmmRpy;
using rpyfmm::mpi::InnerProductStats;
using rpyfmm::rpy::SqrtMethod;
using rpyfmm::rpy::SqrtOptions;
using rpyfmm::rpy::SqrtPreconditioner;
using rpyfmm::rpy::SqrtReport;
using namespace rpyfmm_mpi_test;

// Only the samplers replace an operator's kept blocks: its accessor gives a const reference, and
// SamplerBlocks has no public way to replace them through one.
template <class Operator>
constexpr bool kBlocksReadOnly =
    std::is_same_v<decltype(std::declval<const Operator&>().sampler_blocks()), const rpyfmm::mpi::SamplerBlocks&>;
static_assert(kBlocksReadOnly<DistributedDirectRpy> && kBlocksReadOnly<DistributedFmmRpy>);

namespace {

SqrtOptions block_sampler(SqrtMethod method, int block) {
  SqrtOptions o = sampler(method, SqrtPreconditioner::block, 1e-6);
  o.preconditioner_block = block;
  return o;
}

// One translational sample of this rank's share of z on `op`, with its statistics.
struct Sample {
  std::vector<double> w;
  SqrtReport report;
  InnerProductStats stats;
};

template <class Operator>
Sample sample(const Operator& op, const std::vector<double>& local_z, const SqrtOptions& options,
              std::size_t nrhs = 1) {
  Sample s{std::vector<double>(local_z.size()), {}, {}};
  s.report = rpyfmm::mpi::sqrt_apply(op, local_z, s.w, nrhs, options, &s.stats);
  return s;
}

// This rank's particles in blocks owned by other ranks, and other ranks' particles in the blocks
// it owns, for the serial blocks of the whole set (rpy::bisect_blocks) on the ranks' shares `part`
// of every rank: the owner of a block is the rank holding most of its members, the lowest on a tie
// (docs/mpi.md, "Brownian displacements").
struct Moved {
  std::size_t sent = 0, received = 0;
};

Moved moved_particles(const Particles& p, std::size_t max_block, Split split) {
  const std::vector<std::size_t> counts = split_counts(p.size(), static_cast<std::size_t>(world_size()), split);
  std::vector<std::size_t> rank_of;
  for (std::size_t r = 0; r < counts.size(); ++r) rank_of.insert(rank_of.end(), counts[r], r);
  const rpyfmm::rpy::BlockPartition blocks = rpyfmm::rpy::bisect_blocks(p.x, max_block);
  const auto me = static_cast<std::size_t>(world_rank());
  Moved m;
  for (std::size_t b = 0; b < blocks.blocks(); ++b) {
    std::vector<std::size_t> members(counts.size(), 0);
    for (std::size_t k = blocks.offsets[b]; k < blocks.offsets[b + 1]; ++k) ++members[rank_of[blocks.order[k]]];
    const auto owner = static_cast<std::size_t>(std::max_element(members.begin(), members.end()) - members.begin());
    const std::size_t total = blocks.offsets[b + 1] - blocks.offsets[b];
    if (owner == me) m.received += total - members[me];
    if (owner != me) m.sent += members[me];
  }
  return m;
}

// The build's distributed bisection and members' exchange (BlockPreconditionerStats::
// gather_bytes_received): nothing from other ranks on one rank; on several, at least one
// collective's result (every set here has more particles than a block). The exact count, which
// depends on the selection's rounds, is checked in StatisticsCountEachExchangeOfTheBlocks.
void expect_built(const BlockPreconditionerStats& s, const std::string& what) {
  EXPECT_FALSE(s.reused) << what;
  if (world_size() == 1) {
    EXPECT_EQ(s.gather_bytes_received, 0u) << what;
  } else {
    EXPECT_GT(s.gather_bytes_received, 0u) << what;
  }
  EXPECT_GE(s.gather_seconds, 0.0) << what;
  EXPECT_LE(s.gather_seconds, s.build_seconds) << what;  // the bisection is a part of the build
}

void expect_reused(const BlockPreconditionerStats& s, const std::string& what) {
  EXPECT_TRUE(s.reused) << what;
  EXPECT_EQ(s.build_seconds, 0.0) << what;
  EXPECT_EQ(s.gather_seconds, 0.0) << what;
  EXPECT_EQ(s.gather_bytes_received, 0u) << what;
}

std::string on_rank(const std::string& what) {
  return what + ", rank " + std::to_string(world_rank()) + " of " + std::to_string(world_size());
}

}  // namespace

TEST(MpiDistributedSqrtBlockCache, RepeatedSamplesAreTheFirstBitForBitWhateverIsCalledBetween) {
  // Blocks of at most 8 particles of the whole set, split geometrically (blocks cut between ranks).
  // Every sample of the configuration must be, bit for bit, the serial DirectRpy::apply_sqrt's with
  // the block preconditioner on the whole set, so the kept blocks can change no bit; "reused" must
  // be set exactly where this configuration's blocks (positions, block size, matrix) were built by
  // an earlier call and no set_positions came since.
  const Particles p = clustered_particles(90, 30, 71);
  const Partition part = partition_of(p.size(), Split::geometric);
  const WholeSet set(p, 13, 2);
  const std::vector<double> z = share(set.z, 3, part.offset, part.n);
  const SqrtOptions lanczos8 = block_sampler(SqrtMethod::lanczos, 8);
  std::vector<double> serial(set.z.size());
  set.op.apply_sqrt(set.z, serial, lanczos8);
  const std::vector<double> expected = share(serial, 3, part.offset, part.n);

  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  place(op, p, part);
  const auto expect_first = [&](const Sample& s, const std::string& what) {
    EXPECT_EQ(bitwise_mismatches(s.w, expected), 0u) << on_rank(what);
  };
  const Sample first = sample(op, z, lanczos8);
  expect_first(first, "first sample");
  expect_built(first.stats.blocks, on_rank("first sample"));
  const Sample second = sample(op, z, lanczos8);
  expect_first(second, "second sample");
  expect_reused(second.stats.blocks, on_rank("second sample"));

  // A product, the sampler without preconditioner (no blocks: its block statistics all zero), and
  // Chebyshev with the same blocks (the blocks do not depend on the method).
  std::vector<double> u(3 * part.n);
  op.apply(share(p.f, 3, part.offset, part.n), u);
  const Sample plain = sample(op, z, sampler(SqrtMethod::lanczos, SqrtPreconditioner::none, 1e-6));
  EXPECT_FALSE(plain.stats.blocks.reused);
  EXPECT_EQ(plain.stats.blocks.apply_g.applications + plain.stats.blocks.solve_g.applications, 0);
  const SqrtOptions chebyshev8 = block_sampler(SqrtMethod::chebyshev, 8);
  std::vector<double> serial_chebyshev(set.z.size());
  set.op.apply_sqrt(set.z, serial_chebyshev, chebyshev8);
  const Sample chebyshev = sample(op, z, chebyshev8);
  EXPECT_EQ(bitwise_mismatches(chebyshev.w, share(serial_chebyshev, 3, part.offset, part.n)), 0u);
  expect_reused(chebyshev.stats.blocks, on_rank("Chebyshev after Lanczos"));
  const Sample after_others = sample(op, z, lanczos8);
  expect_first(after_others, "after a product and other samplers");
  expect_reused(after_others.stats.blocks, on_rank("after a product and other samplers"));

  // Another block size, then the sampler with rotation (the scaled grand mobility's blocks): each
  // replaces the kept blocks, so the next sample of 8 builds them again.
  const Sample four = sample(op, z, block_sampler(SqrtMethod::lanczos, 4));
  expect_built(four.stats.blocks, on_rank("block size 4"));
  const Sample eight_again = sample(op, z, lanczos8);
  expect_first(eight_again, "after block size 4");
  expect_built(eight_again.stats.blocks, on_rank("after block size 4"));
  std::vector<double> z_r(z.size(), 0.5), w_t(z.size()), w_r(z.size());
  InnerProductStats rotation;
  rpyfmm::mpi::sqrt_apply_rotation(op, z, z_r, w_t, w_r, lanczos8, rotation);
  expect_built(rotation.blocks, on_rank("rotation"));
  const Sample after_rotation = sample(op, z, lanczos8);
  expect_first(after_rotation, "after the sampler with rotation");
  expect_built(after_rotation.stats.blocks, on_rank("after the sampler with rotation"));

  // set_positions to the same positions, to other ones (the serial sample of those), back, and a
  // failed one (NaN on the last rank): every one drops the blocks.
  place(op, p, part);
  const Sample same = sample(op, z, lanczos8);
  expect_first(same, "after set_positions to the same positions");
  expect_built(same.stats.blocks, on_rank("after set_positions to the same positions"));
  const Particles moved = clustered_particles(90, 30, 72);
  const WholeSet other(moved, 13, 2);
  std::vector<double> serial_other(other.z.size());
  other.op.apply_sqrt(set.z, serial_other, lanczos8);
  place(op, moved, part);
  const Sample at_other = sample(op, z, lanczos8);
  EXPECT_EQ(bitwise_mismatches(at_other.w, share(serial_other, 3, part.offset, part.n)), 0u);
  expect_built(at_other.stats.blocks, on_rank("other positions"));
  expect_reused(sample(op, z, lanczos8).stats.blocks, on_rank("other positions, second sample"));
  place(op, p, part);
  const Sample back = sample(op, z, lanczos8);
  expect_first(back, "back to the first positions");
  expect_built(back.stats.blocks, on_rank("back to the first positions"));
  std::vector<double> bad = share(p.x, 3, part.offset, part.n);
  if (part.offset == 0 && part.n > 0) bad[0] = std::numeric_limits<double>::quiet_NaN();  // the first particle
  expect_collective_error([&] { op.set_positions(bad, share(p.a, 1, part.offset, part.n)); }, ErrorCode::invalid_input,
                          "DistributedDirectRpy::set_positions");
  expect_collective_error([&] { sample(op, z, lanczos8); }, ErrorCode::invalid_input, "positions not set");
  place(op, p, part);
  const Sample after_failure = sample(op, z, lanczos8);
  expect_first(after_failure, "after a failed set_positions");
  expect_built(after_failure.stats.blocks, on_rank("after a failed set_positions"));
}

TEST(MpiDistributedSqrtBlockCache, StatisticsCountEachExchangeOfTheBlocks) {
  // Lanczos with the blocks on two right-hand sides, on every split: G^T and G once per product
  // call with the columns it multiplies, G^{-1} once with both columns; each application moves
  // dofs doubles per column of every moved particle each way (the particles counted here from the
  // serial blocks and the owner rule), and the build sends each moved particle's index, block,
  // position and radius to the owner once. With rotation: 6 doubles per particle and column.
  const Particles p = clustered_particles(90, 30, 73);
  constexpr std::size_t kBlock = 8;
  const WholeSet set(p, 17, 3);
  constexpr std::size_t kColumns = 2;
  for (Split s : kSplits) {
    const Partition part = partition_of(p.size(), s);
    const std::string what = on_rank("split " + std::to_string(static_cast<int>(s)));
    std::vector<double> z = share(set.z, 3, part.offset, part.n);
    for (std::size_t i = 0; i < 3 * part.n; ++i) z.push_back(0.5 * z[i] + 0.25);
    DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
    place(op, p, part);
    const Sample first = sample(op, z, block_sampler(SqrtMethod::lanczos, static_cast<int>(kBlock)), kColumns);
    const BlockPreconditionerStats& b = first.stats.blocks;
    expect_built(b, what);
    const Moved m = moved_particles(p, kBlock, s);
    // The build's bytes: those of the distributed bisection on this share (what the operator
    // built), of which the members' exchange, 6 doubles per member from another rank, is a part,
    // with at least the owners' MPI_Allreduce (16 bytes per block) beside it on several ranks.
    const rpyfmm::mpi::detail::DistributedBlocks d = rpyfmm::mpi::detail::distributed_bisection(
        rpyfmm::mpi::Communicator(MPI_COMM_WORLD), part.offset, share(p.x, 3, part.offset, part.n),
        share(p.a, 1, part.offset, part.n), kBlock, "test");
    EXPECT_EQ(b.gather_bytes_received, d.bytes_received) << what;
    if (world_size() > 1) {
      EXPECT_GE(b.gather_bytes_received, 48 * m.received + 16 * d.blocks()) << what;
    }
    EXPECT_EQ(b.particles_sent, m.sent) << what;
    EXPECT_EQ(b.particles_received, m.received) << what;
    const std::uint64_t per_column = 8 * 3 * (m.sent + m.received);
    EXPECT_EQ(b.apply_g.applications, first.report.operator_applications) << what;
    EXPECT_EQ(b.apply_g_transpose.applications, first.report.operator_applications) << what;
    EXPECT_EQ(b.apply_g.columns, first.report.vector_products) << what;
    EXPECT_EQ(b.apply_g_transpose.columns, first.report.vector_products) << what;
    EXPECT_EQ(b.solve_g.applications, 1) << what;
    EXPECT_EQ(b.solve_g.columns, static_cast<long long>(kColumns)) << what;
    for (const auto* e : {&b.apply_g, &b.apply_g_transpose, &b.solve_g}) {
      EXPECT_EQ(e->bytes_received, per_column * static_cast<std::uint64_t>(e->columns)) << what;
      EXPECT_GE(e->seconds, 0.0) << what;
    }
    EXPECT_EQ(b.exchange_seconds(), b.apply_g.seconds + b.apply_g_transpose.seconds + b.solve_g.seconds) << what;
    EXPECT_EQ(b.exchange_bytes_received(),
              b.apply_g.bytes_received + b.apply_g_transpose.bytes_received + b.solve_g.bytes_received)
        << what;
    // Used again: the same exchanges, no build.
    const Sample again = sample(op, z, block_sampler(SqrtMethod::lanczos, static_cast<int>(kBlock)), kColumns);
    EXPECT_EQ(bitwise_mismatches(again.w, first.w), 0u) << what;
    expect_reused(again.stats.blocks, what);
    EXPECT_EQ(again.stats.blocks.particles_sent, m.sent) << what;
    EXPECT_EQ(again.stats.blocks.exchange_bytes_received(), b.exchange_bytes_received()) << what;
    // With rotation: 6 rows per particle.
    std::vector<double> z_t(z.begin(), z.begin() + static_cast<std::ptrdiff_t>(3 * part.n));
    std::vector<double> z_r(z.begin() + static_cast<std::ptrdiff_t>(3 * part.n), z.end()), w_t(z_t.size()),
        w_r(z_t.size());
    InnerProductStats rotation;
    const SqrtReport r = rpyfmm::mpi::sqrt_apply_rotation(
        op, z_t, z_r, w_t, w_r, block_sampler(SqrtMethod::lanczos, static_cast<int>(kBlock)), rotation);
    // The inner products of the call with InnerProductStats&: the start and three exchanges per
    // Lanczos step with reorthogonalization (rpyfmm/mpi/sqrt.hpp, InnerProductStats).
    EXPECT_EQ(rotation.exchanges, 1 + 3 * static_cast<long long>(r.iterations)) << what;
    EXPECT_EQ(rotation.blocks.apply_g.applications, r.operator_applications) << what;
    EXPECT_EQ(rotation.blocks.solve_g.bytes_received, 8 * 6 * (m.sent + m.received)) << what;
    EXPECT_EQ(rotation.blocks.apply_g.bytes_received,
              8 * 6 * (m.sent + m.received) * static_cast<std::uint64_t>(r.vector_products))
        << what;
  }
}

TEST(MpiDistributedSqrtBlockCache, FmmOperatorKeepsItsBlocksUntilSetPositions) {
  // The same on DistributedFmmRpy: a second sample with the kept blocks is the first bit for bit
  // (the operator's product is deterministic for one partition), and set_positions drops them.
  const Particles p = clustered_particles(90, 30, 74);
  const Partition part = partition_of(p.size(), Split::geometric);
  const WholeSet set(p, 19, 1);
  const std::vector<double> z = share(set.z, 3, part.offset, part.n);
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-6});
  place(op, p, part);
  const SqrtOptions options = block_sampler(SqrtMethod::lanczos, 8);
  const Sample first = sample(op, z, options);
  expect_built(first.stats.blocks, on_rank("first sample"));
  const Sample second = sample(op, z, options);
  EXPECT_EQ(bitwise_mismatches(second.w, first.w), 0u) << on_rank("second sample");
  expect_reused(second.stats.blocks, on_rank("second sample"));
  place(op, p, part);
  const Sample after = sample(op, z, options);
  EXPECT_EQ(bitwise_mismatches(after.w, first.w), 0u) << on_rank("after set_positions");
  expect_built(after.stats.blocks, on_rank("after set_positions"));
}
