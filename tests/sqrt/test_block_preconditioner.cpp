// The block preconditioner of the Krylov samplers (rpyfmm/rpy/block_preconditioner.hpp):
// G = L^{-1} against the dense RPY matrix, the preconditioned sample w = G^{-1} (G M G^T)^{1/2} z
// against the same formula evaluated densely (eigendecomposition), its covariance B B^T = M, the
// fallback for coincident particles, and the FMM and periodic (PSE) operators behind it. The
// statistical covariance test of the preconditioned sampler is in test_sqrt_operator.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <string>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/block_factors.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "sqrt_test_util.hpp"

using namespace rpyfmm::rpy;

namespace {

enum class Which { g, g_transpose, g_inverse };

/// The preconditioner's map as a dense matrix, column by column from unit vectors.
Eigen::MatrixXd dense_map(const BlockPreconditioner& p, Which which) {
  const auto n = static_cast<Eigen::Index>(3 * p.size());
  Eigen::MatrixXd out(n, n);
  for (Eigen::Index k = 0; k < n; ++k) {
    Eigen::VectorXd e = Eigen::VectorXd::Unit(n, k);
    if (which == Which::g) p.apply_g(e.data());
    if (which == Which::g_transpose) p.apply_g_transpose(e.data());
    if (which == Which::g_inverse) p.solve_g(e.data());
    out.col(k) = e;
  }
  return out;
}

/// B = G^{-1} (G M G^T)^{1/2}, evaluated densely: the matrix the preconditioned sampler applies.
/// (Eigenvalues clamped at 0: coincident particles make M only semidefinite.)
Eigen::MatrixXd dense_sampler(const Eigen::MatrixXd& M, const Eigen::MatrixXd& G) {
  const Eigen::MatrixXd A = G * M * G.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (A + A.transpose()));
  const Eigen::MatrixXd root =
      es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal() * es.eigenvectors().transpose();
  return G.partialPivLu().solve(root);  // G is triangular only in block order
}

double relative_error(const std::vector<double>& w, const Eigen::VectorXd& ref) {
  return (Eigen::Map<const Eigen::VectorXd>(w.data(), ref.size()) - ref).norm() / ref.norm();
}

/// 400 particles of mixed radii (phi 0.1) behind a DirectRpy, its dense matrix M, blocks of at
/// most 48 particles, their dense G and sampler B = G^{-1} (G M G^T)^{1/2}.
class BlockPreconditionerSuspension : public ::testing::Test {
 protected:
  static constexpr std::size_t N = 400;
  static DirectRpy& placed(DirectRpy& op) {
    op.set_positions(sqrt_test::random_points(N, 0.1, 71u), sqrt_test::radii(N, false, 72u));
    return op;
  }
  /// B z for the noise z.
  [[nodiscard]] Eigen::VectorXd sampled(const std::vector<double>& z) const {
    return B * Eigen::Map<const Eigen::VectorXd>(z.data(), M.rows());
  }
  DirectRpy op{Geometry::open(), 1.0};  // members initialize in this order
  BlockPreconditioner p{placed(op), 48};
  Eigen::MatrixXd M{sqrt_test::dense_of(op)};
  Eigen::MatrixXd G{dense_map(p, Which::g)};
  Eigen::MatrixXd B{dense_sampler(M, G)};
};

/// The canonical median bisection written out with full sorts (no selection algorithm): the
/// part's bounding box, its first axis of widest extent, the part sorted by (coordinate, index),
/// its first floor(n / 2) particles the lower part; a final part's members sorted by index.
void sorted_bisection(const std::vector<double>& x, std::vector<std::size_t> part, std::size_t max_block,
                      BlockPartition& out) {
  if (part.size() <= max_block) {
    std::sort(part.begin(), part.end());
    out.order.insert(out.order.end(), part.begin(), part.end());
    out.offsets.push_back(out.order.size());
    return;
  }
  std::array<double, 3> extent{};
  for (std::size_t c = 0; c < 3; ++c) {
    const auto [lo, hi] = std::minmax_element(
        part.begin(), part.end(), [&](std::size_t i, std::size_t j) { return x[3 * i + c] < x[3 * j + c]; });
    extent[c] = x[3 * *hi + c] - x[3 * *lo + c];
  }
  const std::size_t axis = static_cast<std::size_t>(std::max_element(extent.begin(), extent.end()) - extent.begin());
  std::sort(part.begin(), part.end(), [&](std::size_t i, std::size_t j) {
    return x[3 * i + axis] < x[3 * j + axis] || (x[3 * i + axis] == x[3 * j + axis] && i < j);
  });
  const auto mid = part.begin() + static_cast<std::ptrdiff_t>(part.size() / 2);
  sorted_bisection(x, std::vector<std::size_t>(part.begin(), mid), max_block, out);
  sorted_bisection(x, std::vector<std::size_t>(mid, part.end()), max_block, out);
}

}  // namespace

