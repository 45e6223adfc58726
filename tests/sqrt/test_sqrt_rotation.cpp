// Brownian samplers on the grand mobility with rotation (MobilityOperator::apply_sqrt_rotation,
// docs/theory/samplers.md section 5): against the dense 6N x 6N matrix assembled from
// DirectRpy::apply(F, T, U, W) with unit vectors and its square roots by Eigen's symmetric
// eigensolver; covariances of many samples with fixed seeds; the free-draining exact sampler;
// bad input; thread independence.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/free_draining.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "sqrt_test_util.hpp"
#include "translation_only_operator.hpp"

using namespace rpyfmm::rpy;

namespace {

using Eigen::Index;
using Eigen::MatrixXd;
using Eigen::VectorXd;

using sqrt_test::grand_dense;
using sqrt_test::scaled_error;
using sqrt_test::scaling;

/// One sample: [w_t; w_r] for the noise [z_t; z_r] = z (6N).
VectorXd sample(const MobilityOperator& op, const VectorXd& z, const SqrtOptions& options,
                SqrtReport* report = nullptr) {
  const std::size_t n = 3 * op.size();
  std::vector<double> wt(n), wr(n);
  const SqrtReport r = op.apply_sqrt_rotation(std::span<const double>(z.data(), n),
                                              std::span<const double>(z.data() + n, n), wt, wr, options);
  if (report != nullptr) *report = r;
  VectorXd w(2 * n);
  for (std::size_t k = 0; k < n; ++k) {
    w(static_cast<Index>(k)) = wt[k];
    w(static_cast<Index>(n + k)) = wr[k];
  }
  return w;
}

/// Philox noise of 6N entries, (seed, step) for the translational half, step + 2^32 for the rotational.
VectorXd philox_noise(std::size_t N, std::uint64_t seed, std::uint64_t step) {
  VectorXd z(static_cast<Index>(6 * N));
  fill_normal(std::span<double>(z.data(), 3 * N), seed, step);
  fill_normal(std::span<double>(z.data() + 3 * N, 3 * N), seed, step + (std::uint64_t{1} << 32));
  return z;
}

struct Suspension {
  std::vector<double> x, a;
};

Suspension suspension(std::size_t N, bool mixed, std::uint32_t seed) {
  return {sqrt_test::random_points(N, 0.15, seed), sqrt_test::radii(N, mixed, seed + 1)};
}

// The grand matrix that the tests use as reference is the operator's, symmetric positive definite.
TEST(SqrtRotation, ReferenceMatrixIsSymmetricPositiveDefinite) {
  const Suspension s = suspension(30, true, 11u);
  DirectRpy op;
  op.set_positions(s.x, s.a);
  const MatrixXd M = grand_dense(op);
  EXPECT_LE((M - M.transpose()).norm(), 1e-14 * M.norm());
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<MatrixXd>(M).eigenvalues()(0), 0.0);
  EXPECT_NEAR(M(0, 0), 1.0 / (6 * std::numbers::pi * s.a[0]), 1e-15);
  EXPECT_NEAR(M(90, 90), 1.0 / (8 * std::numbers::pi * std::pow(s.a[0], 3)), 1e-14);
}

// Lanczos, Chebyshev, eigen and cholesky against S^{-1} (S M S)^{1/2} z and S^{-1} chol(S M S) z
// from the dense matrix: Lanczos within 10 x tol (sqrt.hpp: measured 2-3 x tol on RPY
// suspensions), Chebyshev 1e-5 within 1e-4, the dense methods to rounding (1e-10).
TEST(SqrtRotation, AgreesWithDenseScaledRoot) {
  const std::size_t N = 40;
  for (bool mixed : {false, true}) {
    const Suspension s = suspension(N, mixed, mixed ? 21u : 23u);
    DirectRpy op(Geometry::open(), 0.7);
    op.set_positions(s.x, s.a);
    const VectorXd sd = scaling(s.a);
    const MatrixXd M = grand_dense(op);
    const MatrixXd A = sd.asDiagonal() * M * sd.asDiagonal();
    const MatrixXd root = sd.cwiseInverse().asDiagonal() * sqrt_test::principal_sqrt(A);
    const MatrixXd chol = sd.cwiseInverse().asDiagonal() * MatrixXd(Eigen::LLT<MatrixXd>(A).matrixL());
    const VectorXd z = philox_noise(N, 3u, 0u);
    const VectorXd ref = root * z;
    for (double tol : {1e-3, 1e-6}) {
      SqrtReport report;
      const VectorXd w = sample(op, z, {.tolerance = tol}, &report);
      EXPECT_EQ(report.method, SqrtMethod::lanczos);
      EXPECT_EQ(report.preconditioner_blocks, 0u);
      EXPECT_LE(scaled_error(w, ref, sd), 10 * tol) << "mixed " << mixed << " tol " << tol;
    }
    const VectorXd wc = sample(op, z, {.method = SqrtMethod::chebyshev, .tolerance = 1e-5});
    EXPECT_LE(scaled_error(wc, ref, sd), 1e-4) << "chebyshev, mixed " << mixed;
    EXPECT_LE(scaled_error(sample(op, z, {.method = SqrtMethod::eigen}), ref, sd), 1e-10);
    const VectorXd ref_chol = chol * z;
    EXPECT_LE(scaled_error(sample(op, z, {.method = SqrtMethod::cholesky}), ref_chol, sd), 1e-10);
  }
}

