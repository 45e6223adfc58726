// rpyfmm::mpi::sqrt_apply and rpyfmm::mpi::fill_normal: the noise of each rank's share against the
// serial rpy::fill_normal (bit for bit), the distributed Lanczos square root against the serial
// Lanczos sampler on DirectRpy (bit for bit) and the dense principal square root (the serial
// contract), the covariance of its samples against the dense mobility matrix, and collective
// failure.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::DistributedDirectRpy;
using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::SqrtMethod;
using rpyfmm::rpy::SqrtOptions;
using rpyfmm::rpy::SqrtPreconditioner;
using namespace rpyfmm_mpi_test;

namespace {

SqrtOptions lanczos(double tolerance) {
  SqrtOptions o;
  o.method = SqrtMethod::lanczos;
  o.preconditioner = SqrtPreconditioner::none;
  o.tolerance = tolerance;
  return o;
}

double relative_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0.0, s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) d += (a[i] - b[i]) * (a[i] - b[i]), s += b[i] * b[i];
  return std::sqrt(d / s);
}

// The whole vector from every rank's share (in rank order), on every rank.
std::vector<double> all_gather(const std::vector<double>& local) {
  const int ranks = world_size();
  int mine = static_cast<int>(local.size());
  std::vector<int> counts(static_cast<std::size_t>(ranks)), displs(static_cast<std::size_t>(ranks));
  MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  int total = 0;
  for (int r = 0; r < ranks; ++r)
    displs[static_cast<std::size_t>(r)] = total, total += counts[static_cast<std::size_t>(r)];
  std::vector<double> all(static_cast<std::size_t>(total));
  MPI_Allgatherv(local.data(), mine, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, MPI_COMM_WORLD);
  return all;
}

}  // namespace

TEST(MpiDistributedSqrt, NoiseOfEachShareIsTheSerialNoiseBitForBit) {
  // A particle's noise depends on (seed, step, stream, global index) only.
  constexpr std::size_t kN = 1003;
  for (std::uint32_t stream : {0u, 5u}) {
    std::vector<double> serial(3 * kN);
    rpyfmm::rpy::fill_normal(serial, 42, 17, stream);
    for (Split s : kSplits) {
      const Partition part = partition_of(kN, s);
      std::vector<double> z(3 * part.n);
      rpyfmm::mpi::fill_normal(z, part.offset, 42, 17, stream);
      EXPECT_EQ(bitwise_mismatches(z, share(serial, 3, part.offset, part.n)), 0u) << "stream " << stream;
    }
  }
}

namespace {

// The distributed sampler on `p` split by every split, against the serial sampler's w_serial bit
// for bit (every inner product is the serial one: krylov_space.hpp), with the same number of
// iterations, and the same bits again on a second call. Returns the last split's gathered w.
std::vector<double> expect_serial_lanczos(const Particles& p, const std::vector<double>& z,
                                          const std::vector<double>& w_serial, int serial_iterations,
                                          double tolerance) {
  std::vector<double> w_all;
  for (Split s : kSplits) {
    const Partition part = partition_of(p.size(), s);
    DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
    op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
    std::vector<double> w(3 * part.n);
    const rpyfmm::rpy::SqrtReport report =
        rpyfmm::mpi::sqrt_apply(op, share(z, 3, part.offset, part.n), w, lanczos(tolerance));
    EXPECT_EQ(report.iterations, serial_iterations) << "tolerance " << tolerance;
    EXPECT_TRUE(report.converged);
    EXPECT_EQ(bitwise_mismatches(w, share(w_serial, 3, part.offset, part.n)), 0u)
        << "tolerance " << tolerance << ", rank " << world_rank() << " of " << world_size();
    std::vector<double> again(w.size());
    rpyfmm::mpi::sqrt_apply(op, share(z, 3, part.offset, part.n), again, lanczos(tolerance));
    EXPECT_EQ(bitwise_mismatches(again, w), 0u);
    w_all = all_gather(w);
  }
  return w_all;
}

}  // namespace

TEST(MpiDistributedSqrt, LanczosEqualsSerialLanczosBitForBitAndDenseRootToTolerance) {
  // 200 clustered particles, 600 entries: one reduction chunk, whose sum passes through every
  // rank. Against the dense principal root (an independent reference) the serial contract holds:
  // within 10 x the tolerance (rpy/sqrt.hpp).
  const Particles p = clustered_particles(170, 30, 61);
  DirectRpy serial(Geometry::open(), kViscosity);
  serial.set_positions(p.x, p.a);
  std::vector<double> z(3 * p.size());
  rpyfmm::rpy::fill_normal(z, 7, 3);
  SqrtOptions dense;
  dense.method = SqrtMethod::eigen;
  std::vector<double> w_dense(z.size());
  serial.apply_sqrt(z, w_dense, dense);
  for (double tolerance : {1e-3, 1e-6}) {
    std::vector<double> w_serial(z.size());
    const rpyfmm::rpy::SqrtReport report = serial.apply_sqrt(z, w_serial, lanczos(tolerance));
    const std::vector<double> w = expect_serial_lanczos(p, z, w_serial, report.iterations, tolerance);
    EXPECT_LT(relative_difference(w, w_dense), 10.0 * tolerance) << "tolerance " << tolerance;
  }
}

