// rpyfmm::mpi::sqrt_apply and rpyfmm::mpi::fill_normal: the noise of each rank's share against the
// serial rpy::fill_normal (bit for bit); the distributed Lanczos and Chebyshev square roots against
// the serial samplers on DirectRpy (bit for bit) and the dense principal square root (the serial
// contracts); the block preconditioner of the whole set's blocks against the serial preconditioned
// sampler (bit for bit, every split) and the dense root of G M G^T; the covariance of the
// samples against the dense mobility matrix; and collective failure. With rotation
// (sqrt_apply_rotation): the serial DirectRpy::apply_sqrt_rotation bit for bit on every partition,
// the dense scaled root S^{-1} (S M S)^{1/2} z of the grand mobility, the block-preconditioned
// sample against the serial one (bit for bit, every split) and a dense square root of M, the
// samplers on DistributedFmmRpy against the dense root, and collective failure. (The
// translational samplers on DistributedFmmRpy: test_distributed_fmm_rpy.cpp.)
#include <gtest/gtest.h>
#include <mpi.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "krylov_space.hpp"
#include "mpi_test_support.hpp"
#include "rpyfmm/bd/rotation_sampling.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "rpyfmm/rpy/sqrt.hpp"
#include "sqrt/detail.hpp"
#include "sqrt_test_support.hpp"
#include "sqrt_test_util.hpp"

using rpyfmm::ErrorCode;
using rpyfmm::mpi::DistributedDirectRpy;
using rpyfmm::rpy::BlockPreconditioner;
using rpyfmm::rpy::DirectRpy;
using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::SqrtMethod;
using rpyfmm::rpy::SqrtOptions;
using rpyfmm::rpy::SqrtPreconditioner;
using rpyfmm::rpy::SqrtReport;
using namespace rpyfmm_mpi_test;

namespace {

SqrtOptions lanczos(double tolerance) {
  return sampler(SqrtMethod::lanczos, SqrtPreconditioner::none, tolerance);
}

// The serial contracts against the dense principal root (tests/sqrt/test_sqrt_accuracy.cpp):
// Lanczos within 10 x its tolerance (its stopping test underestimates the error left: rpy/sqrt.hpp),
// Chebyshev within 1.5 x (its error bound holds when the estimated bounds enclose the spectrum).
double slack(SqrtMethod method) {
  return method == SqrtMethod::lanczos ? 10.0 : 1.5;
}

}  // namespace

