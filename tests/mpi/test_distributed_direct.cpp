// rpyfmm::mpi::DistributedDirectRpy against the serial DirectRpy on the concatenation of all ranks'
// particles: bit for bit on uniform, strongly clustered and extreme-scale inputs, with equal and
// different radii, empty ranks and more ranks than particles; and collective failure (every rank
// throws the same message, none hangs) on bad input of one rank. The grand mobility with rotation
// against DirectRpy's bit for bit on the same partitions, and the symmetry of the 6N matrix it
// assembles.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

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

enum class Radii { common, per_particle };

// The whole set on the serial operator and this rank's share (offset, n) on the distributed one;
// with Radii::common every rank passes p.a[0].
void set_positions(const Particles& p, Radii radii, std::size_t offset, std::size_t n, DirectRpy& serial,
                   DistributedDirectRpy& op) {
  if (radii == Radii::common) {
    serial.set_positions(p.x, p.a[0]);
    op.set_positions(share(p.x, 3, offset, n), p.a[0]);
  } else {
    serial.set_positions(p.x, p.a);
    op.set_positions(share(p.x, 3, offset, n), share(p.a, 1, offset, n));
  }
}

// Distributes `p` by `split`, applies M on the shares and compares each rank's velocities with the
// serial operator's on the whole set, bit for bit. With Radii::common every rank passes p.a[0].
void expect_equal_to_serial(const Particles& p, Split split, Radii radii) {
  const auto rank = static_cast<std::size_t>(world_rank());
  const std::vector<std::size_t> counts = split_counts(p.size(), static_cast<std::size_t>(world_size()), split);
  std::size_t offset = 0;
  for (std::size_t r = 0; r < rank; ++r) offset += counts[r];
  const std::size_t n = counts[rank];

  DirectRpy serial(Geometry::open(), kViscosity);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  set_positions(p, radii, offset, n, serial, op);
  std::vector<double> u_serial(3 * p.size());
  serial.apply(p.f, u_serial);

  EXPECT_EQ(op.global_size(), p.size());
  EXPECT_EQ(op.local_size(), n);
  EXPECT_EQ(op.offset(), offset);
  ASSERT_EQ(op.counts().size(), counts.size());
  for (std::size_t r = 0; r < counts.size(); ++r) EXPECT_EQ(op.counts()[r], counts[r]) << "rank " << r;
  std::vector<double> u(3 * n, std::numeric_limits<double>::quiet_NaN());
  op.apply(share(p.f, 3, offset, n), u);
  EXPECT_EQ(bitwise_mismatches(u, share(u_serial, 3, offset, n)), 0u) << "rank " << rank << " of " << world_size();
}

}  // namespace

TEST(MpiDistributedDirect, UniformEqualRadiiEqualsSerialBitForBit) {
  // 700 particles: more than two of DirectRpy's source blocks (256).
  const Particles p = uniform_particles(700, 40.0, 1.0, 1.0, 11);
  for (Split s : kSplits) expect_equal_to_serial(p, s, Radii::common);
  for (Split s : kSplits) expect_equal_to_serial(p, s, Radii::per_particle);  // all equal: the equal-radii path
}

TEST(MpiDistributedDirect, UniformDifferentRadiiEqualsSerialBitForBit) {
  const Particles p = uniform_particles(531, 25.0, 0.3, 1.7, 12);
  for (Split s : kSplits) expect_equal_to_serial(p, s, Radii::per_particle);
}

TEST(MpiDistributedDirect, StronglyClusteredEqualsSerialBitForBit) {
  // 400 overlapping spheres (partial overlap, one inside another, a coincident pair) and 60 far
  // ones: with last_only / geometric the cluster lies on one rank's share.
  const Particles p = clustered_particles(400, 60, 13);
  for (Split s : kSplits) expect_equal_to_serial(p, s, Radii::per_particle);
}

TEST(MpiDistributedDirect, ExtremeLengthScalesEqualSerialBitForBit) {
  // Extent 1e137 and radii 1e135: DirectRpy evaluates in units of a power of two chosen from all
  // particles, which every rank sees after the gather.
  Particles p = uniform_particles(300, 1.0, 0.002, 0.004, 14);
  for (double& x : p.x) x *= 1e137;
  for (double& a : p.a) a *= 1e137;
  for (Split s : kSplits) expect_equal_to_serial(p, s, Radii::per_particle);
  // Forces near 1e300: the product is evaluated on forces scaled by the largest of all ranks.
  Particles q = uniform_particles(300, 30.0, 1.0, 1.0, 15);
  for (double& f : q.f) f *= 1e300;
  for (Split s : kSplits) expect_equal_to_serial(q, s, Radii::common);
}