// The FMM operator behind the same sampler: Lanczos on FmmRpy (tolerance 1e-8) agrees with the dense
// scaled root of the exact (direct) grand matrix, and block-preconditioned Lanczos with the same
// sampler on DirectRpy, within 10 x the square-root tolerance 1e-6 (the FMM error is far below).
TEST(SqrtRotation, FmmOperatorAgreesWithDenseScaledRoot) {
  const std::size_t N = 100;
  const Suspension s = suspension(N, true, 25u);
  DirectRpy direct;
  direct.set_positions(s.x, s.a);
  FmmRpy fmm(Geometry::open(), 1.0, {.tolerance = 1e-8});
  fmm.set_positions(s.x, s.a);
  ASSERT_TRUE(fmm.supports_rotation());
  const VectorXd sd = scaling(s.a);
  const VectorXd z = philox_noise(N, 13u, 0u);
  const VectorXd ref = sd.cwiseInverse().asDiagonal() *
                       (sqrt_test::principal_sqrt(sd.asDiagonal() * grand_dense(direct) * sd.asDiagonal()) * z);
  EXPECT_LE(scaled_error(sample(fmm, z, {.tolerance = 1e-6}), ref, sd), 1e-5);
  // Preconditioned (`automatic`: block for Lanczos): the same B z as on the direct operator.
  const SqrtOptions block{.tolerance = 1e-6, .preconditioner = SqrtPreconditioner::automatic};
  SqrtReport report;
  const VectorXd w = sample(fmm, z, block, &report);
  EXPECT_GT(report.preconditioner_blocks, 1u);
  EXPECT_LE(scaled_error(w, sample(direct, z, block), sd), 1e-5);
}

// With unit radii S = I: the sample is the principal root M^{1/2} z of the grand mobility itself.
TEST(SqrtRotation, UnitRadiiGivePrincipalRoot) {
  const std::size_t N = 30;
  const Suspension s = suspension(N, false, 31u);
  DirectRpy op;
  op.set_positions(s.x, 1.0);
  const MatrixXd root = sqrt_test::principal_sqrt(grand_dense(op));
  const VectorXd z = philox_noise(N, 4u, 2u);
  const VectorXd ref = root * z;
  EXPECT_LE((sample(op, z, {.method = SqrtMethod::eigen}) - ref).norm(), 1e-12 * ref.norm());
  EXPECT_LE((sample(op, z, {.tolerance = 1e-6}) - ref).norm(), 1e-5 * ref.norm());
}

