// rpyfmm::mpi::DistributedDirectRpy::apply_block: nrhs right-hand sides in one pass of the source
// blocks. Each right-hand side against two independent products, bit for bit: the distributed
// apply of it alone, and the rank's share of the serial DirectRpy::apply_block on the whole set
// (whose right-hand sides equal DirectRpy::apply of each, checked here too); for every split,
// equal and different radii, overlapping and coincident spheres, every instruction-set level; the
// traffic of one pass; and collective failure on bad input of one rank.
#include <gtest/gtest.h>
#include <mpi.h>

#include <climits>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "block_test_support.hpp"
#include "mpi_test_support.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "simd_levels.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::DistributedDirectRpy;
using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::Geometry;
using namespace rpyfmm_mpi_test;

namespace {

// Distributes `p` by `split` (per-particle radii) and checks apply_block with nrhs right-hand sides
// on every rank: each right-hand side bit for bit equal to the distributed apply of it alone and to
// the rank's share of DirectRpy::apply_block on the whole set; and the serial block's right-hand
// sides bit for bit equal to DirectRpy::apply of each.
void expect_block_equal(const Particles& p, Split split, std::size_t nrhs, std::uint64_t seed) {
  const Partition part = partition_of(p.size(), split);
  const std::size_t n3 = 3 * p.size(), m3 = 3 * part.n;
  const std::vector<double> f = block_forces(p, nrhs, seed);

  DirectRpy serial(Geometry::open(), kViscosity);
  serial.set_positions(p.x, p.a);
  std::vector<double> serial_block(n3 * nrhs);
  serial.apply_block(f, serial_block, nrhs);

  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  const std::vector<double> mine = block_share(f, nrhs, part);
  std::vector<double> u(m3 * nrhs, std::numeric_limits<double>::quiet_NaN());
  op.apply_block(mine, u, nrhs);

  const std::vector<double> serial_mine = block_share(serial_block, nrhs, part);
  for (std::size_t k = 0; k < nrhs; ++k) {
    const std::string where = "rhs " + std::to_string(k) + " of " + std::to_string(nrhs) + ", rank " +
                              std::to_string(world_rank()) + " of " + std::to_string(world_size());
    std::vector<double> single(m3, std::numeric_limits<double>::quiet_NaN());
    op.apply(column_of(mine, m3, k), single);
    EXPECT_EQ(bitwise_mismatches(column_of(u, m3, k), single), 0u) << "distributed single apply, " << where;
    EXPECT_EQ(bitwise_mismatches(column_of(u, m3, k), column_of(serial_mine, m3, k)), 0u)
        << "DirectRpy::apply_block, " << where;
    std::vector<double> serial_single(n3);
    serial.apply(column_of(f, n3, k), serial_single);
    EXPECT_EQ(bitwise_mismatches(column_of(serial_block, n3, k), serial_single), 0u)
        << "DirectRpy::apply_block against DirectRpy::apply, rhs " << k;
  }
}

}  // namespace

TEST(MpiDistributedDirectBlock, EqualRadiiEqualsSingleAndSerialBitForBit) {
  // 700 particles: more than two of DirectRpy's source blocks (256).
  const Particles p = uniform_particles(700, 40.0, 1.0, 1.0, 71);
  for (Split s : kSplits)
    for (std::size_t nrhs : {1u, 2u, 4u}) expect_block_equal(p, s, nrhs, 72);
}

TEST(MpiDistributedDirectBlock, DifferentRadiiAndOverlapsEqualSingleAndSerialBitForBit) {
  const Particles uniform = uniform_particles(531, 25.0, 0.3, 1.7, 73);
  // 400 overlapping spheres (partial overlap, one inside another, a coincident pair), 60 far ones.
  const Particles clustered = clustered_particles(400, 60, 74);
  for (Split s : kSplits) {
    expect_block_equal(uniform, s, 3, 75);
    expect_block_equal(clustered, s, 5, 76);
  }
}

TEST(MpiDistributedDirectBlock, CoincidentParticlesOnDifferentRanksEqualSerialBitForBit) {
  // Particle i + 150 sits on particle i: with the even split the partners lie on different ranks.
  Particles p = uniform_particles(300, 12.0, 0.5, 1.5, 77);
  for (std::size_t i = 0; i < 150; ++i)
    for (std::size_t d = 0; d < 3; ++d) p.x[3 * (i + 150) + d] = p.x[3 * i + d];
  for (Split s : kSplits) expect_block_equal(p, s, 3, 78);
}

TEST(MpiDistributedDirectBlock, EveryKernelLevelEqualsSerialBitForBit) {
  // 1100 particles: shares start and end inside DirectRpy's source blocks of 256.
  const Particles p = uniform_particles(1100, 50.0, 0.4, 1.6, 79);
  const Particles q = uniform_particles(900, 40.0, 1.0, 1.0, 80);
  for (rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
    const rpyfmm::ScopedSimdLevel scoped(level);
    for (Split s : kSplits) {
      expect_block_equal(p, s, 3, 81);
      expect_block_equal(q, s, 2, 82);
    }
  }
}