TEST(MpiDistributedDirect, EveryKernelLevelEqualsSerialBitForBit) {
  // 1100 particles: the shares start and end inside DirectRpy's source blocks of 256, which the
  // operator completes across ranks; each instruction-set level's kernels on every rank.
  const Particles p = uniform_particles(1100, 50.0, 0.4, 1.6, 16);
  const Particles q = uniform_particles(900, 40.0, 1.0, 1.0, 17);
  for (rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
    const rpyfmm::ScopedSimdLevel scoped(level);
    for (Split s : kSplits) expect_equal_to_serial(p, s, Radii::per_particle);
    for (Split s : kSplits) expect_equal_to_serial(q, s, Radii::common);
  }
}

TEST(MpiDistributedDirect, CoincidentParticlesOnDifferentRanksEqualSerialBitForBit) {
  // Particle i + 150 sits on particle i (r = 0: the self-term limit with equal radii, one sphere
  // inside the other with different radii); with the even split the partners lie on different ranks.
  Particles p = uniform_particles(300, 12.0, 0.5, 1.5, 18);
  for (std::size_t i = 0; i < 150; ++i)
    for (std::size_t d = 0; d < 3; ++d) p.x[3 * (i + 150) + d] = p.x[3 * i + d];
  for (Split s : kSplits) expect_equal_to_serial(p, s, Radii::per_particle);
  for (Split s : kSplits) expect_equal_to_serial(p, s, Radii::common);
}

TEST(MpiDistributedDirect, EachRankReceivesEveryOtherShareOnce) {
  // The source blocks pass once per product: 7 doubles per particle of the other ranks (positions,
  // radius, force), and nothing is gathered in set_positions beyond counts and summaries.
  const Particles p = uniform_particles(333, 20.0, 0.5, 1.5, 19);
  const auto rank = static_cast<std::size_t>(world_rank());
  const std::vector<std::size_t> counts =
      split_counts(p.size(), static_cast<std::size_t>(world_size()), Split::geometric);
  std::size_t offset = 0;
  for (std::size_t r = 0; r < rank; ++r) offset += counts[r];
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(share(p.x, 3, offset, counts[rank]), share(p.a, 1, offset, counts[rank]));
  std::vector<double> u(3 * counts[rank]);
  op.apply(share(p.f, 3, offset, counts[rank]), u);
  EXPECT_EQ(op.communication().apply_bytes_received, 7 * sizeof(double) * (p.size() - counts[rank]));
  EXPECT_GE(op.communication().apply_seconds, 0.0);
  EXPECT_GE(op.communication().set_positions_seconds, 0.0);
}

TEST(MpiDistributedDirect, MoreRanksThanParticles) {
  for (std::size_t n : {1, 2, 3}) {
    const Particles p = uniform_particles(n, 3.0, 0.8, 1.2, 20 + n);
    for (Split s : kSplits) expect_equal_to_serial(p, s, Radii::per_particle);
  }
}

TEST(MpiDistributedDirect, DifferentCommonRadiusPerRankEqualsSerialWithPerParticleRadii) {
  Particles p = uniform_particles(257, 20.0, 1.0, 1.0, 30);
  const std::vector<std::size_t> counts = split_counts(p.size(), static_cast<std::size_t>(world_size()), Split::even);
  std::size_t i = 0;
  for (std::size_t r = 0; r < counts.size(); ++r)
    for (std::size_t k = 0; k < counts[r]; ++k) p.a[i++] = 1.0 + 0.25 * static_cast<double>(r);
  DirectRpy serial(Geometry::open(), kViscosity);
  serial.set_positions(p.x, p.a);
  std::vector<double> u_serial(3 * p.size());
  serial.apply(p.f, u_serial);

  const auto rank = static_cast<std::size_t>(world_rank());
  std::size_t offset = 0;
  for (std::size_t r = 0; r < rank; ++r) offset += counts[r];
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(share(p.x, 3, offset, counts[rank]), 1.0 + 0.25 * static_cast<double>(rank));
  std::vector<double> u(3 * counts[rank]);
  op.apply(share(p.f, 3, offset, counts[rank]), u);
  EXPECT_EQ(bitwise_mismatches(u, share(u_serial, 3, offset, counts[rank])), 0u);
}