// The scaling makes the sampler independent of the length unit: a suspension and its copy scaled by
// L (positions and radii) have M^tt / L, M^tr / L^2, M^rr / L^3, so S M S is the unit one divided by
// L and Lanczos takes the same steps; the samples are the unit ones times L^{-1/2} (translations)
// and L^{-3/2} (rotations) to rounding (L powers of two: 1e-12), and each half keeps the tolerance
// (within 10 x tol of its dense reference, relative to its own norm). Unscaled, the rotations would
// weigh L^{-2} times the translations in the stopping test.
TEST(SqrtRotation, SameStepsAndToleranceAtEveryLengthScale) {
  const std::size_t N = 30;
  const Suspension unit = suspension(N, true, 35u);
  const VectorXd z = philox_noise(N, 12u, 0u);
  const double tol = 1e-4;
  SqrtReport unit_report;
  VectorXd unit_w;
  for (double L : {1.0, 0.0625, 16.0}) {
    Suspension s = unit;
    for (double& v : s.x) v *= L;
    for (double& v : s.a) v *= L;
    DirectRpy op;
    op.set_positions(s.x, s.a);
    const VectorXd sd = scaling(s.a);
    const VectorXd ref = sd.cwiseInverse().asDiagonal() *
                         (sqrt_test::principal_sqrt(sd.asDiagonal() * grand_dense(op) * sd.asDiagonal()) * z);
    SqrtReport report;
    const VectorXd w = sample(op, z, {.tolerance = tol}, &report);
    const auto h = static_cast<Index>(3 * N);
    EXPECT_LE((w.head(h) - ref.head(h)).norm(), 10 * tol * ref.head(h).norm()) << "L " << L;
    EXPECT_LE((w.tail(h) - ref.tail(h)).norm(), 10 * tol * ref.tail(h).norm()) << "L " << L;
    if (L == 1.0) {
      unit_report = report;
      unit_w = w;
      continue;
    }
    EXPECT_EQ(report.iterations, unit_report.iterations) << "L " << L;
    VectorXd back = w;
    back.head(h) *= std::sqrt(L);
    back.tail(h) *= L * std::sqrt(L);
    EXPECT_LE((back - unit_w).norm(), 1e-12 * unit_w.norm()) << "L " << L;
  }
}

// The block preconditioner's factors on the 6N operator: L L^T equals the block diagonal of
// S M S (6 rows per particle, the spatial blocks) to single precision; with one block holding all
// particles, G S M S G^T = I up to that rounding, so Lanczos stops within 3 steps.
TEST(SqrtRotation, BlockPreconditionerFactorsScaledGrandBlocks) {
  const std::size_t N = 24;
  const Suspension s = suspension(N, true, 41u);
  DirectRpy op(Geometry::open(), 1.3);
  op.set_positions(s.x, s.a);
  const VectorXd sd = scaling(s.a);
  const MatrixXd A = sd.asDiagonal() * grand_dense(op) * sd.asDiagonal();
  const auto n = static_cast<Index>(6 * N);
  for (std::size_t block : {std::size_t{8}, N}) {
    const BlockPreconditioner pre(op, block, PreconditionedMatrix::scaled_grand);
    ASSERT_EQ(pre.rows(), 6 * N);
    MatrixXd L(n, n);  // columns L e_k
    for (Index k = 0; k < n; ++k) {
      VectorXd e = VectorXd::Unit(n, k);
      pre.solve_g(e.data());
      L.col(k) = e;
    }
    const MatrixXd LLt = L * L.transpose();
    if (block == N) {
      EXPECT_LE((LLt - A).norm(), 1e-6 * A.norm());
      continue;
    }
    // Entries of L L^T are those of A within a spatial block and exactly 0 across blocks (whose
    // partition is internal): compare on L L^T's pattern, which must couple translations and
    // rotations of different particles.
    MatrixXd masked = MatrixXd::Zero(n, n);
    for (Index i = 0; i < n; ++i)
      for (Index j = 0; j < n; ++j)
        if (LLt(i, j) != 0.0) masked(i, j) = A(i, j);
    EXPECT_LE((LLt - masked).norm(), 1e-6 * A.norm());
    const Index coupled = (masked.topRightCorner(n / 2, n / 2).array().abs() > 1e-3 * A(0, 0)).count();
    EXPECT_GT(coupled, Index(6 * N));
    EXPECT_LT(coupled, n * n / 8);  // not one block
  }
  SqrtReport report;
  sample(op, philox_noise(N, 5u, 0u),
         {.tolerance = 1e-3, .preconditioner = SqrtPreconditioner::block, .preconditioner_block = static_cast<int>(N)},
         &report);
  EXPECT_EQ(report.preconditioner_blocks, 1u);
  EXPECT_LE(report.iterations, 3);
}