TEST(MpiDistributedSqrt, NoiseOfEachShareIsTheSerialNoiseBitForBit) {
  // A particle's noise depends on (seed, step, stream, global index) only. Streams 0 and
  // bd::kRotationNoiseStream: the serial BD engine's z_t and z_r of a step with rotation.
  constexpr std::size_t kN = 1003;
  for (std::uint32_t stream : {0u, rpyfmm::bd::kRotationNoiseStream, 5u}) {
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
  const WholeSet set(p, 7, 3);
  const DirectRpy& serial = set.op;
  const std::vector<double>& z = set.z;
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
  const WholeSet set(p, 8, 1);
  std::vector<double> w_serial(set.z.size());
  const rpyfmm::rpy::SqrtReport report = set.op.apply_sqrt(set.z, w_serial, lanczos(1e-3));
  expect_serial_lanczos(p, set.z, w_serial, report.iterations, 1e-3);
}

namespace {

// The distributed sampler by `options` on DistributedDirectRpy with p split by `s`: this rank's
// share of w, and the report.
std::pair<std::vector<double>, SqrtReport> distributed_sample(const Particles& p, Split s, const std::vector<double>& z,
                                                              const SqrtOptions& options) {
  const Partition part = partition_of(p.size(), s);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
  std::vector<double> w(3 * part.n);
  const SqrtReport report = rpyfmm::mpi::sqrt_apply(op, share(z, 3, part.offset, part.n), w, options);
  return {w, report};
}

}  // namespace

TEST(MpiDistributedSqrt, ChebyshevEqualsSerialChebyshevBitForBitAndDenseRootToTolerance) {
  // The bound estimate's Lanczos steps sum their inner products in the serial order and the
  // recurrence is elementwise but for the products, so the distributed Chebyshev sampler is the
  // serial one bit for bit: the same bounds, degree and w. 200 clustered particles (one reduction
  // chunk, against the dense principal root as well) and 1500 uniform ones (two chunks).
  const Particles clustered = clustered_particles(170, 30, 61);
  const Particles uniform = uniform_particles(1500, 60.0, 0.5, 1.5, 63);
  for (const Particles* p : {&clustered, &uniform}) {
    const WholeSet set(*p, 9, 2);
    const DirectRpy& serial = set.op;
    const std::vector<double>& z = set.z;
    std::vector<double> w_dense;
    if (p == &clustered) {
      w_dense.resize(z.size());
      serial.apply_sqrt(z, w_dense, sampler(SqrtMethod::eigen, SqrtPreconditioner::none, 1e-3));
    }
    for (double tolerance : {1e-3, 1e-6}) {
      if (p == &uniform && tolerance < 1e-3) continue;  // degree 145 on 1500 particles: the chunks at 1e-3 suffice
      const SqrtOptions options = sampler(SqrtMethod::chebyshev, SqrtPreconditioner::none, tolerance);
      std::vector<double> w_serial(z.size());
      const SqrtReport expected = serial.apply_sqrt(z, w_serial, options);
      for (Split s : kSplits) {
        const Partition part = partition_of(p->size(), s);
        const auto [w, report] = distributed_sample(*p, s, z, options);
        EXPECT_EQ(report.iterations, expected.iterations);
        EXPECT_EQ(report.operator_applications, expected.operator_applications);
        EXPECT_EQ(report.lambda_min, expected.lambda_min);
        EXPECT_EQ(report.lambda_max, expected.lambda_max);
        EXPECT_EQ(bitwise_mismatches(w, share(w_serial, 3, part.offset, part.n)), 0u)
            << "N " << p->size() << ", tolerance " << tolerance << ", rank " << world_rank();
      }
      if (!w_dense.empty()) {
        EXPECT_LT(relative_difference(w_serial, w_dense), slack(SqrtMethod::chebyshev) * tolerance);
      }
    }
  }
}

namespace {

// G w: the root A^{1/2} z (A = G M G^T) that the samplers' tolerances refer to.
std::vector<double> whitened(const BlockPreconditioner& g, std::vector<double> w) {
  g.apply_g(w.data());
  return w;
}

}  // namespace

TEST(MpiDistributedSqrt, BlockPreconditionerIsTheSerialSamplerOnEveryPartition) {
  // The blocks are the serial BlockPreconditioner's of the whole set whatever the partition
  // (mpi/src/global_blocks.hpp; the geometric and even splits cut blocks between ranks), each
  // factored by one rank with the serial code and applied there in the serial entry order, and the
  // inner products are summed in the serial order: w is, bit for bit, the serial
  // DirectRpy::apply_sqrt's with the block preconditioner on every split (so the same w for every
  // split), with the serial iterations and number of blocks. Against the dense principal root of
  // A = G M G^T: the serial contract on A^{1/2} set.z.
  const Particles p = clustered_particles(170, 30, 61);
  const WholeSet set(p, 11, 4);
  constexpr double kTolerance = 1e-6;
  const BlockPreconditioner g(set.op);  // the automatic block size, as the samplers' 0
  std::vector<double> root(set.z.size());
  g.sample(set.op.as_linear_operator(), set.z, root, 1, sampler(SqrtMethod::eigen, SqrtPreconditioner::none, 1e-3));
  root = whitened(g, root);
  const SqrtMethod methods[2] = {SqrtMethod::lanczos, SqrtMethod::chebyshev};
  for (int k = 0; k < 2; ++k) {
    const SqrtOptions options = sampler(methods[k], SqrtPreconditioner::block, kTolerance);
    std::vector<double> w_whole(set.z.size());
    const SqrtReport serial = set.op.apply_sqrt(set.z, w_whole, options);
    ASSERT_EQ(serial.preconditioner_blocks, g.blocks());
    for (Split s : kSplits) {
      const Partition part = partition_of(p.size(), s);
      const auto [w, report] = distributed_sample(p, s, set.z, options);
      EXPECT_EQ(bitwise_mismatches(w, share(w_whole, 3, part.offset, part.n)), 0u)
          << rpyfmm::rpy::to_string(methods[k]) << ", split " << static_cast<int>(s) << ", rank " << world_rank()
          << " of " << world_size();
      EXPECT_EQ(report.preconditioner_blocks, serial.preconditioner_blocks);
      EXPECT_EQ(report.iterations, serial.iterations);
      EXPECT_EQ(report.operator_applications, serial.operator_applications);
      EXPECT_LT(relative_difference(whitened(g, all_gather(w)), root), slack(methods[k]) * kTolerance)
          << rpyfmm::rpy::to_string(methods[k]);
    }
  }
}

// At eta = 1e-20 and lengths scaled by 1e-20 (eta a = 1e-40 for unit radii; both within their
// documented ranges) the self mobilities, about 5e38, exceed single precision: the serial
// preconditioner factors its blocks times a power of two (rpy::block_scale_exponent over all
// radii). Every rank must use the same power, that of the whole set's radii, so the distributed
// sample is again the serial one bit for bit on every split (without it each rank's float blocks
// overflowed and the sampler stopped with "local output entry (0, 0) is infinite").
TEST(MpiDistributedSqrt, BlockPreconditionerAtExtremeViscosityTimesRadius) {
  constexpr double kScale = 1e-20;
  Particles p = clustered_particles(60, 20, 67);
  for (double& v : p.x) v *= kScale;
  for (double& v : p.a) v *= kScale;
  rpyfmm::rpy::DirectRpy whole(rpyfmm::rpy::Geometry::open(), kScale);
  whole.set_positions(p.x, p.a);
  std::vector<double> z(3 * p.size());
  rpyfmm::rpy::fill_normal(z, 11, 4);
  const SqrtOptions options = sampler(SqrtMethod::lanczos, SqrtPreconditioner::block, 1e-6);
  std::vector<double> w_whole(z.size());
  const SqrtReport serial = whole.apply_sqrt(z, w_whole, options);
  ASSERT_TRUE(serial.converged);
  ASSERT_GT(serial.preconditioner_blocks, 1u);
  for (Split s : kSplits) {
    const Partition part = partition_of(p.size(), s);
    rpyfmm::mpi::DistributedDirectRpy op(MPI_COMM_WORLD, kScale);
    place(op, p, part);
    std::vector<double> w(3 * part.n);
    const SqrtReport report = rpyfmm::mpi::sqrt_apply(op, share(z, 3, part.offset, part.n), w, options);
    EXPECT_EQ(bitwise_mismatches(w, share(w_whole, 3, part.offset, part.n)), 0u)
        << "split " << static_cast<int>(s) << ", rank " << world_rank() << " of " << world_size();
    EXPECT_EQ(report.iterations, serial.iterations);
  }
}

namespace {

// Four overlapping and nearby spheres with different radii split geometrically, 1500 samples w
// by `options` with the noise of steps 0..1499: the sample covariance C = <w w^T> estimates M,
// each entry with standard error sqrt((M_ii M_jj + M_ij^2) / S) (Wick's theorem for Gaussian w).
// Every entry must lie within 5 standard errors (for the 78 distinct entries a false failure has
// probability ~5e-5; the samples are fixed by the seed, so the outcome is reproducible).
void expect_covariance_of_mobility(const SqrtOptions& options) {
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
    rpyfmm::mpi::sqrt_apply(op, z, w, options);
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

}  // namespace

TEST(MpiDistributedSqrt, SampleCovarianceMatchesTheMobilityMatrix) {
  expect_covariance_of_mobility(lanczos(1e-8));
}

TEST(MpiDistributedSqrt, BlockPreconditionedSampleCovarianceMatchesTheMobilityMatrix) {
  // Blocks of at most 2 particles of the whole set (the geometric split puts them on different
  // ranks): w = L (L^{-1} M L^{-T})^{1/2} z, a square root of M other than the principal one, with
  // the covariance M all the same.
  SqrtOptions options = sampler(SqrtMethod::lanczos, SqrtPreconditioner::block, 1e-8);
  options.preconditioner_block = 2;
  expect_covariance_of_mobility(options);
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
  SqrtOptions dense = lanczos(1e-3);
  if (world_rank() == last) dense.method = SqrtMethod::eigen;
  expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, z, w, dense); }, ErrorCode::not_supported,
                          prefix + "rpyfmm::mpi::sqrt_apply: method 'eigen' is not offered across ranks");
  SqrtOptions bounds = sampler(SqrtMethod::chebyshev, SqrtPreconditioner::none, 1e-3);
  if (world_rank() == last) bounds.lambda_min = -1.0, bounds.lambda_max = 1.0;
  expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, z, w, bounds); }, ErrorCode::invalid_argument,
                          prefix + "rpyfmm::mpi::sqrt_apply: Chebyshev eigenvalue bounds must satisfy");
  SqrtOptions block = sampler(SqrtMethod::lanczos, SqrtPreconditioner::block, 1e-3);
  if (world_rank() == last) block.preconditioner_block = -1;
  expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, z, w, block); }, ErrorCode::invalid_argument,
                          prefix + "rpyfmm::mpi::sqrt_apply: preconditioner_block must be >= 0");
  if (world_size() > 1) {
    expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, z, w, lanczos(world_rank() == last ? 1e-4 : 1e-3)); },
                            ErrorCode::invalid_argument, "the ranks pass different options");
    SqrtOptions method = lanczos(1e-3), preconditioner = lanczos(1e-3);
    if (world_rank() == last) {
      method.method = SqrtMethod::chebyshev;
      preconditioner.preconditioner = SqrtPreconditioner::block;
    }
    for (const SqrtOptions& mixed : {method, preconditioner}) {
      expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, z, w, mixed); }, ErrorCode::invalid_argument,
                              "the ranks pass different options (method, preconditioner");
    }
  }
  EXPECT_NO_THROW(rpyfmm::mpi::sqrt_apply(op, z, w, lanczos(1e-3)));
}