TEST(MpiDistributedDirect, RepeatedProductsAndNewPositions) {
  const Particles p = uniform_particles(200, 15.0, 0.5, 1.0, 40);
  const Particles q = clustered_particles(90, 10, 41);
  // One operator, several configurations and right-hand sides: each product as on a fresh one.
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  for (const auto& [particles, split] : {std::pair{&p, Split::even}, std::pair{&q, Split::geometric}}) {
    const std::vector<std::size_t> counts =
        split_counts(particles->size(), static_cast<std::size_t>(world_size()), split);
    const auto rank = static_cast<std::size_t>(world_rank());
    std::size_t offset = 0;
    for (std::size_t r = 0; r < rank; ++r) offset += counts[r];
    const std::size_t n = counts[rank];
    op.set_positions(share(particles->x, 3, offset, n), share(particles->a, 1, offset, n));
    DirectRpy serial(Geometry::open(), kViscosity);
    serial.set_positions(particles->x, particles->a);
    for (double scale : {1.0, -3.0}) {
      std::vector<double> f = particles->f;
      for (double& v : f) v *= scale;
      std::vector<double> u_serial(f.size()), u(3 * n);
      serial.apply(f, u_serial);
      op.apply(share(f, 3, offset, n), u);
      EXPECT_EQ(bitwise_mismatches(u, share(u_serial, 3, offset, n)), 0u);
    }
  }
}

// ------------------------------------------------------------------------------- rotation ---

namespace {

// Torques in [-scale, scale], one set for one seed on every rank.
std::vector<double> random_torques(std::size_t n, double scale, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-scale, scale);
  std::vector<double> t(3 * n);
  for (double& v : t) v = u(rng);
  return t;
}

// [U; W] of the shares split by `split` against DirectRpy's on the whole set, bit for bit: the
// rotational sums go over DirectRpy's source blocks of 256 counted from global particle 0, whole
// where a block straddles two ranks' shares, as the translational ones (direct_operator.hpp).
void expect_rotation_equal_to_serial(const Particles& p, const std::vector<double>& t, Split split, Radii radii) {
  const auto rank = static_cast<std::size_t>(world_rank());
  const auto [offset, n] = partition_of(p.size(), split);
  DirectRpy serial(Geometry::open(), kViscosity);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  set_positions(p, radii, offset, n, serial, op);
  ASSERT_TRUE(op.supports_rotation());
  std::vector<double> u_serial(3 * p.size()), w_serial(3 * p.size());
  serial.apply(p.f, t, u_serial, w_serial);
  std::vector<double> u(3 * n, std::numeric_limits<double>::quiet_NaN()), w = u;
  op.apply(share(p.f, 3, offset, n), share(t, 3, offset, n), u, w);

  EXPECT_EQ(bitwise_mismatches(u, share(u_serial, 3, offset, n)), 0u) << "rank " << rank << " of " << world_size();
  EXPECT_EQ(bitwise_mismatches(w, share(w_serial, 3, offset, n)), 0u) << "rank " << rank << " of " << world_size();
}

}  // namespace

TEST(MpiDistributedDirect, RotationEqualRadiiEqualsSerialBitForBit) {
  // 700 particles: more than two of DirectRpy's source blocks; touching and overlapping pairs
  // (r <= 2a) among them.
  const Particles p = uniform_particles(700, 25.0, 1.0, 1.0, 60);
  const std::vector<double> t = random_torques(p.size(), 1.0, 61);
  for (Split s : kSplits) expect_rotation_equal_to_serial(p, t, s, Radii::common);
  for (Split s : kSplits) expect_rotation_equal_to_serial(p, t, s, Radii::per_particle);
}

