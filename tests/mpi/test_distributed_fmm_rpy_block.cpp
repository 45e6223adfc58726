// rpyfmm::mpi::DistributedFmmRpy::apply_block: nrhs right-hand sides in one Laplace evaluation.
// Each right-hand side against the exact product of the serial rpy::DirectRpy on the whole set
// (relative l2 error over all particles at most the tolerance, 1e-3, 1e-6 and 1e-9) and against the
// distributed apply of it alone; right-hand sides of very different loads; threads; and collective
// failure on bad input of one rank.
#include <gtest/gtest.h>
#include <mpi.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "block_test_support.hpp"
#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::DistributedFmmRpy;
using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::Geometry;
using namespace rpyfmm_mpi_test;

namespace {

constexpr double kTolerances[] = {1e-3, 1e-6, 1e-9};
// Leaves of 24 points, as in test_distributed_fmm_rpy.cpp: most pairs in the far field.
constexpr int kLeaf = 24;

// Distributes `p` by `split`, applies apply_block to the block `f` (nrhs vectors of the whole set)
// at `tolerance` and checks every right-hand side on every rank: its error against DirectRpy's
// exact product of it is at most the tolerance, and it equals the distributed apply of it alone bit
// for bit. Rank 0 prints the errors. Returns this rank's share of the block product.
std::vector<double> expect_block_contract(const Particles& p, const std::vector<double>& f, std::size_t nrhs,
                                          Split split, double tolerance, const char* label) {
  const Partition part = partition_of(p.size(), split);
  const std::size_t n3 = 3 * p.size(), m3 = 3 * part.n;
  DirectRpy direct(Geometry::open(), kViscosity);
  direct.set_positions(p.x, p.a);
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = tolerance, .leaf_capacity = kLeaf});
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  const std::vector<double> mine = block_share(f, nrhs, part);
  std::vector<double> u(m3 * nrhs, std::numeric_limits<double>::quiet_NaN());
  op.apply_block(mine, u, nrhs);
  for (std::size_t k = 0; k < nrhs; ++k) {
    // DirectRpy::apply of each right-hand side: its apply_block shares one load scale over the
    // block (see EachRightHandSideLoadScaledByItself).
    std::vector<double> exact(n3), single(m3, std::numeric_limits<double>::quiet_NaN());
    direct.apply(column_of(f, n3, k), exact);
    op.apply(column_of(mine, m3, k), single);
    const std::vector<double> uk = column_of(u, m3, k);
    const double error = global_relative_error(uk, share(exact, 3, part.offset, part.n));
    EXPECT_LE(error, tolerance) << label << ", rhs " << k << " of " << nrhs;
    EXPECT_EQ(bitwise_mismatches(uk, single), 0u)
        << label << ", rhs " << k << " of " << nrhs << " against apply, rank " << world_rank();
    if (world_rank() == 0) {
      std::printf("[fmm-rpy-block] %-18s P=%d eps=%.0e rhs %zu/%zu: error vs DirectRpy %.2e\n", label, world_size(),
                  tolerance, k, nrhs, error);
    }
  }
  return u;
}

}  // namespace

TEST(MpiDistributedFmmRpyBlock, UniformEqualRadiiWithinToleranceAndEqualToSingle) {
  // Equal radii (four densities per right-hand side), a few overlapping pairs.
  const Particles p = uniform_particles(600, 30.0, 1.0, 1.0, 91);
  const std::vector<double> f = block_forces(p, 3, 92);
  for (double eps : kTolerances) {
    expect_block_contract(p, f, 3, Split::even, eps, "uniform, even");
    expect_block_contract(p, f, 3, Split::first_empty, eps, "uniform, first empty");
  }
}

TEST(MpiDistributedFmmRpyBlock, ClusteredDifferentRadiiWithinToleranceAndEqualToSingle) {
  // Seven densities per right-hand side; overlapping pairs (one inside another, a coincident pair)
  // whose partners lie on different ranks, corrected with one halo exchange for the block.
  const Particles p = clustered_particles(300, 60, 93);
  const std::vector<double> f = block_forces(p, 4, 94);
  for (double eps : kTolerances) {
    expect_block_contract(p, f, 4, Split::even, eps, "clustered, even");
    expect_block_contract(p, f, 4, Split::last_only, eps, "clustered, last only");
  }
}

TEST(MpiDistributedFmmRpyBlock, EachRightHandSideLoadScaledByItself) {
  // Right-hand sides near 1e300, 1 and 1e-300: each scaled by its own largest force of all ranks,
  // so each is within the tolerance of DirectRpy::apply of it and equal to the apply of it alone.
  const Particles p = uniform_particles(400, 25.0, 0.5, 1.5, 95);
  std::vector<double> f;
  for (double s : {1e300, 1.0, 1e-300})
    for (double v : p.f) f.push_back(s * v);
  expect_block_contract(p, f, 3, Split::geometric, 1e-6, "loads 1e300..1e-300");
}

TEST(MpiDistributedFmmRpyBlock, ResultsIndependentOfThreadCount) {
  const Particles p = clustered_particles(200, 40, 96);
  const std::vector<double> f = block_forces(p, 2, 97);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const std::vector<double> one = expect_block_contract(p, f, 2, Split::even, 1e-6, "1 thread");
  omp_set_num_threads(3);
  const std::vector<double> three = expect_block_contract(p, f, 2, Split::even, 1e-6, "3 threads");
  omp_set_num_threads(saved);
  EXPECT_EQ(bitwise_mismatches(one, three), 0u);
}

// ----------------------------------------------------------------------- collective errors ---

TEST(MpiDistributedFmmRpyBlock, BadInputOnOneRankFailsEveryRank) {
  const Particles p = uniform_particles(40, 10.0, 1.0, 1.0, 98);  // every rank has at least 10
  const Partition part = partition_of(p.size(), Split::even);
  const std::size_t nrhs = 3;
  const std::vector<double> f = block_share(block_forces(p, nrhs, 99), nrhs, part);
  std::vector<double> u(f.size());
  DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-6});
  const std::string where = "rpyfmm::mpi::DistributedFmmRpy::apply_block: ";
  expect_collective_error([&] { op.apply_block(f, u, nrhs); }, ErrorCode::invalid_input, where + "positions not set");
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  expect_block_refusals(op, f, u, nrhs, p.size(), where);
}