// ------------------------------------------------------------------------------- rotation ---

namespace {

// A vector of n entries in [-1, 1), the same on every rank for one seed.
std::vector<double> random_vector(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> v(n);
  for (double& x : v) x = u(rng);
  return v;
}

// This rank's shares of the `segments` segments of v (3 counts[r] entries of rank r in each),
// one after another: the layout of DistributedKrylovSpace.
std::vector<double> segment_shares(const std::vector<double>& v, std::span<const std::size_t> counts,
                                   std::size_t segments) {
  const std::size_t length = v.size() / segments;
  std::size_t offset = 0;
  for (int r = 0; r < world_rank(); ++r) offset += 3 * counts[static_cast<std::size_t>(r)];
  const std::size_t mine = 3 * counts[static_cast<std::size_t>(world_rank())];
  std::vector<double> out;
  for (std::size_t s = 0; s < segments; ++s) {
    const auto first = v.begin() + static_cast<std::ptrdiff_t>(s * length + offset);
    out.insert(out.end(), first, first + static_cast<std::ptrdiff_t>(mine));
  }
  return out;
}

}  // namespace

TEST(MpiDistributedSqrt, GrandInnerProductsAreTheSerialOnesBitForBit) {
  // The distributed basis's dot and dots (mpi/src/krylov_space.hpp) against the serial kernels
  // (rpy/src/sqrt/kernels.cpp) on the whole vector, bit for bit, for the translations alone and
  // for [x_t; x_r], at every split. N = 1 and 4: one chunk through every share (twice with
  // rotation); 700: two chunks, the first straddling the halves; 3000 (18000 entries, 5 chunks):
  // with two ranks split evenly the chunks end on ranks 0, 1, 0, 1, 1, so the gathered chunk sums
  // come out of chunk order and must be added in it. Random vectors (most orders of a few chunk
  // sums round alike), and x_0 = 1 with y holding 1, -1 and 2^-60 at the starts of chunks 0, 1
  // and 2: chunk sums whose sum is 2^-60 in chunk order and 0 in the order (c0 + c2) + c1.
  for (std::size_t n : {std::size_t{1}, std::size_t{4}, std::size_t{700}, std::size_t{3000}}) {
    for (std::size_t segments : {std::size_t{1}, std::size_t{2}}) {
      const std::size_t length = 3 * n * segments;
      for (bool cancelling : {false, true}) {
        std::vector<double> y = random_vector(length, 7 * n + segments);
        std::vector<std::vector<double>> x;
        for (std::uint64_t q = 0; q < 3; ++q) x.push_back(random_vector(length, 1000 * q + n + segments));
        if (cancelling) {
          std::fill(x[0].begin(), x[0].end(), 1.0);
          std::fill(y.begin(), y.end(), 0.0);
          const double starts[] = {1.0, -1.0, std::ldexp(1.0, -60)};
          for (std::size_t c = 0; c < 3 && c * 4096 < length; ++c) y[c * 4096] = starts[c];
        }
        const double dot = rpyfmm::rpy::sqrt_detail::dot(x[0].data(), y.data(), length);
        std::vector<double> dots(3);
        rpyfmm::rpy::sqrt_detail::dots(x, y.data(), length, dots.data());
        for (Split s : kSplits) {
          const std::vector<std::size_t> counts = split_counts(n, static_cast<std::size_t>(world_size()), s);
          const rpyfmm::mpi::Communicator comm(MPI_COMM_WORLD);
          rpyfmm::mpi::DistributedKrylovSpace space(comm, counts, segments);
          ASSERT_EQ(space.n(), length);
          const std::vector<double> y_mine = segment_shares(y, counts, segments);
          for (const std::vector<double>& xq : x) {
            const std::vector<double> mine = segment_shares(xq, counts, segments);
            std::copy(mine.begin(), mine.end(), space.push());
          }
          const std::string what = "N " + std::to_string(n) + ", segments " + std::to_string(segments) +
                                   (cancelling ? ", cancelling" : ", random") + ", rank " +
                                   std::to_string(world_rank()) + " of " + std::to_string(world_size());
          const double d = space.dot(space.vector(0), y_mine.data());
          EXPECT_EQ(std::memcmp(&d, &dot, sizeof d), 0) << what << ": " << d << " vs " << dot;
          std::vector<double> h(3);
          space.dots(3, y_mine.data(), h.data());
          EXPECT_EQ(bitwise_mismatches(h, dots), 0u) << what;
        }
      }
    }
  }
}

