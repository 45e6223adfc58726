// rpyfmm::mpi::DistributedFmmRpy::communication(): the bookkeeping of its exchanges (docs/mpi.md,
// "Distributed FmmRpy"). Bytes are checked exactly against what the exchanges must carry (owned
// and halo particle counts, the Laplace FMM's own statistics); seconds only where an exchange
// certainly runs (> 0), as sums of their parts (floating-point addition is monotone, so a sum of
// non-negative terms is at least any sub-sum taken in the same order) and as the exact running sum
// over the products since set_positions.
#include <gtest/gtest.h>
#include <mpi.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/sqrt.hpp"

using rpyfmm::mpi::DistributedFmmRpy;
using rpyfmm::mpi::FmmRpyCommunication;
using namespace rpyfmm_mpi_test;

namespace {

constexpr std::uint64_t kDouble = sizeof(double);

double total(const rpyfmm::StageTimes& times) {
  double sum = 0.0;
  for (const auto& [stage, seconds] : times) sum += seconds;
  return sum;
}

std::uint64_t sum_over_ranks(std::uint64_t mine) {
  std::uint64_t all = 0;
  MPI_Allreduce(&mine, &all, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  return all;
}

// The statistics of a product whose near field moves `blocks` blocks of 3 doubles per particle back
// to the input ranks (nrhs; 3 with torques: U from the forces, U from the torques, W): the near
// field's bytes are this rank's particles' blocks (its own share of the partition's move counted,
// as SfcPartition counts it); the totals add the Laplace FMM's evaluation, which carries the halo
// particles' loads among its essential charges.
void expect_product_counted(const DistributedFmmRpy& op, std::uint64_t blocks) {
  const FmmRpyCommunication& s = op.communication();
  const auto& far = op.laplace().communication();
  EXPECT_EQ(s.near_apply_bytes_received, op.local_size() * 3 * blocks * kDouble);
  EXPECT_EQ(s.apply_bytes_received, far.evaluate_bytes_received + s.near_apply_bytes_received);
  EXPECT_GT(s.near_apply_seconds, 0.0);
  EXPECT_GE(s.apply_seconds, total(far.evaluate_seconds) + s.near_apply_seconds);
  // The near sums' local work: on a rank that owns particles (its RPY blocks and self terms).
  if (op.laplace().owned_size() > 0) {
    EXPECT_GT(s.near_sums_seconds, 0.0);
  }
}

}  // namespace

TEST(MpiDistributedFmmRpyCommunication, NearFieldExchangesCountedInSetPositionsAndEveryProduct) {
  // 150 pairs overlapping at 0.6 (a_i + a_j), partners on different input ranks; radii 0.5 ... 1.5,
  // so the radii travel to the owners and the halo once per set_positions.
  const Particles p = pairs_at(150, 20.0, 0.6, 91);
  const Partition part = partition_of(p.size(), Split::even);
  const std::vector<double> x = share(p.x, 3, part.offset, part.n), a = share(p.a, 1, part.offset, part.n);
  const std::vector<double> f = share(p.f, 3, part.offset, part.n);
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-6});
  EXPECT_EQ(op.communication().set_positions_seconds, 0.0);
  op.set_positions(x, a);
  ASSERT_FALSE(op.equal_radii());
  const std::uint64_t halo = sum_over_ranks(op.halo_size());
  // On one rank nothing comes from another rank; on more, particles of every owner's region lie
  // within reach of its neighbours' (radii >= 0.5 in a cube of side 20 cut into adjacent regions).
  if (world_size() == 1) {
    EXPECT_EQ(halo, 0u);
  } else {
    ASSERT_GT(halo, 0u);
  }
  EXPECT_EQ(op.halo_size(), op.laplace().communication().halo_received);

  // The radii: one double per owned particle (its own share included) and per halo particle.
  const FmmRpyCommunication& s = op.communication();
  EXPECT_EQ(s.near_set_positions_bytes_received, (op.laplace().owned_size() + op.halo_size()) * kDouble);
  EXPECT_GT(s.near_set_positions_seconds, 0.0);
  EXPECT_GE(s.set_positions_seconds, total(op.laplace().communication().plan_seconds) + s.near_set_positions_seconds);
  EXPECT_EQ(s.apply_seconds, 0.0);
  EXPECT_EQ(s.applies_seconds, 0.0);
  EXPECT_EQ(s.apply_bytes_received, 0u);
  EXPECT_EQ(s.near_sums_seconds, 0.0);

  // Three kinds of product: their MPI seconds summed in order, exactly as the operator sums them.
  std::vector<double> u(f.size()), block(2 * f.size()), us(block.size()), t(f.size(), 0.5), w(f.size());
  for (std::size_t i = 0; i < f.size(); ++i) block[i] = block[f.size() + i] = f[i];
  double sum = 0.0;
  op.apply(f, u);
  expect_product_counted(op, 1);
  sum += s.apply_seconds;
  EXPECT_EQ(s.applies_seconds, sum);
  op.apply_block(block, us, 2);
  expect_product_counted(op, 2);
  sum += s.apply_seconds;
  EXPECT_EQ(s.applies_seconds, sum);
  op.apply(f, t, u, w);
  expect_product_counted(op, 3);
  sum += s.apply_seconds;
  EXPECT_EQ(s.applies_seconds, sum);
  EXPECT_GE(s.applies_seconds, s.apply_seconds);
  if (world_rank() == 0) {
    std::printf(
        "[fmm-rpy-stats] P=%d rank 0: set_positions %.2e s (near %.2e s), last apply %.2e s "
        "(near %.2e s), %llu bytes (near %llu), halo %zu, 3 applies %.2e s\n",
        world_size(), s.set_positions_seconds, s.near_set_positions_seconds, s.apply_seconds, s.near_apply_seconds,
        static_cast<unsigned long long>(s.apply_bytes_received),
        static_cast<unsigned long long>(s.near_apply_bytes_received), op.halo_size(), s.applies_seconds);
  }

  // A product refused on every rank (forces of the wrong size) leaves the statistics as they were.
  const FmmRpyCommunication before = s;
  const std::vector<double> short_f(f.size() + 3, 1.0);
  EXPECT_THROW(op.apply(short_f, u), rpyfmm::Error);
  EXPECT_EQ(s.applies_seconds, before.applies_seconds);
  EXPECT_EQ(s.apply_bytes_received, before.apply_bytes_received);

  // A new configuration starts the sums again.
  op.set_positions(x, a);
  EXPECT_GT(s.set_positions_seconds, 0.0);
  EXPECT_EQ(s.apply_seconds, 0.0);
  EXPECT_EQ(s.applies_seconds, 0.0);
  EXPECT_EQ(s.near_apply_bytes_received, 0u);
}