TEST(MpiDistributedDirect, RotationDifferentRadiiEqualsSerialBitForBit) {
  const Particles p = uniform_particles(531, 20.0, 0.3, 1.7, 62);
  for (Split s : kSplits) expect_rotation_equal_to_serial(p, random_torques(p.size(), 1.0, 63), s, Radii::per_particle);
  // Partial overlaps, spheres inside others and a coincident pair, with far ones on other ranks.
  const Particles q = clustered_particles(400, 60, 64);
  for (Split s : kSplits) expect_rotation_equal_to_serial(q, random_torques(q.size(), 2.0, 65), s, Radii::per_particle);
}

TEST(MpiDistributedDirect, RotationCoincidentParticlesOnDifferentRanksEqualSerialBitForBit) {
  // Particle i + 150 sits on particle i: the r = 0 limits (h = 1 / (8 pi max(a)^3), no coupling),
  // with the even split across ranks.
  Particles p = uniform_particles(300, 12.0, 0.5, 1.5, 66);
  for (std::size_t i = 0; i < 150; ++i)
    for (std::size_t d = 0; d < 3; ++d) p.x[3 * (i + 150) + d] = p.x[3 * i + d];
  const std::vector<double> t = random_torques(p.size(), 1.0, 67);
  for (Split s : kSplits) expect_rotation_equal_to_serial(p, t, s, Radii::per_particle);
  for (Split s : kSplits) expect_rotation_equal_to_serial(p, t, s, Radii::common);
}

TEST(MpiDistributedDirect, RotationEveryKernelLevelEqualsSerialBitForBit) {
  const Particles p = uniform_particles(600, 20.0, 0.4, 1.6, 68);
  const std::vector<double> t = random_torques(p.size(), 1.0, 69);
  for (rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
    const rpyfmm::ScopedSimdLevel scoped(level);
    for (Split s : kSplits) expect_rotation_equal_to_serial(p, t, s, Radii::per_particle);
    for (Split s : kSplits) expect_rotation_equal_to_serial(p, t, s, Radii::common);
  }
}

TEST(MpiDistributedDirect, RotationLoadScaledAndMoreRanksThanParticles) {
  // Torques near 1e300 against forces of order one: the load scale of MobilityOperator::apply
  // from the largest force and torque of all ranks.
  const Particles p = uniform_particles(300, 20.0, 0.5, 1.5, 70);
  for (Split s : kSplits)
    expect_rotation_equal_to_serial(p, random_torques(p.size(), 1e300, 71), s, Radii::per_particle);
  for (std::size_t n : {1, 2, 3}) {
    const Particles q = uniform_particles(n, 3.0, 0.8, 1.2, 72 + n);
    for (Split s : kSplits) expect_rotation_equal_to_serial(q, random_torques(n, 1.0, 75 + n), s, Radii::per_particle);
  }
}

TEST(MpiDistributedDirect, RotationRepeatedProductsBitForBit) {
  const Particles p = uniform_particles(300, 15.0, 0.5, 1.0, 80);
  const Particles q = clustered_particles(90, 10, 81);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  for (const auto& [particles, split] : {std::pair{&p, Split::even}, std::pair{&q, Split::geometric}}) {
    const Partition part = partition_of(particles->size(), split);
    const std::vector<double> t = random_torques(particles->size(), 1.0, 82);
    const std::vector<double> f = share(particles->f, 3, part.offset, part.n), tl = share(t, 3, part.offset, part.n);
    op.set_positions(share(particles->x, 3, part.offset, part.n), share(particles->a, 1, part.offset, part.n));
    std::vector<double> u1(3 * part.n), w1(3 * part.n), u2(3 * part.n), w2(3 * part.n);
    op.apply(f, tl, u1, w1);
    op.apply(f, tl, u2, w2);
    EXPECT_EQ(bitwise_mismatches(u1, u2), 0u);
    EXPECT_EQ(bitwise_mismatches(w1, w2), 0u);
    // The blocks of the same shares on a fresh operator: the same bits again.
    DistributedDirectRpy fresh(MPI_COMM_WORLD, kViscosity);
    fresh.set_positions(share(particles->x, 3, part.offset, part.n), share(particles->a, 1, part.offset, part.n));
    fresh.apply(f, tl, u2, w2);
    EXPECT_EQ(bitwise_mismatches(u1, u2), 0u);
    EXPECT_EQ(bitwise_mismatches(w1, w2), 0u);
  }
}