namespace {

// The noise of a Brownian step with rotation on the whole set: z_t from stream 0 and z_r from the
// serial BD engine's rotational stream (bd/rotation_sampling.hpp), as a rank draws its shares by
// mpi::fill_normal (sqrt.hpp).
struct GrandVectors {
  std::vector<double> t, r;
};

GrandVectors grand_noise(std::size_t n, std::uint64_t seed, std::uint64_t step) {
  GrandVectors z{std::vector<double>(3 * n), std::vector<double>(3 * n)};
  rpyfmm::rpy::fill_normal(z.t, seed, step);
  rpyfmm::rpy::fill_normal(z.r, seed, step, rpyfmm::bd::kRotationNoiseStream);
  return z;
}

// The serial sampler with rotation on the whole set.
std::pair<GrandVectors, SqrtReport> serial_rotation(const DirectRpy& op, const GrandVectors& z,
                                                    const SqrtOptions& options) {
  GrandVectors w{std::vector<double>(z.t.size()), std::vector<double>(z.r.size())};
  const SqrtReport report = op.apply_sqrt_rotation(z.t, z.r, w.t, w.r, options);
  return {w, report};
}

// The distributed sampler with rotation on `op` (holding the particles of `part`): this rank's
// shares of w_t and w_r.
template <class Operator>
std::pair<GrandVectors, SqrtReport> distributed_rotation(const Operator& op, const Partition& part,
                                                         const GrandVectors& z, const SqrtOptions& options) {
  GrandVectors w{std::vector<double>(3 * part.n), std::vector<double>(3 * part.n)};
  const SqrtReport report = rpyfmm::mpi::sqrt_apply_rotation(op, share(z.t, 3, part.offset, part.n),
                                                             share(z.r, 3, part.offset, part.n), w.t, w.r, options);
  return {w, report};
}

// The distributed sampler with rotation on DistributedDirectRpy, `p` split by every split, against
// the serial DirectRpy::apply_sqrt_rotation on the whole set bit for bit: the same iterations,
// products, bounds and both halves of w, and the same bits again on a second call.
void expect_serial_rotation(const Particles& p, const SqrtOptions& options, std::uint64_t step) {
  DirectRpy serial(Geometry::open(), kViscosity);
  serial.set_positions(p.x, p.a);
  const GrandVectors z = grand_noise(p.size(), 5, step);
  const auto [expected, serial_report] = serial_rotation(serial, z, options);
  const std::string what = std::string(rpyfmm::rpy::to_string(options.method)) + ", N " + std::to_string(p.size()) +
                           ", tolerance " + std::to_string(options.tolerance) + ", rank " +
                           std::to_string(world_rank()) + " of " + std::to_string(world_size());
  for (Split s : kSplits) {
    const Partition part = partition_of(p.size(), s);
    DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
    place(op, p, part);
    const auto [w, report] = distributed_rotation(op, part, z, options);
    EXPECT_EQ(report.iterations, serial_report.iterations) << what;
    EXPECT_EQ(report.operator_applications, serial_report.operator_applications) << what;
    EXPECT_EQ(report.lambda_min, serial_report.lambda_min) << what;
    EXPECT_EQ(report.lambda_max, serial_report.lambda_max) << what;
    EXPECT_EQ(report.converged, serial_report.converged) << what;
    EXPECT_EQ(bitwise_mismatches(w.t, share(expected.t, 3, part.offset, part.n)), 0u) << what;
    EXPECT_EQ(bitwise_mismatches(w.r, share(expected.r, 3, part.offset, part.n)), 0u) << what;
    const auto [again, again_report] = distributed_rotation(op, part, z, options);
    EXPECT_EQ(bitwise_mismatches(again.t, w.t) + bitwise_mismatches(again.r, w.r), 0u) << what;
  }
}

// The particle sets of the bitwise tests, 6N entries in [x_t; x_r] against the reduction chunks of
// 4096: 200 clustered spheres of different radii, overlapping, one pair coincident, and 200 equal
// spheres (1200 entries: one chunk whose sum passes through every rank twice, translations then
// rotations); 700 equal spheres (4200 entries: the first chunk ends in the rotations, the
// translations' end inside it). More chunks, out of chunk order on the gather:
// GrandInnerProductsAreTheSerialOnesBitForBit.
std::vector<Particles> rotation_sets() {
  return {clustered_particles(170, 30, 61), uniform_particles(200, 25.0, 1.0, 1.0, 64),
          uniform_particles(700, 45.0, 1.0, 1.0, 65)};
}

}  // namespace

