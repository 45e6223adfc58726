// rpyfmm::mpi::sqrt_apply and rpyfmm::mpi::fill_normal: the noise of each rank's share against the
// serial rpy::fill_normal (bit for bit); the distributed Lanczos and Chebyshev square roots against
// the serial samplers on DirectRpy (bit for bit) and the dense principal square root (the serial
// contracts); the block preconditioner of each rank's particles against the serial preconditioned
// sampler with the same blocks (bit for bit) and the dense root of G M G^T; the covariance of the
// samples against the dense mobility matrix; and collective failure. (The samplers on
// DistributedFmmRpy: test_distributed_fmm_rpy.cpp.)
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

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

SqrtOptions sampler(SqrtMethod method, SqrtPreconditioner preconditioner, double tolerance) {
  SqrtOptions o;
  o.method = method;
  o.preconditioner = preconditioner;
  o.tolerance = tolerance;
  return o;
}

SqrtOptions lanczos(double tolerance) {
  return sampler(SqrtMethod::lanczos, SqrtPreconditioner::none, tolerance);
}

// The serial contracts against the dense principal root (tests/sqrt/test_sqrt_accuracy.cpp):
// Lanczos within 10 x its tolerance (its stopping test underestimates the error left: rpy/sqrt.hpp),
// Chebyshev within 1.5 x (its error bound holds when the estimated bounds enclose the spectrum).
double slack(SqrtMethod method) {
  return method == SqrtMethod::lanczos ? 10.0 : 1.5;
}

// The whole set on one rank: the serial DirectRpy and the noise of (seed, step).
struct WholeSet {
  DirectRpy op{Geometry::open(), kViscosity};
  std::vector<double> z;
  WholeSet(const Particles& p, std::uint64_t seed, std::uint64_t step) : z(3 * p.size()) {
    op.set_positions(p.x, p.a);
    rpyfmm::rpy::fill_normal(z, seed, step);
  }
};

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

// G = diag(G_0, ..., G_{P-1}) with G_r the serial BlockPreconditioner of rank r's particles alone
// under a split: the preconditioner the distributed sampler builds, here on one rank.
struct ShareBlocks {
  std::vector<BlockPreconditioner> g;
  std::vector<std::size_t> first;  // the entry of rank r's first particle

  template <class F>
  void each(double* x, F&& f) const {
    for (std::size_t r = 0; r < g.size(); ++r) f(g[r], x + first[r]);
  }
  [[nodiscard]] std::size_t blocks() const {
    std::size_t b = 0;
    for (const BlockPreconditioner& gr : g) b += gr.blocks();
    return b;
  }
};

ShareBlocks share_blocks(const Particles& p, Split s, std::size_t block) {
  ShareBlocks b;
  std::size_t offset = 0;
  for (std::size_t n : split_counts(p.size(), static_cast<std::size_t>(world_size()), s)) {
    b.g.emplace_back(share(p.x, 3, offset, n), share(p.a, 1, offset, n), kViscosity, Geometry::open(), block);
    b.first.push_back(3 * offset);
    offset += n;
  }
  return b;
}

// w = G^{-1} (G M G^T)^{1/2} z on one rank, with A = G M G^T by DirectRpy's products and its root
// by rpy::sqrt_apply with `options` (lanczos, chebyshev or eigen), as BlockPreconditioner::sample
// composes them.
std::vector<double> serial_share_sample(const DirectRpy& serial, const ShareBlocks& b, const std::vector<double>& z,
                                        const SqrtOptions& options) {
  const rpyfmm::rpy::LinearOperatorView m = serial.as_linear_operator();
  rpyfmm::rpy::LinearOperatorView a;
  a.n = m.n;
  a.apply = [&](std::span<const double> x, std::span<double> y, std::size_t nrhs) {  // nrhs: the dense method's
    for (std::size_t k = 0; k < nrhs; ++k) {
      std::vector<double> t(x.begin() + static_cast<std::ptrdiff_t>(k * m.n),
                            x.begin() + static_cast<std::ptrdiff_t>((k + 1) * m.n));
      const std::span<double> yk = y.subspan(k * m.n, m.n);
      b.each(t.data(), [](const BlockPreconditioner& g, double* v) { g.apply_g_transpose(v); });
      m.apply(t, yk, 1);
      b.each(yk.data(), [](const BlockPreconditioner& g, double* v) { g.apply_g(v); });
    }
  };
  SqrtOptions plain = options;
  plain.preconditioner = SqrtPreconditioner::none;
  std::vector<double> w(z.size());
  rpyfmm::rpy::sqrt_apply(a, z, w, 1, plain);
  b.each(w.data(), [](const BlockPreconditioner& g, double* v) { g.solve_g(v); });
  return w;
}