// Block-preconditioned samples B z = S^{-1} L (G S M S G^T)^{1/2} z against the dense form built
// from the same L (solve_g on unit vectors), Lanczos within 10 x tol, Chebyshev 1e-5 within 1e-4;
// `automatic` takes the block preconditioner for Lanczos.
TEST(SqrtRotation, BlockPreconditionedAgreesWithDenseForm) {
  const std::size_t N = 40;
  const Suspension s = suspension(N, true, 51u);
  DirectRpy op;
  op.set_positions(s.x, s.a);
  const VectorXd sd = scaling(s.a);
  const MatrixXd A = sd.asDiagonal() * grand_dense(op) * sd.asDiagonal();
  const auto n = static_cast<Index>(6 * N);
  const BlockPreconditioner pre(op, 8, PreconditionedMatrix::scaled_grand);
  MatrixXd L(n, n);
  for (Index k = 0; k < n; ++k) {
    VectorXd e = VectorXd::Unit(n, k);
    pre.solve_g(e.data());
    L.col(k) = e;
  }
  const MatrixXd G = L.inverse();
  const MatrixXd B = sd.cwiseInverse().asDiagonal() * L * sqrt_test::principal_sqrt(G * A * G.transpose());
  const VectorXd z = philox_noise(N, 6u, 1u);
  const VectorXd ref = B * z;
  for (auto p : {SqrtPreconditioner::block, SqrtPreconditioner::automatic}) {
    SqrtReport report;
    const VectorXd w = sample(op, z, {.tolerance = 1e-6, .preconditioner = p, .preconditioner_block = 8}, &report);
    EXPECT_EQ(report.preconditioner_blocks, pre.blocks());
    EXPECT_LE(scaled_error(w, ref, sd), 1e-5);
  }
  const VectorXd wc = sample(op, z,
                             {.method = SqrtMethod::chebyshev,
                              .tolerance = 1e-5,
                              .preconditioner = SqrtPreconditioner::block,
                              .preconditioner_block = 8});
  EXPECT_LE(scaled_error(wc, ref, sd), 1e-4);
}

// Fluctuation-dissipation with rotation: two spheres (radii 1 and 1.5, overlapping at r = 2.08, so
// the translation-rotation blocks couple them, correlation up to 0.19) sampled 10000 times with Philox
// noise of fixed seeds. Each of the 78 entries of the 12 x 12 covariance, cross blocks included,
// must lie within 5 standard errors of M (false alarm ~1e-4 per sampler: the test is deterministic,
// its seeds fixed). Negative control: a sampler that drops the translation-rotation coupling
// (block-diagonal root) fails the same test.
class TwoSphereCovariance : public ::testing::Test {
 protected:
  static constexpr Index kSamples = 10000;

  // Products of two particles each: one thread, so that they do not wait on each other.
  void SetUp() override {
    saved_threads_ = omp_get_max_threads();
    omp_set_num_threads(1);
    op_.set_positions(std::vector<double>{0.0, 0.0, 0.0, 1.2, 1.2, 1.2}, std::vector<double>{1.0, 1.5});  // r = 2.08
    M_ = grand_dense(op_);
    Z_.resize(12, kSamples);
    for (Index k = 0; k < kSamples; ++k) Z_.col(k) = philox_noise(2, 91u, static_cast<std::uint64_t>(k));
  }

  /// Largest |C_ij - M_ij| / se_ij over the entries of the sample covariance C = W W^T / S, with
  /// the standard error of a Gaussian sample covariance, se_ij^2 = (M_ii M_jj + M_ij^2) / S.
  [[nodiscard]] double max_z_of(const MatrixXd& W) const {
    const double S = static_cast<double>(W.cols());
    const MatrixXd C = W * W.transpose() / S;
    double worst = 0.0;
    for (Index i = 0; i < M_.rows(); ++i)
      for (Index j = 0; j <= i; ++j) {
        const double se = std::sqrt((M_(i, i) * M_(j, j) + M_(i, j) * M_(i, j)) / S);
        worst = std::max(worst, std::abs(C(i, j) - M_(i, j)) / se);
      }
    return worst;
  }

  [[nodiscard]] double max_z(const SqrtOptions& options) const {
    MatrixXd W(12, kSamples);
    for (Index k = 0; k < kSamples; ++k) W.col(k) = sample(op_, Z_.col(k), options);
    return max_z_of(W);
  }

  void TearDown() override { omp_set_num_threads(saved_threads_); }

  DirectRpy op_{Geometry::open(), 0.5};
  MatrixXd M_, Z_;
  int saved_threads_ = 1;
};