TEST(MpiDistributedSqrt, RotationLanczosEqualsSerialBitForBitOnEveryPartition) {
  for (const Particles& p : rotation_sets()) expect_serial_rotation(p, lanczos(1e-3), 1);
  expect_serial_rotation(clustered_particles(170, 30, 61), lanczos(1e-6), 2);
}

TEST(MpiDistributedSqrt, RotationChebyshevEqualsSerialBitForBitOnEveryPartition) {
  // The bound estimate's start vector: each rank's shares of the serial one in both halves. The
  // sets of 200 (different and equal radii): the degree on 700 makes that one slow on a shared
  // machine, and the chunks are the Lanczos test's.
  const SqrtOptions options = sampler(SqrtMethod::chebyshev, SqrtPreconditioner::none, 1e-3);
  const std::vector<Particles> sets = rotation_sets();
  for (std::size_t k = 0; k < 2; ++k) expect_serial_rotation(sets[k], options, 3);
}

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

// A suspension of the serial samplers' tests with rotation (tests/sqrt/test_sqrt_rotation.cpp): N
// spheres at volume fraction 0.15 (some overlapping), radii 1 or uniform in [0.5, 2].
Particles suspension(std::size_t n, bool mixed, std::uint32_t seed) {
  Particles p;
  p.x = sqrt_test::random_points(n, 0.15, seed);
  p.a = sqrt_test::radii(n, mixed, seed + 1);
  return p;
}

