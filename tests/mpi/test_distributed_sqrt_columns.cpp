// rpyfmm::mpi::sqrt_apply with several right-hand sides (nrhs): each column against the sampler of
// one right-hand side on that column alone, bit for bit (Lanczos and Chebyshev, without and with
// the block preconditioner, on every split); the whole set against the serial block sampler
// DirectRpy::apply_sqrt_block, bit for bit, with and without the block preconditioner; the
// exchanges of inner products, as many as the column with the most iterations takes alone; the
// FMM operator against the direct one; and collective failure on bad input.
#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cstddef>
#include <cstdio>
#include <span>
#include <string>
#include <vector>

#include "mpi_test_support.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "rpyfmm/rpy/sqrt.hpp"
#include "sqrt_test_support.hpp"

using rpyfmm::mpi::DistributedDirectRpy, rpyfmm::mpi::DistributedFmmRpy, rpyfmm::mpi::InnerProductStats;
using rpyfmm::rpy::SqrtMethod, rpyfmm::rpy::SqrtOptions, rpyfmm::rpy::SqrtPreconditioner, rpyfmm::rpy::SqrtReport;
using ErrorCode = rpyfmm::ErrorCode;
using namespace rpyfmm_mpi_test;

namespace {

constexpr std::size_t kColumns = 3;

// Three columns of the whole set (3 entries per particle each, one after another): two draws of
// the noise and a smooth field (one vector on every particle), which Lanczos resolves in fewer
// iterations, so the columns converge at different iterations.
std::vector<double> whole_columns(std::size_t particles) {
  const std::size_t n = 3 * particles;
  std::vector<double> z(kColumns * n);
  rpyfmm::rpy::fill_normal(std::span<double>(z).first(n), 11, 1);
  rpyfmm::rpy::fill_normal(std::span<double>(z).subspan(n, n), 11, 2);
  for (std::size_t i = 0; i < n; ++i) z[2 * n + i] = 1.0 + static_cast<double>(i % 3);
  return z;
}

// Column c, of `length` entries, of columns stored one after another.
std::vector<double> column(const std::vector<double>& v, std::size_t c, std::size_t length) {
  return {v.begin() + static_cast<std::ptrdiff_t>(c * length),
          v.begin() + static_cast<std::ptrdiff_t>((c + 1) * length)};
}

// This rank's shares of every column of the whole set, one after another (apply_block's layout).
std::vector<double> column_shares(const std::vector<double>& whole, std::size_t particles, const Partition& part) {
  std::vector<double> out;
  for (std::size_t c = 0; c < kColumns; ++c) {
    const std::vector<double> s = share(column(whole, c, 3 * particles), 3, part.offset, part.n);
    out.insert(out.end(), s.begin(), s.end());
  }
  return out;
}

// One call on all the columns and one call per column, by `options`.
struct ColumnsAndSingles {
  std::vector<double> w;
  SqrtReport report;
  InnerProductStats stats;
  std::vector<std::vector<double>> single_w;
  std::vector<SqrtReport> single_reports;
  std::vector<InnerProductStats> single_stats;
};

template <class Operator>
ColumnsAndSingles sample_both_ways(const Operator& op, const std::vector<double>& z, const SqrtOptions& options) {
  const std::size_t n = 3 * op.local_size();
  ColumnsAndSingles r;
  r.w.assign(z.size(), 0.0);
  r.report = rpyfmm::mpi::sqrt_apply(op, z, r.w, kColumns, options, &r.stats);
  for (std::size_t c = 0; c < kColumns; ++c) {
    std::vector<double> w(n);
    InnerProductStats stats;
    r.single_reports.push_back(rpyfmm::mpi::sqrt_apply(op, column(z, c, n), w, 1, options, &stats));
    r.single_w.push_back(w);
    r.single_stats.push_back(stats);
  }
  return r;
}

// Each column bit for bit the sampler on that column alone (the product of a column in
// apply_block is apply's bit for bit, and every column's arithmetic is the single iteration's),
// the report aggregated as rpy::sqrt_apply's block variant, and the exchanges of inner products
// those of the column that takes the most: Lanczos runs one exchange per stage of all the columns'
// steps; Chebyshev's only inner products are the bound estimate's, once per call.
void expect_columns_are_singles(const ColumnsAndSingles& r, std::size_t n, const SqrtOptions& options,
                                const std::string& label) {
  int iterations = 0, fewest = r.single_reports[0].iterations;
  long long products = 0, exchanges = 0;
  for (std::size_t c = 0; c < kColumns; ++c) {
    fewest = std::min(fewest, r.single_reports[c].iterations);
    EXPECT_EQ(bitwise_mismatches(column(r.w, c, n), r.single_w[c]), 0u)
        << label << ", column " << c << ", rank " << world_rank();
    iterations = std::max(iterations, r.single_reports[c].iterations);
    products += r.single_reports[c].vector_products;
    exchanges = std::max(exchanges, r.single_stats[c].exchanges);
  }
  EXPECT_EQ(r.report.iterations, iterations) << label;
  EXPECT_EQ(r.stats.exchanges, exchanges) << label;
  if (options.method == SqrtMethod::lanczos) {
    EXPECT_EQ(r.report.vector_products, products) << label;
    EXPECT_EQ(r.report.operator_applications, iterations) << label;  // one call per iteration
    EXPECT_EQ(r.stats.exchanges, 1 + 3 * iterations) << label;       // the start, 3 per step
    EXPECT_LT(fewest, iterations) << label;                          // a column stopped while others went on
  } else {
    const int estimate = r.single_reports[0].operator_applications - r.single_reports[0].iterations;
    EXPECT_EQ(r.report.operator_applications, estimate + iterations) << label;
    EXPECT_EQ(r.report.vector_products, estimate + static_cast<long long>(kColumns) * iterations) << label;
    EXPECT_EQ(r.report.lambda_min, r.single_reports[0].lambda_min) << label;
    EXPECT_EQ(r.report.lambda_max, r.single_reports[0].lambda_max) << label;
  }
  if (world_rank() == 0) {
    std::printf("[sqrt-columns] %s: %d iterations, %lld exchanges of inner products for %zu columns\n", label.c_str(),
                r.report.iterations, r.stats.exchanges, kColumns);
  }
}

}  // namespace