TEST(MpiDistributedDirect, RotationLeavesTheTranslationalProductUnchanged) {
  const Particles p = uniform_particles(400, 15.0, 0.5, 1.5, 85);
  const Partition part = partition_of(p.size(), Split::even);
  DirectRpy serial(Geometry::open(), kViscosity);
  serial.set_positions(p.x, p.a);
  std::vector<double> u_serial(3 * p.size());
  serial.apply(p.f, u_serial);
  const std::vector<double> u_ref = share(u_serial, 3, part.offset, part.n);

  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  const std::vector<double> f = share(p.f, 3, part.offset, part.n);
  std::vector<double> u(3 * part.n), w(3 * part.n);
  op.apply(f, share(random_torques(p.size(), 1.0, 86), 3, part.offset, part.n), u, w);
  // U = M F after a product with torques: DirectRpy's bits, as before.
  op.apply(f, u);
  EXPECT_EQ(bitwise_mismatches(u, u_ref), 0u);
  // With zero torques the velocities are the translational product's: the rotational terms of U
  // are all zero (c_ut (0 x e)), the load scale is the forces' alone.
  std::vector<double> u_rotation(3 * part.n);
  op.apply(f, std::vector<double>(3 * part.n, 0.0), u_rotation, w);
  EXPECT_EQ(bitwise_mismatches(u_rotation, u_ref), 0u);
}

TEST(MpiDistributedDirect, RotationGrandMatrixIsSymmetric) {
  // The 6N x 6N matrix [[M_tt, M_tr]; [M_rt, M_rr]] assembled column by column from the
  // distributed products on unit loads, rows gathered from every rank: symmetric (the grand
  // mobility is, Wajnryb et al. 2013; docs/theory/rpy.md section 7). Each entry is one pair term
  // (the other sources' loads are zero), evaluated for (i, j) and (j, i) by the same formulas with
  // the factors multiplied in other orders (e.g. (k e_b) e_c against (k e_c) e_b) and, in the
  // rotational blocks, h + k e_b e_c summed: within 64 eps of the largest entry of the pair's 3 x 3
  // blocks. A wrong sign or a swapped coupling (c_ut against c_wf, which differ for different radii)
  // breaks the symmetry by the size of the entry.
  const Particles p = clustered_particles(24, 6, 90);  // overlapping, inside, coincident; far ones
  const std::size_t n_total = p.size(), rows = 6 * n_total;
  const Partition part = partition_of(n_total, Split::geometric);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  std::vector<int> counts3, displs3;
  for (std::size_t c : op.counts()) {
    displs3.push_back(counts3.empty() ? 0 : displs3.back() + counts3.back());
    counts3.push_back(static_cast<int>(3 * c));
  }
  std::vector<double> matrix(rows * rows);  // row-major, [U (3N); W (3N)] by [F (3N); T (3N)]
  std::vector<double> f(3 * part.n), t(3 * part.n), u(3 * part.n), w(3 * part.n), column(rows);
  for (std::size_t col = 0; col < rows; ++col) {
    std::fill(f.begin(), f.end(), 0.0);
    std::fill(t.begin(), t.end(), 0.0);
    const std::size_t entry = col % (3 * n_total);  // of F or T
    if (entry >= 3 * part.offset && entry < 3 * (part.offset + part.n))
      (col < 3 * n_total ? f : t)[entry - 3 * part.offset] = 1.0;
    op.apply(f, t, u, w);
    MPI_Allgatherv(u.data(), static_cast<int>(u.size()), MPI_DOUBLE, column.data(), counts3.data(), displs3.data(),
                   MPI_DOUBLE, MPI_COMM_WORLD);
    MPI_Allgatherv(w.data(), static_cast<int>(w.size()), MPI_DOUBLE, column.data() + 3 * n_total, counts3.data(),
                   displs3.data(), MPI_DOUBLE, MPI_COMM_WORLD);
    for (std::size_t row = 0; row < rows; ++row) matrix[row * rows + col] = column[row];
  }
  // The largest entry of the 3 x 3 block holding (row, col) and of its transposed block.
  const auto block_scale = [&](std::size_t row, std::size_t col) {
    double largest = 0.0;
    for (std::size_t a = 0; a < 3; ++a)
      for (std::size_t b = 0; b < 3; ++b) {
        const std::size_t r = row - row % 3 + a, c = col - col % 3 + b;
        largest = std::max({largest, std::abs(matrix[r * rows + c]), std::abs(matrix[c * rows + r])});
      }
    return largest;
  };
  const double eps = std::numeric_limits<double>::epsilon();
  std::size_t asymmetric = 0, nonzero = 0;
  for (std::size_t row = 0; row < rows; ++row)
    for (std::size_t col = row + 1; col < rows; ++col) {
      const double a = matrix[row * rows + col], b = matrix[col * rows + row];
      nonzero += a != 0.0 ? 1 : 0;
      if (std::abs(a - b) > 64.0 * eps * block_scale(row, col)) {
        if (asymmetric++ < 5)
          ADD_FAILURE() << "entry (" << row << ", " << col << ") = " << a << ", (" << col << ", " << row << ") = " << b;
      }
    }
  EXPECT_EQ(asymmetric, 0u);
  // Not vacuous: the couplings between translation and rotation are there.
  EXPECT_GT(nonzero, rows * rows / 4);
  double coupling = 0.0;
  for (std::size_t row = 0; row < 3 * n_total; ++row)
    for (std::size_t col = 3 * n_total; col < rows; ++col)
      coupling = std::max(coupling, std::abs(matrix[row * rows + col]));
  EXPECT_GT(coupling, 0.0);
}