// [v_t; v_r] as one 6N vector.
VectorXd stacked(const std::vector<double>& t, const std::vector<double>& r) {
  VectorXd v(static_cast<Eigen::Index>(t.size() + r.size()));
  std::copy(t.begin(), t.end(), v.data());
  std::copy(r.begin(), r.end(), v.data() + t.size());
  return v;
}

// Every rank's shares of w, gathered into [w_t; w_r] on every rank.
VectorXd gathered(const GrandVectors& w) {
  return stacked(all_gather(w.t), all_gather(w.r));
}

// The dense references of the whole set: S = diag(I, a_i I) and S M S with M the grand mobility
// assembled from the serial DirectRpy's products with unit forces and torques.
struct DenseGrand {
  VectorXd s;
  MatrixXd m, a;  // M and S M S
  explicit DenseGrand(const Particles& p) : s(sqrt_test::scaling(p.a)) {
    DirectRpy serial(Geometry::open(), kViscosity);
    serial.set_positions(p.x, p.a);
    m = sqrt_test::grand_dense(serial);
    a = s.asDiagonal() * m * s.asDiagonal();
  }
  // S^{-1} (S M S)^{1/2} z: the principal root's sample.
  [[nodiscard]] VectorXd principal(const VectorXd& z) const {
    return s.cwiseInverse().asDiagonal() * (sqrt_test::principal_sqrt(a) * z);
  }
};

// Lanczos at 1e-3 and 1e-6 and Chebyshev at 1e-5 (the serial test's cases) on `op` against the
// dense principal root, each within slack(method) x its tolerance plus `product_error` (the
// operator's, 0 for the exact product), in the norm |S x| the tolerances refer to.
template <class Operator>
void expect_principal_root(const Operator& op, const Partition& part, const Particles& p, const DenseGrand& dense,
                           double product_error) {
  const GrandVectors z = grand_noise(p.size(), 3, 0);
  const VectorXd ref = dense.principal(stacked(z.t, z.r));
  const std::pair<SqrtMethod, double> cases[] = {
      {SqrtMethod::lanczos, 1e-3}, {SqrtMethod::lanczos, 1e-6}, {SqrtMethod::chebyshev, 1e-5}};
  for (const auto& [method, tolerance] : cases) {
    const auto [w, report] = distributed_rotation(op, part, z, sampler(method, SqrtPreconditioner::none, tolerance));
    const double error = sqrt_test::scaled_error(gathered(w), ref, dense.s);
    EXPECT_LE(error, slack(method) * tolerance + product_error)
        << rpyfmm::rpy::to_string(method) << ", tolerance " << tolerance << ", N " << p.size();
    if (world_rank() == 0) {
      std::printf("[sqrt-rotation] %s %s tol %.0e: %.2e against the dense root\n", op.name().c_str(),
                  rpyfmm::rpy::to_string(method), tolerance, error);
    }
  }
}

}  // namespace

TEST(MpiDistributedSqrt, RotationSamplesAgreeWithDenseScaledRoot) {
  // 40 spheres, equal and different radii: 240 x 240 dense S M S and its principal root by the
  // symmetric eigensolver. The distributed samples are the serial ones bit for bit (above), so the
  // serial contracts hold: Lanczos within 10 x, Chebyshev within 1.5 x the tolerance.
  for (bool mixed : {false, true}) {
    const Particles p = suspension(40, mixed, mixed ? 21u : 23u);
    const DenseGrand dense(p);
    for (Split s : kSplits) {
      const Partition part = partition_of(p.size(), s);
      DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
      place(op, p, part);
      expect_principal_root(op, part, p, dense, 0.0);
    }
  }
}