// bisect_blocks is the canonical median bisection (block_factors.hpp): the same order and offsets
// as the bisection by full sorts, on random points, on a lattice where most coordinates tie
// (-0.0 and +0.0 among them, equal under <) and on coincident points, for several block sizes.
TEST(BlockPartition, BisectionIsTheCanonicalMedianSplit) {
  std::vector<std::vector<double>> sets{sqrt_test::random_points(300, 0.1, 5u), std::vector<double>(3 * 70, 2.5)};
  std::vector<double> lattice(3 * 400);
  for (std::size_t g = 0; g < 400; ++g)
    for (std::size_t c = 0; c < 3; ++c) {
      const std::size_t k = (g * 31 + c * 7) % 5;
      lattice[3 * g + c] = k == 0 && g % 2 == 1 ? -0.0 : static_cast<double>(k);
    }
  sets.push_back(lattice);
  for (const std::vector<double>& x : sets) {
    for (const std::size_t max_block : {1, 2, 5, 16, 500}) {
      BlockPartition expected;
      std::vector<std::size_t> all(x.size() / 3);
      for (std::size_t g = 0; g < all.size(); ++g) all[g] = g;
      sorted_bisection(x, all, max_block, expected);
      const BlockPartition got = bisect_blocks(x, max_block);
      EXPECT_EQ(got.offsets, expected.offsets) << x.size() / 3 << " particles, max_block " << max_block;
      EXPECT_EQ(got.order, expected.order) << x.size() / 3 << " particles, max_block " << max_block;
    }
  }
}