// G w: the root A^{1/2} z that the samplers' tolerances refer to.
std::vector<double> whitened(const ShareBlocks& b, std::vector<double> w) {
  b.each(w.data(), [](const BlockPreconditioner& g, double* v) { g.apply_g(v); });
  return w;
}

}  // namespace

TEST(MpiDistributedSqrt, BlockPreconditionerOfEachRanksParticlesIsTheSerialSamplerWithTheSameBlocks) {
  // Each rank factors the blocks of its own particles (blocks never straddle ranks), so G, and the
  // sample, depend on the partition. With the serial sampler run on one rank with the same G
  // (ShareBlocks), the distributed one agrees bit for bit: the same products, inner products summed
  // in the serial order, and G applied to each share as there. Where one rank holds every particle
  // (last only; every split on one rank) G is the serial preconditioner's, so w is the serial
  // MobilityOperator::apply_sqrt's bit for bit. Against the dense principal root of A = G M G^T:
  // the serial contract on A^{1/2} set.z.
  const Particles p = clustered_particles(170, 30, 61);
  const WholeSet set(p, 11, 4);
  constexpr double kTolerance = 1e-6;
  const std::size_t block = BlockPreconditioner::automatic_block(p.size());
  std::vector<double> w_whole[2];
  const SqrtMethod methods[2] = {SqrtMethod::lanczos, SqrtMethod::chebyshev};
  for (int k = 0; k < 2; ++k) {
    w_whole[k].resize(set.z.size());
    set.op.apply_sqrt(set.z, w_whole[k], sampler(methods[k], SqrtPreconditioner::block, kTolerance));
  }
  for (Split s : kSplits) {
    const Partition part = partition_of(p.size(), s);
    const ShareBlocks g = share_blocks(p, s, block);
    const std::vector<double> root =
        whitened(g, serial_share_sample(set.op, g, set.z, sampler(SqrtMethod::eigen, SqrtPreconditioner::none, 1e-3)));
    for (int k = 0; k < 2; ++k) {
      const SqrtOptions options = sampler(methods[k], SqrtPreconditioner::block, kTolerance);
      const std::vector<double> expected = serial_share_sample(set.op, g, set.z, options);
      const auto [w, report] = distributed_sample(p, s, set.z, options);
      EXPECT_EQ(bitwise_mismatches(w, share(expected, 3, part.offset, part.n)), 0u)
          << rpyfmm::rpy::to_string(methods[k]) << ", rank " << world_rank() << " of " << world_size();
      EXPECT_EQ(report.preconditioner_blocks, g.blocks());
      if (s == Split::last_only || world_size() == 1) {
        EXPECT_EQ(bitwise_mismatches(w, share(w_whole[k], 3, part.offset, part.n)), 0u);
      }
      EXPECT_LT(relative_difference(whitened(g, all_gather(w)), root), slack(methods[k]) * kTolerance)
          << rpyfmm::rpy::to_string(methods[k]);
    }
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
  // Blocks of at most 2 particles within each rank's share: w = L (L^{-1} M L^{-T})^{1/2} z, a
  // different square root of M for each partition, with the covariance M all the same.
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