namespace {

// G, the serial BlockPreconditioner of the scaled grand mobility of the whole set (blocks of at
// most `block` particles, on [x_t; x_r]): the preconditioner the distributed sampler applies on
// every partition, here on one rank.
struct GrandBlocks {
  BlockPreconditioner g;
  GrandBlocks(const Particles& p, std::size_t block)
      : g(p.x, p.a, kViscosity, Geometry::open(), block, rpyfmm::rpy::PreconditionedMatrix::scaled_grand) {}
  // The matrix of x <- f(G, x), column by column.
  template <class F>
  [[nodiscard]] MatrixXd dense(F&& f) const {
    const auto rows = static_cast<Eigen::Index>(g.rows());
    MatrixXd d(rows, rows);
    for (Eigen::Index k = 0; k < rows; ++k) {
      VectorXd e = VectorXd::Unit(rows, k);
      f(g, e.data());
      d.col(k) = e;
    }
    return d;
  }
};

// The block-preconditioned samplers (blocks of at most 4 particles) on `op`, the particles split
// by `s`: w = B z with B = S^{-1} G^{-1} (G S M S G^T)^{1/2}, G the whole set's blocks (GrandBlocks).
// B is a square root of M (B B^T = M to rounding: 1e-10 relative), so the samples have covariance
// M; Lanczos and Chebyshev at 1e-6 give G S w within slack(method) x 1e-6 plus `product_error` of
// (G S M S G^T)^{1/2} z, the root their tolerances refer to.
template <class Operator>
void expect_block_root(const Operator& op, const Particles& p, Split s, const DenseGrand& dense, double product_error) {
  constexpr double kTolerance = 1e-6;
  const Partition part = partition_of(p.size(), s);
  const GrandBlocks blocks(p, 4);
  const MatrixXd g = blocks.dense([](const BlockPreconditioner& gr, double* x) { gr.apply_g(x); });
  const MatrixXd g_inverse = blocks.dense([](const BlockPreconditioner& gr, double* x) { gr.solve_g(x); });
  const MatrixXd root = sqrt_test::principal_sqrt(g * dense.a * g.transpose());
  const MatrixXd b = dense.s.cwiseInverse().asDiagonal() * g_inverse * root;
  EXPECT_LE((b * b.transpose() - dense.m).norm(), 1e-10 * dense.m.norm());
  const GrandVectors z = grand_noise(p.size(), 9, 4);
  const VectorXd ref = root * stacked(z.t, z.r);
  for (SqrtMethod method : {SqrtMethod::lanczos, SqrtMethod::chebyshev}) {
    SqrtOptions options = sampler(method, SqrtPreconditioner::block, kTolerance);
    options.preconditioner_block = 4;
    const auto [w, report] = distributed_rotation(op, part, z, options);
    EXPECT_EQ(report.preconditioner_blocks, blocks.g.blocks());
    const VectorXd whitened = g * (dense.s.asDiagonal() * gathered(w));
    const double error = (whitened - ref).norm() / ref.norm();
    EXPECT_LE(error, slack(method) * kTolerance + product_error) << rpyfmm::rpy::to_string(method);
    if (world_rank() == 0) {
      std::printf("[sqrt-rotation] %s %s block tol %.0e: %.2e against the dense preconditioned root\n",
                  op.name().c_str(), rpyfmm::rpy::to_string(method), kTolerance, error);
    }
  }
}

}  // namespace

TEST(MpiDistributedSqrt, RotationBlockPreconditionedSampleIsTheSerialSamplerOnEveryPartition) {
  // The 6 x 6 per-particle blocks of S M S within the serial spatial blocks of the whole set,
  // whatever the partition (mpi/src/global_blocks.hpp): the sample is a square root of the grand
  // mobility's (expect_block_root), and bit for bit the serial DirectRpy::apply_sqrt_rotation's
  // with the block preconditioner on every split, blocks of 4 and of the automatic size: the same
  // G, products and inner products, the same iterations and number of blocks.
  const Particles p = suspension(40, true, 27u);
  const DenseGrand dense(p);
  DirectRpy serial(Geometry::open(), kViscosity);
  serial.set_positions(p.x, p.a);
  const GrandVectors z = grand_noise(p.size(), 9, 4);
  for (Split s : kSplits) {
    const Partition part = partition_of(p.size(), s);
    DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
    place(op, p, part);
    expect_block_root(op, p, s, dense, 0.0);
    for (SqrtMethod method : {SqrtMethod::lanczos, SqrtMethod::chebyshev}) {
      for (int block : {4, 0}) {  // 0: automatic
        SqrtOptions options = sampler(method, SqrtPreconditioner::block, 1e-6);
        options.preconditioner_block = block;
        const auto [expected, serial_report] = serial_rotation(serial, z, options);
        const auto [w, report] = distributed_rotation(op, part, z, options);
        EXPECT_EQ(report.iterations, serial_report.iterations);
        EXPECT_EQ(report.preconditioner_blocks, serial_report.preconditioner_blocks);
        EXPECT_EQ(bitwise_mismatches(w.t, share(expected.t, 3, part.offset, part.n)) +
                      bitwise_mismatches(w.r, share(expected.r, 3, part.offset, part.n)),
                  0u)
            << rpyfmm::rpy::to_string(method) << ", block " << block << ", split " << static_cast<int>(s) << ", rank "
            << world_rank() << " of " << world_size();
      }
    }
  }
}