TEST(MpiDistributedSqrt, LanczosOverSeveralReductionChunksEqualsSerialBitForBit) {
  // 1500 particles, 4500 entries: two reduction chunks of the serial inner products (4096 and
  // 404 entries), the first ending inside a rank's share for most splits.
  const Particles p = uniform_particles(1500, 60.0, 0.5, 1.5, 63);
  DirectRpy serial(Geometry::open(), kViscosity);
  serial.set_positions(p.x, p.a);
  std::vector<double> z(3 * p.size()), w_serial(z.size());
  rpyfmm::rpy::fill_normal(z, 8, 1);
  const rpyfmm::rpy::SqrtReport report = serial.apply_sqrt(z, w_serial, lanczos(1e-3));
  expect_serial_lanczos(p, z, w_serial, report.iterations, 1e-3);
}

TEST(MpiDistributedSqrt, SampleCovarianceMatchesTheMobilityMatrix) {
  // Four overlapping and nearby spheres with different radii, 1500 samples w = M^{1/2} z with
  // the noise of steps 0..1499: the sample covariance C = <w w^T> estimates M, each entry with
  // standard error sqrt((M_ii M_jj + M_ij^2) / S) (Wick's theorem for Gaussian w). Every entry
  // must lie within 5 standard errors (for the 78 distinct entries a false failure has
  // probability ~5e-5; the samples are fixed by the seed, so the outcome is reproducible).
  const std::vector<double> x = {0.0, 0.0, 0.0, 1.5, 0.2, 0.0, 0.3, 2.1, 0.4, 4.0, 1.0, -1.0};
  const std::vector<double> a = {1.0, 0.8, 1.2, 0.9};
  constexpr std::size_t kN = 4, kDim = 3 * kN, kSamples = 1500;
  DirectRpy serial(Geometry::open(), kViscosity);
  serial.set_positions(x, a);
  std::vector<double> m(kDim * kDim), e(kDim, 0.0), col(kDim);
  for (std::size_t j = 0; j < kDim; ++j) {  // M column by column
    std::fill(e.begin(), e.end(), 0.0);
    e[j] = 1.0;
    serial.apply(e, col);
    for (std::size_t i = 0; i < kDim; ++i) m[i * kDim + j] = col[i];
  }
  const Partition part = partition_of(kN, Split::geometric);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(share(x, 3, part.offset, part.n), share(a, 1, part.offset, part.n));
  std::vector<double> c(kDim * kDim, 0.0), z(3 * part.n), w(3 * part.n);
  for (std::size_t k = 0; k < kSamples; ++k) {
    rpyfmm::mpi::fill_normal(z, part.offset, 2024, k);
    rpyfmm::mpi::sqrt_apply(op, z, w, lanczos(1e-8));
    const std::vector<double> w_all = all_gather(w);
    for (std::size_t i = 0; i < kDim; ++i)
      for (std::size_t j = 0; j < kDim; ++j) c[i * kDim + j] += w_all[i] * w_all[j];
  }
  for (std::size_t i = 0; i < kDim; ++i) {
    for (std::size_t j = 0; j < kDim; ++j) {
      const double mean = c[i * kDim + j] / static_cast<double>(kSamples);
      const double mij = m[i * kDim + j];
      const double se = std::sqrt((m[i * kDim + i] * m[j * kDim + j] + mij * mij) / static_cast<double>(kSamples));
      EXPECT_LT(std::abs(mean - mij), 5.0 * se) << "entry (" << i << ", " << j << ")";
    }
  }
}

TEST(MpiDistributedSqrt, BadInputOnOneRankFailsEveryRank) {
  const int last = world_size() - 1;
  const Particles p = uniform_particles(40, 10.0, 1.0, 1.0, 62);
  const Partition part = partition_of(p.size(), Split::even);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(share(p.x, 3, part.offset, part.n), 1.0);
  std::vector<double> z(3 * part.n, 1.0), w(3 * part.n);
  std::vector<double> bad = z;
  if (world_rank() == last) bad[4] = std::numeric_limits<double>::quiet_NaN();
  const std::string prefix = "rank " + std::to_string(last) + " of " + std::to_string(world_size()) + ": ";
  expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, bad, w, lanczos(1e-3)); }, ErrorCode::invalid_input,
                          prefix + "rpyfmm::mpi::sqrt_apply: local noise entry (1, 1) is NaN");
  SqrtOptions chebyshev = lanczos(1e-3);
  if (world_rank() == last) chebyshev.method = SqrtMethod::chebyshev;
  expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, z, w, chebyshev); }, ErrorCode::not_supported,
                          prefix + "rpyfmm::mpi::sqrt_apply: method 'chebyshev' is not offered across ranks");
  if (world_size() > 1) {
    expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, z, w, lanczos(world_rank() == last ? 1e-4 : 1e-3)); },
                            ErrorCode::invalid_argument, "the ranks pass different options");
  }
  EXPECT_NO_THROW(rpyfmm::mpi::sqrt_apply(op, z, w, lanczos(1e-3)));
}