TEST(MpiDistributedFmmRpyCommunication, NoRadiiExchangedWithEqualRadii) {
  // Radius 0.5 on a lattice of spacing 2: with equal radii every particle's radius is known, so
  // set_positions exchanges none, and the product's bytes are the Laplace FMM's and the velocities back.
  Particles p;
  for (int i = 0; i < 216; ++i) {
    for (int v : {i % 6, (i / 6) % 6, i / 36}) p.x.push_back(2.0 * v);
    p.a.push_back(0.5);
    for (int c = 0; c < 3; ++c) p.f.push_back(std::cos(3.0 * i + c));
  }
  const Partition part = partition_of(p.size(), Split::even);
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-6});
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  ASSERT_TRUE(op.equal_radii());
  const FmmRpyCommunication& s = op.communication();
  EXPECT_EQ(s.near_set_positions_seconds, 0.0);
  EXPECT_EQ(s.near_set_positions_bytes_received, 0u);
  std::vector<double> u(3 * part.n);
  op.apply(share(p.f, 3, part.offset, part.n), u);
  expect_product_counted(op, 1);
  EXPECT_GT(s.apply_seconds, 0.0);
  EXPECT_EQ(s.applies_seconds, s.apply_seconds);
}

TEST(MpiDistributedFmmRpyCommunication, SamplerProductsSummed) {
  // mpi::sqrt_apply calls apply once per Lanczos step: the sum over its products is at least the
  // last one, and positive (every product runs the Laplace FMM's exchanges).
  const Particles p = pairs_at(60, 12.0, 0.6, 17);
  const Partition part = partition_of(p.size(), Split::even);
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-6});
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  std::vector<double> z(3 * part.n), w(z.size());
  rpyfmm::mpi::fill_normal(z, part.offset, 5, 0);
  rpyfmm::rpy::SqrtOptions options;
  options.tolerance = 1e-4;
  const rpyfmm::rpy::SqrtReport report = rpyfmm::mpi::sqrt_apply(op, z, w, options);
  ASSERT_GE(report.operator_applications, 2);
  const FmmRpyCommunication& s = op.communication();
  EXPECT_GT(s.apply_seconds, 0.0);
  EXPECT_GE(s.applies_seconds, s.apply_seconds);
}