TEST(MpiDistributedSqrt, RotationOnFmmAgreesWithDenseScaledRoot) {
  // DistributedFmmRpy at tolerance eps = 1e-8 (relative error of its products): the samplers run
  // on the FMM's S M S + E, |E| <~ eps |S M S|, so the sample moves by at most about
  // |E| / (2 sqrt(lambda_min)) |z| from the exact root's (the derivative of the matrix square root
  // at an SPD matrix is bounded by 1 / (2 sqrt(lambda_min)); Higham, Functions of Matrices, SIAM
  // 2008, Sec. 6.1), i.e. eps kappa / 2 relative to |(S M S)^{1/2} z| >= sqrt(lambda_min) |z|, with
  // kappa the condition number of S M S from the dense eigenvalues. The bounds: the sampler's
  // (as with the exact product) plus eps kappa / 2. 100 spheres of different radii, split evenly
  // and geometrically.
  const Particles p = suspension(100, true, 25u);
  const DenseGrand dense(p);
  const VectorXd eigenvalues = Eigen::SelfAdjointEigenSolver<MatrixXd>(dense.a, Eigen::EigenvaluesOnly).eigenvalues();
  constexpr double kFmmTolerance = 1e-8;
  const double product_error = 0.5 * kFmmTolerance * eigenvalues.maxCoeff() / eigenvalues.minCoeff();
  for (Split s : {Split::even, Split::geometric}) {
    const Partition part = partition_of(p.size(), s);
    rpyfmm::mpi::DistributedFmmRpy op(MPI_COMM_WORLD, kViscosity, {.tolerance = kFmmTolerance});
    op.set_positions(share(p.x, 3, part.offset, part.n), share(p.a, 1, part.offset, part.n));
    expect_principal_root(op, part, p, dense, product_error);
    expect_block_root(op, p, s, dense, product_error);
  }
  if (world_rank() == 0) std::printf("[sqrt-rotation] FMM product term eps kappa / 2 = %.2e\n", product_error);
}

TEST(MpiDistributedSqrt, RotationBadInputOnOneRankFailsEveryRank) {
  const int last = world_size() - 1;
  BadInputSet set;
  const DistributedDirectRpy& op = set.op;
  const std::size_t n = 3 * set.part.n;
  std::vector<double> zt(n, 1.0), zr(n, 1.0), wt(n), wr(n);
  std::vector<double> bad = zr, long_output(n + (world_rank() == last ? 3 : 0));
  if (world_rank() == last) bad[4] = std::numeric_limits<double>::quiet_NaN();
  const std::string prefix = "rank " + std::to_string(last) + " of " + std::to_string(world_size()) + ": ";
  const auto call = [&](std::span<const double> z_r, std::span<double> w_r, const SqrtOptions& options) {
    rpyfmm::mpi::sqrt_apply_rotation(op, zt, z_r, wt, w_r, options);
  };
  expect_collective_error([&] { call(bad, wr, lanczos(1e-3)); }, ErrorCode::invalid_input,
                          prefix + "rpyfmm::mpi::sqrt_apply_rotation: local rotational noise entry (1, 1) is NaN");
  expect_collective_error([&] { call(zr, long_output, lanczos(1e-3)); }, ErrorCode::invalid_input,
                          prefix + "rpyfmm::mpi::sqrt_apply_rotation: local rotational output has");
  SqrtOptions dense = lanczos(1e-3);
  if (world_rank() == last) dense.method = SqrtMethod::eigen;
  expect_collective_error([&] { call(zr, wr, dense); }, ErrorCode::not_supported,
                          prefix + "rpyfmm::mpi::sqrt_apply_rotation: method 'eigen' is not offered across ranks");
  if (world_size() > 1) {
    SqrtOptions block = lanczos(1e-3);
    if (world_rank() == last) block.preconditioner = SqrtPreconditioner::block;
    expect_collective_error([&] { call(zr, wr, block); }, ErrorCode::invalid_argument,
                            "rpyfmm::mpi::sqrt_apply_rotation: the ranks pass different options");
  }
  EXPECT_NO_THROW(call(zr, wr, lanczos(1e-3)));
}