// ----------------------------------------------------------------------- collective errors ---

namespace {

// This rank's share of a small uniform set, split evenly.
struct Share {
  std::vector<double> x, a, f;
};

Share even_share(std::size_t n_total) {
  const Particles p = uniform_particles(n_total, 10.0, 1.0, 1.0, 50);
  const std::vector<std::size_t> counts = split_counts(n_total, static_cast<std::size_t>(world_size()), Split::even);
  const auto rank = static_cast<std::size_t>(world_rank());
  std::size_t offset = 0;
  for (std::size_t r = 0; r < rank; ++r) offset += counts[r];
  return {share(p.x, 3, offset, counts[rank]), share(p.a, 1, offset, counts[rank]),
          share(p.f, 3, offset, counts[rank])};
}

std::string rank_of(int r) {
  return "rank " + std::to_string(r) + " of " + std::to_string(world_size()) + ": ";
}

}  // namespace

TEST(MpiDistributedDirect, NanPositionOnOneRankFailsEveryRankThenRecovers) {
  const int last = world_size() - 1;
  Share s = even_share(40);  // every rank has at least 10
  Share bad = s;
  if (world_rank() == last) bad.x[3 * 2 + 1] = std::numeric_limits<double>::quiet_NaN();
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  expect_collective_error([&] { op.set_positions(bad.x, bad.a); }, ErrorCode::invalid_input,
                          rank_of(last) + "DistributedDirectRpy::set_positions: local positions entry (2, 1) is NaN");
  EXPECT_EQ(op.global_size(), 0u);
  std::vector<double> u(s.f.size());
  expect_collective_error([&] { op.apply(s.f, u); }, ErrorCode::invalid_input, "positions not set");
  // The ranks are in step: good input now succeeds everywhere.
  op.set_positions(s.x, s.a);
  EXPECT_EQ(op.global_size(), 40u);
  EXPECT_NO_THROW(op.apply(s.f, u));
  // A NaN on a rank that holds positions already set: the old positions are dropped everywhere.
  expect_collective_error([&] { op.set_positions(bad.x, 1.0); }, ErrorCode::invalid_input, "is NaN");
  EXPECT_EQ(op.global_size(), 0u);
}

TEST(MpiDistributedDirect, BadForcesOnOneRankFailEveryRank) {
  Share s = even_share(40);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(s.x, s.a);
  std::vector<double> u(s.f.size());
  std::vector<double> f = s.f;
  if (world_rank() == 0) f[4] = std::numeric_limits<double>::infinity();
  expect_collective_error([&] { op.apply(f, u); }, ErrorCode::invalid_input,
                          rank_of(0) + "DistributedDirectRpy::apply: local forces entry (1, 1) is infinite");
  EXPECT_NO_THROW(op.apply(s.f, u));
}