TEST(MpiDistributedSqrtColumns, EachColumnIsTheSingleSampleAndTheSerialBlockSampleBitForBit) {
  // 200 clustered particles (one reduction chunk) at tolerance 1e-6, nrhs 3. Against
  // DirectRpy::apply_sqrt_block on the whole set (the serial block variant; independent of the
  // distributed code): bit for bit, since every inner product is summed in the serial order
  // (krylov_space.hpp), DirectRpy's block product is its single product on every column, and the
  // block preconditioner's G is the serial one of the whole set on every split (its blocks cut
  // between ranks: mpi/src/global_blocks.hpp).
  const Particles p = clustered_particles(170, 30, 61);
  const WholeSet set(p, 0, 0);
  const std::vector<double> z = whole_columns(p.size());
  for (SqrtMethod method : {SqrtMethod::lanczos, SqrtMethod::chebyshev}) {
    for (SqrtPreconditioner preconditioner : {SqrtPreconditioner::none, SqrtPreconditioner::block}) {
      const SqrtOptions options = sampler(method, preconditioner, 1e-6);
      std::vector<double> w_serial(z.size());
      const SqrtReport serial = set.op.apply_sqrt_block(z, w_serial, kColumns, options);
      for (Split s : kSplits) {
        const Partition part = partition_of(p.size(), s);
        DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
        place(op, p, part);
        const std::string label = std::string(to_string(method)) + " (" + to_string(preconditioner) + "), split " +
                                  std::to_string(static_cast<int>(s));
        const ColumnsAndSingles r = sample_both_ways(op, column_shares(z, p.size(), part), options);
        expect_columns_are_singles(r, 3 * part.n, options, label);
        std::vector<double> again(r.w.size());
        rpyfmm::mpi::sqrt_apply(op, column_shares(z, p.size(), part), again, kColumns, options);
        EXPECT_EQ(bitwise_mismatches(again, r.w), 0u) << label << ": a second call";
        EXPECT_EQ(bitwise_mismatches(r.w, column_shares(w_serial, p.size(), part)), 0u)
            << label << ": against the serial block sampler, rank " << world_rank();
        EXPECT_EQ(r.report.iterations, serial.iterations) << label;
        EXPECT_EQ(r.report.vector_products, serial.vector_products) << label;
        EXPECT_EQ(r.report.preconditioner_blocks, serial.preconditioner_blocks) << label;
      }
    }
  }
}

TEST(MpiDistributedSqrtColumns, SingleRightHandSideOverloadIsTheOneColumnCall) {
  // The sampler of one right-hand side and nrhs = 1 are one iteration: the same bits, report and
  // exchanges of inner products (without reorthogonalization: 2 per step).
  const Particles p = uniform_particles(1500, 60.0, 0.5, 1.5, 63);  // 4500 entries: two reduction chunks
  const Partition part = partition_of(p.size(), Split::geometric);
  DistributedDirectRpy op(MPI_COMM_WORLD, kViscosity);
  place(op, p, part);
  std::vector<double> z(3 * part.n), w(z.size()), w1(z.size());
  rpyfmm::mpi::fill_normal(z, part.offset, 3, 4);
  for (bool reorthogonalize : {true, false}) {
    SqrtOptions options = sampler(SqrtMethod::lanczos, SqrtPreconditioner::none, 1e-3);
    options.reorthogonalize = reorthogonalize;
    const SqrtReport single = rpyfmm::mpi::sqrt_apply(op, z, w, options);
    InnerProductStats stats;
    const SqrtReport one = rpyfmm::mpi::sqrt_apply(op, z, w1, 1, options, &stats);
    EXPECT_EQ(bitwise_mismatches(w1, w), 0u) << "reorthogonalize " << reorthogonalize;
    EXPECT_EQ(one.iterations, single.iterations);
    EXPECT_EQ(one.vector_products, single.vector_products);
    EXPECT_EQ(stats.exchanges, 1 + (reorthogonalize ? 3 : 2) * one.iterations);
  }
}