TEST_F(TwoSphereCovariance, CrossBlocksCoupleAndAreTested) {
  double strongest = 0.0;  // largest translation-rotation correlation
  for (Index i = 0; i < 6; ++i)
    for (Index j = 6; j < 12; ++j) strongest = std::max(strongest, std::abs(M_(i, j)) / std::sqrt(M_(i, i) * M_(j, j)));
  EXPECT_GT(strongest, 0.15);
  MatrixXd decoupled = M_;
  decoupled.topRightCorner(6, 6).setZero();
  decoupled.bottomLeftCorner(6, 6).setZero();
  EXPECT_GT(max_z_of(sqrt_test::principal_sqrt(decoupled) * Z_), 5.0);
}

TEST_F(TwoSphereCovariance, Lanczos) {
  EXPECT_LT(max_z({.method = SqrtMethod::lanczos, .tolerance = 1e-8}), 5.0);
}

TEST_F(TwoSphereCovariance, BlockPreconditionedLanczos) {
  EXPECT_LT(max_z({.tolerance = 1e-8, .preconditioner = SqrtPreconditioner::block, .preconditioner_block = 1}), 5.0);
}

// Chebyshev with the bounds given: those of S M S (the scaled operator it runs on), padded.
TEST_F(TwoSphereCovariance, Chebyshev) {
  const VectorXd sd = scaling({1.0, 1.5});
  const VectorXd lambda = Eigen::SelfAdjointEigenSolver<MatrixXd>(sd.asDiagonal() * M_ * sd.asDiagonal()).eigenvalues();
  EXPECT_LT(max_z({.method = SqrtMethod::chebyshev,
                   .tolerance = 1e-6,
                   .lambda_min = 0.9 * lambda(0),
                   .lambda_max = 1.1 * lambda(11)}),
            5.0);
}

TEST_F(TwoSphereCovariance, Cholesky) {
  EXPECT_LT(max_z({.method = SqrtMethod::cholesky}), 5.0);
}

// Free draining: U = F / (6 pi eta a), W = T / (8 pi eta a^3), and the exact diagonal root for
// every method (to rounding: 4 ulp), with no operator products.
TEST(SqrtRotation, FreeDrainingIsExact) {
  const std::size_t N = 7;
  const double eta = 0.8;
  const Suspension s = suspension(N, true, 61u);
  FreeDrainingMobility op(Geometry::open(), eta);
  op.set_positions(s.x, s.a);
  ASSERT_TRUE(op.supports_rotation());
  const MatrixXd M = grand_dense(op);
  VectorXd diag(6 * N);
  for (std::size_t k = 0; k < 3 * N; ++k) {
    const double ai = s.a[k / 3];
    diag(static_cast<Index>(k)) = 1.0 / (6 * std::numbers::pi * eta * ai);
    diag(static_cast<Index>(3 * N + k)) = 1.0 / (8 * std::numbers::pi * eta * ai * ai * ai);
  }
  EXPECT_LE((M - MatrixXd(diag.asDiagonal())).norm(), 4e-16 * diag.norm());
  const VectorXd z = philox_noise(N, 7u, 0u);
  const VectorXd ref = diag.cwiseSqrt().cwiseProduct(z);
  for (SqrtMethod m : {SqrtMethod::automatic, SqrtMethod::lanczos, SqrtMethod::eigen}) {
    SqrtReport report;
    const VectorXd w = sample(op, z, {.method = m}, &report);
    EXPECT_EQ(report.method, SqrtMethod::cholesky);
    EXPECT_EQ(report.operator_applications, 0);
    for (Index k = 0; k < w.size(); ++k) EXPECT_NEAR(w(k), ref(k), 4e-16 * std::abs(ref(k))) << k;
  }
}

using rpyfmm::testing::TranslationOnly;

/// The code and message of the error `fn` throws (fails the test if it throws none).
template <class Fn>
std::pair<rpyfmm::ErrorCode, std::string> error_of(Fn&& fn) {
  try {
    fn();
  } catch (const rpyfmm::Error& e) {
    return {e.code(), e.what()};
  }
  ADD_FAILURE() << "no rpyfmm::Error thrown";
  return {rpyfmm::ErrorCode::io_error, ""};
}