TEST(MpiDistributedDirect, NanForceOnLastRankFailsEveryRank) {
  const int last = world_size() - 1;
  Share s = even_share(40);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(s.x, s.a);
  std::vector<double> u(s.f.size());
  std::vector<double> f = s.f;
  if (world_rank() == last) f[3 * 3 + 2] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { op.apply(f, u); }, ErrorCode::invalid_input,
                          rank_of(last) + "DistributedDirectRpy::apply: local forces entry (3, 2) is NaN");
  EXPECT_NO_THROW(op.apply(s.f, u));
}

TEST(MpiDistributedDirect, WrongSizesOnOneRankFailEveryRank) {
  const int last = world_size() - 1;
  Share s = even_share(40);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  // Positions not a multiple of 3.
  std::vector<double> x = s.x;
  if (world_rank() == last) x.push_back(1.0);
  // (the count in the message is the last rank's, so every rank's message names it)
  const std::string message =
      expect_collective_error([&] { op.set_positions(x, 1.0); }, ErrorCode::invalid_input,
                              rank_of(last) + "DistributedDirectRpy::set_positions: local positions have ");
  EXPECT_NE(message.find(" entries, not a multiple of 3"), std::string::npos) << message;
  // Radii of the wrong count.
  std::vector<double> a = s.a;
  if (world_rank() == 0) a.pop_back();
  expect_collective_error([&] { op.set_positions(s.x, a); }, ErrorCode::invalid_input,
                          rank_of(0) + "DistributedDirectRpy::set_positions: local radii has");
  // A radius that is not > 0, one common radius and one per particle.
  expect_collective_error([&] { op.set_positions(s.x, world_rank() == last ? -1.0 : 1.0); },
                          ErrorCode::invalid_argument, rank_of(last) + "DistributedDirectRpy::set_positions: radius");
  a = s.a;
  if (world_rank() == last) a[1] = 0.0;
  expect_collective_error([&] { op.set_positions(s.x, a); }, ErrorCode::invalid_argument,
                          rank_of(last) + "DistributedDirectRpy::set_positions: radius of local particle 1");
  // Forces and velocities of the wrong size.
  op.set_positions(s.x, s.a);
  std::vector<double> f = s.f, u(s.f.size());
  if (world_rank() == last) f.resize(f.size() - 3);
  expect_collective_error([&] { op.apply(f, u); }, ErrorCode::invalid_input,
                          rank_of(last) + "DistributedDirectRpy::apply: local forces has");
  std::vector<double> u_wrong(world_rank() == 0 ? 0 : s.f.size());
  expect_collective_error([&] { op.apply(s.f, u_wrong); }, ErrorCode::invalid_input,
                          rank_of(0) + "DistributedDirectRpy::apply: local velocities has");
  EXPECT_NO_THROW(op.apply(s.f, u));
}

TEST(MpiDistributedDirect, NoParticlesAnywhereFailsEveryRank) {
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  expect_collective_error([&] { op.set_positions(std::vector<double>{}, 1.0); }, ErrorCode::invalid_input,
                          "no particles on any of the " + std::to_string(world_size()) + " ranks");
}

TEST(MpiDistributedDirect, BadOrDifferentViscosityFailsEveryRank) {
  const int last = world_size() - 1;
  expect_collective_error([&] { DistributedDirectRpy op(MPI_COMM_WORLD, world_rank() == last ? std::nan("") : 1.0); },
                          ErrorCode::invalid_argument,
                          rank_of(last) + "DistributedDirectRpy: viscosity must be finite and > 0");
  if (world_size() > 1) {
    expect_collective_error([&] { DistributedDirectRpy op(MPI_COMM_WORLD, 1.0 + world_rank()); },
                            ErrorCode::invalid_argument, "the ranks pass different viscosities");
  }
}

TEST(MpiDistributedDirect, TooSmallRadiusOfTheGatheredSetFailsEveryRank) {
  // Valid on each rank, refused by DirectRpy for the gathered set (a radius below 2^-300 of the
  // suspension's size): every rank reports the same problem.
  Share s = even_share(40);
  if (world_rank() == 0) s.a[0] = 1e-300;
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  expect_collective_error([&] { op.set_positions(s.x, s.a); }, ErrorCode::invalid_input, "DirectRpy::set_positions");
  EXPECT_EQ(op.global_size(), 0u);
}