// G = L^{-1} with L L^T the block diagonal of M: the particles' 3x3 diagonal blocks of
// A = G M G^T are identities (to the single-precision storage of L), G^T and G^{-1} are the
// transpose and inverse of G, and B B^T = M exactly.
// Blocks: 300 particles halved until <= 32 per block gives 16 blocks of 18-19.
TEST(BlockPreconditioner, WhitensTheBlockDiagonal) {
  const std::size_t N = 300;
  const auto x = sqrt_test::random_points(N, 0.2, 61u);
  const auto a = sqrt_test::radii(N, true, 62u);
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(x, a);
  const BlockPreconditioner p(x, a, 1.0, Geometry::open(), 32);
  EXPECT_EQ(p.blocks(), 16u);
  EXPECT_EQ(p.diagonal_blocks(), 0u);
  const Eigen::MatrixXd G = dense_map(p, Which::g);
  const Eigen::MatrixXd A = G * M * G.transpose();
  std::size_t whitened_pairs = 0;  // particle pairs i != j whose block of A vanishes (same block)
  for (std::size_t i = 0; i < N; ++i) {
    const auto bi = static_cast<Eigen::Index>(3 * i);
    EXPECT_LE((A.block<3, 3>(bi, bi) - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-5) << i;
    for (std::size_t j = 0; j < N; ++j) {
      if (j != i && A.block<3, 3>(bi, static_cast<Eigen::Index>(3 * j)).cwiseAbs().maxCoeff() <= 1e-5) ++whitened_pairs;
    }
  }
  EXPECT_GE(whitened_pairs, 16u * 18u * 17u);  // every pair within a block (others are coupled)
  EXPECT_LE((dense_map(p, Which::g_transpose) - G.transpose()).norm(), 1e-14 * G.norm());
  const Eigen::MatrixXd Ginv = dense_map(p, Which::g_inverse);
  EXPECT_LE((Ginv * G - Eigen::MatrixXd::Identity(G.rows(), G.cols())).norm(), 1e-10 * std::sqrt(double(G.rows())));
  const Eigen::MatrixXd B = dense_sampler(M, G);
  EXPECT_LE((B * B.transpose() - M).norm(), 1e-10 * M.norm());
}

// The preconditioned Lanczos sample through MobilityOperator::apply_sqrt equals B z to the
// sampler's usual accuracy (<= 10 tol, as for M^{1/2} z: sqrt.hpp), for tolerances 1e-2 ... 1e-8,
// and needs fewer products than Lanczos on M itself (the reason for the preconditioner).
TEST_F(BlockPreconditionerSuspension, SampleMatchesDenseReferenceInFewerProducts) {
  std::vector<double> z(3 * N), w(3 * N);
  fill_normal(z, 5u, 0u);
  const Eigen::VectorXd ref = sampled(z);
  for (double tol : {1e-2, 1e-4, 1e-6, 1e-8}) {
    SqrtOptions opt{.tolerance = tol, .preconditioner = SqrtPreconditioner::block, .preconditioner_block = 48};
    const SqrtReport rep = op.apply_sqrt(z, w, opt);
    EXPECT_EQ(rep.method, SqrtMethod::lanczos);
    EXPECT_EQ(rep.preconditioner_blocks, p.blocks());
    EXPECT_LE(relative_error(w, ref), 10 * tol) << tol;
    const SqrtReport plain = op.apply_sqrt(z, w, SqrtOptions{.tolerance = tol});
    EXPECT_EQ(plain.preconditioner_blocks, 0u);
    if (tol <= 1e-4) {
      EXPECT_LE(rep.iterations, 0.75 * plain.iterations) << tol;
    }
  }
  // `automatic` preconditions Lanczos with the automatic block size (400 / 64 -> 16: 32 blocks).
  SqrtOptions automatic{.tolerance = 1e-4, .preconditioner = SqrtPreconditioner::automatic};
  EXPECT_EQ(BlockPreconditioner::automatic_block(N), 16u);
  EXPECT_EQ(op.apply_sqrt(z, w, automatic).preconditioner_blocks, 32u);
  // ... and falls back to none for the other methods (dense eigen: the principal root).
  automatic.method = SqrtMethod::eigen;
  EXPECT_EQ(op.apply_sqrt(z, w, automatic).preconditioner_blocks, 0u);
  const Eigen::VectorXd principal =
      sqrt_test::principal_sqrt(M) * Eigen::Map<const Eigen::VectorXd>(z.data(), M.rows());
  EXPECT_LE(relative_error(w, principal), 1e-10);
  // Block variant: several noise vectors at once give the single-vector results.
  std::vector<double> z2(6 * N), w2(6 * N), w1(3 * N);
  fill_normal(std::span<double>(z2.data() + 3 * N, 3 * N), 5u, 1u);
  std::copy(z.begin(), z.end(), z2.begin());
  const SqrtOptions opt{.tolerance = 1e-6, .preconditioner = SqrtPreconditioner::block, .preconditioner_block = 48};
  op.apply_sqrt_block(z2, w2, 2, opt);
  for (std::size_t r = 0; r < 2; ++r) {
    op.apply_sqrt(std::span<const double>(z2.data() + 3 * N * r, 3 * N), w1, opt);
    const Eigen::VectorXd one = Eigen::Map<const Eigen::VectorXd>(w1.data(), 3 * static_cast<Eigen::Index>(N));
    EXPECT_LE(relative_error(std::vector<double>(w2.begin() + 3 * N * r, w2.begin() + 3 * N * (r + 1)), one), 1e-5);
  }
}

// The preconditioned Chebyshev sampler equals B z within its bound (the relative error is <= tol when
// the bounds enclose the spectrum of A = G M G^T: chebyshev.cpp; 2 tol allows for the padded
// estimate), with bounds estimated on A or given; its degree falls with A's condition number
// (degree ~ sqrt(kappa) log(1/tol): at least 2x lower here, where kappa(M) / kappa(A) ~ 6).
// `automatic` preconditions it only when the bounds are estimated: given bounds are M's.
TEST_F(BlockPreconditionerSuspension, ChebyshevSamplerOnThePreconditionedOperator) {
  std::vector<double> z(3 * N), w(3 * N);
  fill_normal(z, 9u, 0u);
  const Eigen::VectorXd ref = sampled(z);
  const Eigen::VectorXd evA = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(G * M * G.transpose()).eigenvalues();
  const Eigen::VectorXd evM = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(M).eigenvalues();
  for (double tol : {1e-2, 1e-4, 1e-6}) {
    SqrtOptions opt{.method = SqrtMethod::chebyshev,
                    .tolerance = tol,
                    .preconditioner = SqrtPreconditioner::block,
                    .preconditioner_block = 48};
    const SqrtReport rep = op.apply_sqrt(z, w, opt);
    EXPECT_EQ(rep.method, SqrtMethod::chebyshev);
    EXPECT_EQ(rep.preconditioner_blocks, p.blocks());
    EXPECT_LE(rep.lambda_min, evA(0)) << tol;  // the estimated bounds enclose A's spectrum
    EXPECT_GE(rep.lambda_max, evA(evA.size() - 1)) << tol;
    EXPECT_LE(relative_error(w, ref), 2 * tol) << tol;
    const SqrtReport plain = op.apply_sqrt(z, w, SqrtOptions{.method = SqrtMethod::chebyshev, .tolerance = tol});
    EXPECT_LE(2 * rep.iterations, plain.iterations) << tol;
    // Exact bounds of A, given: the same sample within tol.
    opt.lambda_min = evA(0);
    opt.lambda_max = evA(evA.size() - 1);
    EXPECT_EQ(op.apply_sqrt(z, w, opt).lambda_min, evA(0));
    EXPECT_LE(relative_error(w, ref), tol) << tol;
  }
  // `automatic` with estimated bounds: preconditioned; with given bounds (M's): not.
  SqrtOptions automatic{
      .method = SqrtMethod::chebyshev, .tolerance = 1e-6, .preconditioner = SqrtPreconditioner::automatic};
  EXPECT_EQ(op.apply_sqrt(z, w, automatic).preconditioner_blocks, 32u);
  automatic.lambda_min = evM(0);
  automatic.lambda_max = evM(evM.size() - 1);
  EXPECT_EQ(op.apply_sqrt(z, w, automatic).preconditioner_blocks, 0u);
  const Eigen::VectorXd principal =
      sqrt_test::principal_sqrt(M) * Eigen::Map<const Eigen::VectorXd>(z.data(), M.rows());
  EXPECT_LE(relative_error(w, principal), 1e-6);
}

// Coincident particles make their block of M singular: that block keeps its diagonal, G stays
// invertible, B B^T = M still holds and the sample is finite and accurate.
TEST(BlockPreconditioner, CoincidentParticlesKeepTheDiagonal) {
  const std::size_t N = 60;
  auto x = sqrt_test::random_points(N, 0.1, 81u);
  for (int c = 0; c < 3; ++c) x[3 * 7 + c] = x[3 * 3 + c];  // particle 7 on top of particle 3
  const std::vector<double> a(N, 1.0);
  DirectRpy op(Geometry::open(), 1.0);
  op.set_positions(x, a);
  const Eigen::MatrixXd M = sqrt_test::dense_of(op);
  const BlockPreconditioner p(op, N);  // one block holding both
  EXPECT_EQ(p.blocks(), 1u);
  EXPECT_EQ(p.diagonal_blocks(), 1u);
  const Eigen::MatrixXd G = dense_map(p, Which::g);
  EXPECT_LE((G - Eigen::MatrixXd(M.diagonal().cwiseSqrt().cwiseInverse().asDiagonal())).norm(), 1e-6 * G.norm());
  const Eigen::MatrixXd B = dense_sampler(M, G);
  EXPECT_LE((B * B.transpose() - M).norm(), 1e-10 * M.norm());
  std::vector<double> z(3 * N), w(3 * N);
  fill_normal(z, 9u, 0u);
  op.apply_sqrt(
      z, w,
      SqrtOptions{
          .tolerance = 1e-6, .preconditioner = SqrtPreconditioner::block, .preconditioner_block = static_cast<int>(N)});
  EXPECT_LE(relative_error(w, B * Eigen::Map<const Eigen::VectorXd>(z.data(), M.rows())), 1e-5);
}

// Fewer particles than a block: G = L^{-1} with L L^T = M, so A = I and the sample is the
// Cholesky sample L z after one Lanczos step.
TEST(BlockPreconditioner, OneBlockGivesTheCholeskySampleInOneStep) {
  const std::size_t N = 30;
  DirectRpy op(Geometry::open(), 1.0);
  op.set_positions(sqrt_test::random_points(N, 0.2, 91u), sqrt_test::radii(N, true, 92u));
  std::vector<double> z(3 * N), w(3 * N), c(3 * N);
  fill_normal(z, 2u, 0u);
  const SqrtReport rep = op.apply_sqrt(
      z, w, SqrtOptions{.tolerance = 1e-6, .preconditioner = SqrtPreconditioner::block, .preconditioner_block = 32});
  EXPECT_EQ(rep.preconditioner_blocks, 1u);
  EXPECT_LE(rep.iterations, 2);
  op.apply_sqrt(z, c, SqrtOptions{.method = SqrtMethod::cholesky});
  Eigen::VectorXd ref = Eigen::Map<const Eigen::VectorXd>(c.data(), 3 * static_cast<Eigen::Index>(N));
  EXPECT_LE(relative_error(w, ref), 1e-6);  // L in single precision
}

// The FMM operator (free space) and the PSE operator (periodic; blocks use minimum-image
// separations) behind the same preconditioned sampler, against dense B z of each operator.
TEST(BlockPreconditioner, FmmAndPeriodicOperators) {
  const std::size_t N = 400;
  const auto x = sqrt_test::random_points(N, 0.1, 101u);
  const auto a = sqrt_test::radii(N, true, 102u);
  DirectRpy direct(Geometry::open(), 1.0);
  direct.set_positions(x, a);
  FmmRpy fmm(Geometry::open(), 1.0, FmmRpyOptions{.tolerance = 1e-8});
  fmm.set_positions(x, a);
  std::vector<double> z(3 * N), w(3 * N);
  fill_normal(z, 4u, 0u);
  const SqrtOptions opt{.tolerance = 1e-6, .preconditioner = SqrtPreconditioner::block, .preconditioner_block = 32};
  {
    const Eigen::MatrixXd B =
        dense_sampler(sqrt_test::dense_of(direct), dense_map(BlockPreconditioner(fmm, 32), Which::g));
    fmm.apply_sqrt(z, w, opt);
    EXPECT_LE(relative_error(w, B * Eigen::Map<const Eigen::VectorXd>(z.data(), 3 * N)), 1e-5);
  }
  const std::size_t Np = 120;
  const double box = std::cbrt(Np * 4.0 / 3.0 * std::numbers::pi / 0.1);
  pse::PseRpy pse_op(Geometry::periodic(box), 1.0, pse::PseOptions{.tolerance = 1e-8});
  const auto xp = sqrt_test::random_points(Np, 0.1, 103u);
  pse_op.set_positions(xp, 1.0);
  std::vector<double> zp(3 * Np), wp(3 * Np);
  fill_normal(zp, 6u, 0u);
  const Eigen::MatrixXd Mp = sqrt_test::dense_of(pse_op);
  const Eigen::MatrixXd Bp =
      dense_sampler(0.5 * (Mp + Mp.transpose()), dense_map(BlockPreconditioner(pse_op, 32), Which::g));
  SqrtOptions popt = opt;
  popt.method = SqrtMethod::lanczos;
  pse_op.apply_sqrt(zp, wp, popt);
  EXPECT_LE(relative_error(wp, Bp * Eigen::Map<const Eigen::VectorXd>(zp.data(), 3 * Np)), 1e-5);
}

// Bad input: rpyfmm::Error naming the problem.
TEST(BlockPreconditioner, BadInput) {
  auto expect_error = [](auto&& f, const std::string& needle) {
    try {
      f();
      ADD_FAILURE() << "expected rpyfmm::Error containing '" << needle << "'";
    } catch (const rpyfmm::Error& e) {
      EXPECT_EQ(e.code(), rpyfmm::ErrorCode::invalid_argument) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  const std::size_t N = 10;
  DirectRpy op(Geometry::open(), 1.0);
  op.set_positions(sqrt_test::random_points(N, 0.1, 1u), 1.0);
  std::vector<double> z(3 * N, 1.0), w(3 * N);
  SqrtOptions block{.preconditioner = SqrtPreconditioner::block};
  // A bare linear operator has no particles to form blocks from.
  expect_error([&] { sqrt_apply(op.as_linear_operator(), z, w, 1, block); }, "needs the particles");
  SqrtOptions automatic{.preconditioner = SqrtPreconditioner::automatic};
  EXPECT_NO_THROW(sqrt_apply(op.as_linear_operator(), z, w, 1, automatic));  // falls back to none
  block.method = SqrtMethod::cholesky;
  expect_error([&] { op.apply_sqrt(z, w, block); }, "Lanczos and Chebyshev samplers only, not cholesky");
  block = {.preconditioner = SqrtPreconditioner::block, .preconditioner_block = -1};
  expect_error([&] { op.apply_sqrt(z, w, block); }, "preconditioner_block must be >= 0");
  expect_error([] { sqrt_preconditioner_from_string("jacobi"); }, "unknown preconditioner 'jacobi'");
  EXPECT_EQ(sqrt_preconditioner_from_string("block"), SqrtPreconditioner::block);
  pse::PseRpy pse_op(Geometry::periodic(20.0), 1.0);
  pse_op.set_positions(sqrt_test::random_points(N, 0.01, 2u), 1.0);
  expect_error([&] { pse_op.apply_sqrt(z, w, SqrtOptions{.preconditioner = SqrtPreconditioner::block}); },
               "not the split sampler");
  EXPECT_NO_THROW(pse_op.apply_sqrt(z, w, automatic));  // the split sampler, unpreconditioned
  const std::vector<double> x(6, 0.0), a(3, 1.0);
  try {
    BlockPreconditioner(x, a, 1.0, Geometry::open(), 8);
    ADD_FAILURE() << "accepted 6 coordinates for 3 radii";
  } catch (const rpyfmm::Error& e) {
    EXPECT_NE(std::string(e.what()).find("positions has 6 entries for 3 radii"), std::string::npos) << e.what();
  }
}