TEST(MpiDistributedDirectBlock, EachRightHandSideLoadScaledByItself) {
  // Right-hand sides near 1e300, 1 and 1e-300: each is scaled by its own largest force (of all
  // ranks), so each equals the distributed apply of it alone, DirectRpy::apply of it and
  // DirectRpy::apply_block's right-hand side (which scales each by itself too), bit for bit. One
  // power of two for the whole block would scale the 1e-300 right-hand side by about 2^-997 and
  // underflow its velocities to 0.
  const Particles p = uniform_particles(500, 30.0, 0.5, 1.5, 83);
  const std::size_t n3 = 3 * p.size();
  std::vector<double> f;
  for (double s : {1e300, 1.0, 1e-300})
    for (double v : p.f) f.push_back(s * v);
  DirectRpy serial(Geometry::open(), kViscosity);
  serial.set_positions(p.x, p.a);
  std::vector<double> serial_block(3 * n3);
  serial.apply_block(f, serial_block, 3);
  for (Split split : kSplits) {
    const Partition part = partition_of(p.size(), split);
    const std::size_t m3 = 3 * part.n;
    DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
    op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
    const std::vector<double> mine = block_share(f, 3, part);
    std::vector<double> u(3 * m3);
    op.apply_block(mine, u, 3);
    for (std::size_t k = 0; k < 3; ++k) {
      std::vector<double> single(m3), serial_single(n3);
      op.apply(column_of(mine, m3, k), single);
      serial.apply(column_of(f, n3, k), serial_single);
      EXPECT_EQ(bitwise_mismatches(column_of(u, m3, k), single), 0u) << "rhs " << k << ", rank " << world_rank();
      EXPECT_EQ(bitwise_mismatches(column_of(u, m3, k), share(serial_single, 3, part.offset, part.n)), 0u)
          << "rhs " << k << ", rank " << world_rank();
      EXPECT_EQ(bitwise_mismatches(column_of(u, m3, k), share(column_of(serial_block, n3, k), 3, part.offset, part.n)),
                0u)
          << "serial block, rhs " << k << ", rank " << world_rank();
    }
  }
}

TEST(MpiDistributedDirectBlock, OnePassCarriesEveryRightHandSide) {
  // One broadcast per rank's block: 4 + 3 nrhs doubles per particle of the other ranks (positions,
  // radius, the forces of every right-hand side). Repeated block products agree bit for bit.
  const Particles p = uniform_particles(333, 20.0, 0.5, 1.5, 84);
  const Partition part = partition_of(p.size(), Split::geometric);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  const std::size_t nrhs = 4;
  const std::vector<double> f = block_share(block_forces(p, nrhs, 85), nrhs, part);
  std::vector<double> u(f.size()), again(f.size());
  op.apply_block(f, u, nrhs);
  EXPECT_EQ(op.communication().apply_bytes_received, (4 + 3 * nrhs) * sizeof(double) * (p.size() - part.n));
  op.apply_block(f, again, nrhs);
  EXPECT_EQ(bitwise_mismatches(u, again), 0u);
}

// ----------------------------------------------------------------------- collective errors ---

namespace {

std::string rank_of(int r) {
  return "rank " + std::to_string(r) + " of " + std::to_string(world_size()) + ": ";
}

}  // namespace

TEST(MpiDistributedDirectBlock, BadInputOnOneRankFailsEveryRank) {
  const Particles p = uniform_particles(40, 10.0, 1.0, 1.0, 86);  // every rank has at least 10
  const Partition part = partition_of(p.size(), Split::even);
  const std::size_t nrhs = 3;
  const std::vector<double> f = block_share(block_forces(p, nrhs, 87), nrhs, part);
  std::vector<double> u(f.size());
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  expect_collective_error([&] { op.apply_block(f, u, nrhs); }, ErrorCode::invalid_input,
                          "DistributedDirectRpy::apply_block: positions not set");
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  expect_block_refusals(op, f, u, nrhs, p.size(), "DistributedDirectRpy::apply_block: ");
}

TEST(MpiDistributedDirectBlock, BlockBeyondMpiIntCountsFailsEveryRank) {
  // A rank's source block of (4 + 3 nrhs) x (largest share) doubles must fit one int count: the
  // largest nrhs that fits passes this check (and fails on the sizes of the empty arrays here),
  // one more is refused as not supported, on every rank, before any array is read.
  const Particles p = uniform_particles(40, 10.0, 1.0, 1.0, 88);
  const Partition part = partition_of(p.size(), Split::last_only);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  const std::size_t most = (static_cast<std::size_t>(INT_MAX) / p.size() - 4) / 3;
  std::vector<double> none;
  expect_collective_error([&] { op.apply_block(none, none, most + 1); }, ErrorCode::not_supported,
                          "DistributedDirectRpy::apply_block: " + std::to_string(most + 1) +
                              " right-hand sides: a source block of a rank holding 40 particles would carry more "
                              "doubles than MPI's int counts address (2147483647); at most " +
                              std::to_string(most) + " right-hand sides per call here");
  const int last = world_size() - 1;
  expect_collective_error([&] { op.apply_block(none, none, most); }, ErrorCode::invalid_input,
                          rank_of(last) + "DistributedDirectRpy::apply_block: local forces has 0");
}