TEST(MpiDistributedDirect, TooSmallRadiusIsNamedByItsGlobalIndex) {
  // On the last rank's second particle: every rank names it by its index in the whole set, as the
  // serial operator does.
  const int last = world_size() - 1;
  Share s = even_share(40);
  const std::vector<std::size_t> counts = split_counts(40, static_cast<std::size_t>(world_size()), Split::even);
  std::size_t offset_last = 0;
  for (std::size_t r = 0; r + 1 < counts.size(); ++r) offset_last += counts[r];
  if (world_rank() == last) s.a[1] = 1e-300;
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  expect_collective_error([&] { op.set_positions(s.x, s.a); }, ErrorCode::invalid_input,
                          rank_of(last) + "DistributedDirectRpy::set_positions: radius of particle " +
                              std::to_string(offset_last + 1) + " (1e-300) is below 2^-300");
}

TEST(MpiDistributedDirect, RotationBadTorquesOnOneRankFailEveryRank) {
  const int last = world_size() - 1;
  Share s = even_share(40);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  std::vector<double> u(s.f.size()), w(s.f.size()), t(s.f.size(), 0.5);
  expect_collective_error([&] { op.apply(s.f, t, u, w); }, ErrorCode::invalid_input,
                          "DistributedDirectRpy::apply: positions not set");
  op.set_positions(s.x, s.a);
  std::vector<double> bad = t;
  if (world_rank() == last) bad[3 * 1 + 2] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { op.apply(s.f, bad, u, w); }, ErrorCode::invalid_input,
                          rank_of(last) + "DistributedDirectRpy::apply: local torques entry (1, 2) is NaN");
  bad = t;
  if (world_rank() == 0) bad[0] = -std::numeric_limits<double>::infinity();
  expect_collective_error([&] { op.apply(s.f, bad, u, w); }, ErrorCode::invalid_input,
                          rank_of(0) + "DistributedDirectRpy::apply: local torques entry (0, 0) is infinite");
  // NaN forces are refused by the product with rotation as by the translational one.
  std::vector<double> f = s.f;
  if (world_rank() == last) f[5] = std::numeric_limits<double>::quiet_NaN();
  expect_collective_error([&] { op.apply(f, t, u, w); }, ErrorCode::invalid_input,
                          rank_of(last) + "DistributedDirectRpy::apply: local forces entry (1, 2) is NaN");
  EXPECT_NO_THROW(op.apply(s.f, t, u, w));
}

TEST(MpiDistributedDirect, RotationWrongSizesOnOneRankFailEveryRank) {
  const int last = world_size() - 1;
  Share s = even_share(40);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(s.x, s.a);
  std::vector<double> u(s.f.size()), w(s.f.size()), t(s.f.size(), 0.5);
  std::vector<double> t_wrong = t;
  if (world_rank() == last) t_wrong.push_back(1.0);
  expect_collective_error([&] { op.apply(s.f, t_wrong, u, w); }, ErrorCode::invalid_input,
                          rank_of(last) + "DistributedDirectRpy::apply: local torques has");
  std::vector<double> w_wrong(world_rank() == 0 ? 3 : w.size());
  expect_collective_error([&] { op.apply(s.f, t, u, w_wrong); }, ErrorCode::invalid_input,
                          rank_of(0) + "DistributedDirectRpy::apply: local angular velocities has");
  std::vector<double> u_wrong(world_rank() == last ? 0 : u.size());
  expect_collective_error([&] { op.apply(s.f, t, u_wrong, w); }, ErrorCode::invalid_input,
                          rank_of(last) + "DistributedDirectRpy::apply: local velocities has");
  EXPECT_NO_THROW(op.apply(s.f, t, u, w));
}

TEST(MpiDistributedDirect, RotationProductBeyondDoublePrecisionFailsEveryRank) {
  // Radii of 1e-105 (a suspension of side 1e-104): W ~ T / (8 pi eta a^3) ~ 1e313 for torques of
  // order one, beyond double precision. DirectRpy refuses it; so does every rank here.
  Share s = even_share(40);
  for (double& x : s.x) x *= 1e-105;
  for (double& a : s.a) a *= 1e-105;
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(s.x, s.a);
  std::vector<double> u(s.f.size()), w(s.f.size()), t(s.f.size(), 1.0);
  expect_collective_error([&] { op.apply(s.f, t, u, w); }, ErrorCode::numerical_failure,
                          "DistributedDirectRpy::apply: angular velocities entry (0, 0) is infinite");
}