TEST(SqrtRotation, BadInput) {
  using rpyfmm::ErrorCode;
  const std::size_t N = 5;
  const Suspension s = suspension(N, true, 71u);
  std::vector<double> zt(3 * N, 0.5), zr(3 * N, -0.5), wt(3 * N), wr(3 * N), shorter(3 * N - 1);
  DirectRpy op;
  EXPECT_EQ(error_of([&] { op.apply_sqrt_rotation(zt, zr, wt, wr); }).first, ErrorCode::invalid_input);  // no positions
  op.set_positions(s.x, s.a);
  for (int which = 0; which < 4; ++which) {
    auto [code, message] = error_of([&] {
      op.apply_sqrt_rotation(which == 0 ? shorter : zt, which == 1 ? shorter : zr, which == 2 ? shorter : wt,
                             which == 3 ? shorter : wr);
    });
    EXPECT_EQ(code, ErrorCode::invalid_input) << which;
    EXPECT_NE(message.find(which % 2 == 0 ? "translational" : "rotational"), std::string::npos) << message;
  }
  for (int which = 0; which < 2; ++which) {
    std::vector<double> bad = which == 0 ? zt : zr;
    bad[4] = std::nan("");
    auto [code, message] =
        error_of([&] { op.apply_sqrt_rotation(which == 0 ? bad : zt, which == 1 ? bad : zr, wt, wr); });
    EXPECT_EQ(code, ErrorCode::invalid_input);
    EXPECT_NE(message.find("NaN"), std::string::npos) << message;
  }
  EXPECT_EQ(error_of([&] { op.apply_sqrt_rotation(zt, zr, wt, wr, {.method = SqrtMethod::split}); }).first,
            ErrorCode::not_supported);
  EXPECT_EQ(error_of([&] { op.apply_sqrt_rotation(zt, zr, wt, wr, {.tolerance = 1.5}); }).first,
            ErrorCode::invalid_argument);
  EXPECT_EQ(error_of([&] {
              op.apply_sqrt_rotation(zt, zr, wt, wr,
                                     {.method = SqrtMethod::eigen, .preconditioner = SqrtPreconditioner::block});
            }).first,
            ErrorCode::invalid_argument);
  // The dense methods stop at 6N = kDenseSqrtMaxRows rows, i.e. 1000 particles with rotation.
  DirectRpy large;
  large.set_positions(sqrt_test::random_points(kDenseSqrtMaxRows / 6 + 1, 0.05, 72u), 1.0);
  std::vector<double> lz(3 * large.size(), 0.1), lw(3 * large.size());
  EXPECT_EQ(error_of([&] { large.apply_sqrt_rotation(lz, lz, lw, lw, {.method = SqrtMethod::eigen}); }).first,
            ErrorCode::out_of_memory);

  TranslationOnly plain;
  plain.set_positions(s.x, 1.0);
  auto [code, message] = error_of([&] { plain.apply_sqrt_rotation(zt, zr, wt, wr); });
  EXPECT_EQ(code, ErrorCode::not_supported);
  EXPECT_NE(message.find("translation-only"), std::string::npos) << message;
  EXPECT_NE(message.find("TranslationOnly::apply_sqrt_rotation"), std::string::npos) << message;
}

// Bitwise the same for 1 and 2 threads and on repeated calls (whatever was computed between
// them), for Lanczos, Chebyshev and block-preconditioned Lanczos.
TEST(SqrtRotation, SameOutputForThreadsAndCallHistory) {
  const std::size_t N = 150;
  const Suspension s = suspension(N, true, 81u);
  DirectRpy op;
  op.set_positions(s.x, s.a);
  const VectorXd z = philox_noise(N, 8u, 3u);
  const int saved = omp_get_max_threads();
  for (const SqrtOptions& options :
       {SqrtOptions{.method = SqrtMethod::lanczos}, SqrtOptions{.method = SqrtMethod::chebyshev},
        SqrtOptions{.preconditioner = SqrtPreconditioner::block}}) {
    omp_set_num_threads(1);
    const VectorXd w1 = sample(op, z, options);
    omp_set_num_threads(2);
    const VectorXd w2 = sample(op, z, options);
    sample(op, philox_noise(N, 9u, 0u), {.method = SqrtMethod::lanczos, .tolerance = 1e-2});  // other work
    const VectorXd w3 = sample(op, z, options);
    EXPECT_TRUE(w1 == w2) << to_string(options.method) << " " << to_string(options.preconditioner);
    EXPECT_TRUE(w2 == w3) << to_string(options.method) << " " << to_string(options.preconditioner);
  }
  omp_set_num_threads(saved);
}

}  // namespace