TEST(MpiDistributedSqrtColumns, OnFmmEachColumnIsTheSingleSampleAndTheDirectSampleToTolerance) {
  // 150 clustered particles, the FMM at 1e-9, the samplers at 1e-6. Each column bit for bit the
  // FMM sampler on that column alone (DistributedFmmRpy::apply_block is apply on every column bit
  // for bit); against the direct operator's columns (the same blocks: the same particles) within
  // 1e-5, as MpiDistributedFmmRpy.SamplersOnTheOperator bounds one column: the operators differ by
  // <= 1e-9 relative, which moves the root by about that over the smallest eigenvalue's square
  // root, and each sampler stops within its tolerance of its own root.
  const Particles p = clustered_particles(120, 30, 73);
  const Partition part = partition_of(p.size(), Split::even);
  DistributedFmmRpy fmm(MPI_COMM_WORLD, kViscosity, {.tolerance = 1e-9});
  DistributedDirectRpy direct(MPI_COMM_WORLD, kViscosity);
  place(fmm, p, part);
  place(direct, p, part);
  const std::vector<double> z = column_shares(whole_columns(p.size()), p.size(), part);
  const std::size_t n = 3 * part.n;
  for (SqrtMethod method : {SqrtMethod::lanczos, SqrtMethod::chebyshev}) {
    for (SqrtPreconditioner preconditioner : {SqrtPreconditioner::none, SqrtPreconditioner::block}) {
      const SqrtOptions options = sampler(method, preconditioner, 1e-6);
      const std::string label = std::string("fmm ") + to_string(method) + " (" + to_string(preconditioner) + ")";
      const ColumnsAndSingles r = sample_both_ways(fmm, z, options);
      expect_columns_are_singles(r, n, options, label);
      std::vector<double> w_direct(z.size());
      rpyfmm::mpi::sqrt_apply(direct, z, w_direct, kColumns, options);
      for (std::size_t c = 0; c < kColumns; ++c) {
        const double difference = global_relative_error(column(r.w, c, n), column(w_direct, c, n));
        EXPECT_LE(difference, 1e-5) << label << ", column " << c;
        if (world_rank() == 0)
          std::printf("[sqrt-columns] %s column %zu vs direct: %.2e\n", label.c_str(), c, difference);
      }
    }
  }
}

TEST(MpiDistributedSqrtColumns, BadInputOnOneRankFailsEveryRank) {
  const int last = world_size() - 1;
  BadInputSet set;
  const DistributedDirectRpy& op = set.op;
  const std::size_t n = 3 * set.part.n;
  std::vector<double> z(kColumns * n, 1.0), w(kColumns * n);
  const SqrtOptions options = sampler(SqrtMethod::lanczos, SqrtPreconditioner::none, 1e-3);
  const std::string where = "rpyfmm::mpi::sqrt_apply: ";
  const std::string prefix = "rank " + std::to_string(last) + " of " + std::to_string(world_size()) + ": " + where;
  expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, z, w, 0, options); }, ErrorCode::invalid_argument,
                          where + "number of right-hand sides (nrhs) must be > 0");
  const std::size_t zero_on_last = world_rank() == last ? 0 : kColumns;
  expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, z, w, zero_on_last, options); },
                          ErrorCode::invalid_argument, prefix + "number of right-hand sides (nrhs) must be > 0");
  std::vector<double> short_z = z;
  if (world_rank() == last) short_z.resize(z.size() - 3);
  const std::string message =
      expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, short_z, w, kColumns, options); },
                              ErrorCode::invalid_input, prefix + "local noise has ");
  EXPECT_NE(message.find(" (nrhs 3 x "), std::string::npos) << message;
  SqrtOptions dense = options;
  dense.method = SqrtMethod::eigen;
  expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, z, w, kColumns, dense); }, ErrorCode::not_supported,
                          "method 'eigen' is not offered across ranks");
  if (world_size() > 1) {
    // nrhs differs, each rank's arrays of its own nrhs: the ranks would part ways.
    const std::size_t mine = world_rank() == last ? 1 : kColumns;
    std::vector<double> zm(mine * n, 1.0), wm(mine * n);
    expect_collective_error([&] { rpyfmm::mpi::sqrt_apply(op, zm, wm, mine, options); }, ErrorCode::invalid_argument,
                            "or numbers of right-hand sides; every rank must pass the same ones");
  }
  EXPECT_NO_THROW(rpyfmm::mpi::sqrt_apply(op, z, w, kColumns, options));
}
