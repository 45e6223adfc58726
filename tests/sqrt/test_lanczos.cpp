// Properties of the Lanczos square root: known spectra, breakdown, block
// variant, thread independence, the stopping test vs the true error.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "../../rpy/src/sqrt/detail.hpp"        // dots, subtract_combination
#include "../../rpy/src/sqrt/krylov.hpp"        // LanczosProcess
#include "../../rpy/src/sqrt/krylov_space.hpp"  // KrylovSpace, lanczos_sqrt_in_space
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/core/validate.hpp"  // fail
#include "sqrt_test_util.hpp"

using namespace rpyfmm::rpy;

namespace {

std::span<const double> cspan(const Eigen::VectorXd& v) {
  return {v.data(), static_cast<std::size_t>(v.size())};
}
std::span<double> mspan(Eigen::VectorXd& v) {
  return {v.data(), static_cast<std::size_t>(v.size())};
}

/// Q diag(lambda) Q^T with a random orthogonal Q (fixed seed).
Eigen::MatrixXd with_spectrum(const Eigen::VectorXd& lambda, std::uint32_t seed) {
  const auto n = lambda.size();
  Eigen::MatrixXd G(n, n);
  const Eigen::VectorXd g = sqrt_test::gaussian(n * n, seed);
  G = Eigen::Map<const Eigen::MatrixXd>(g.data(), n, n);
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(G);
  const Eigen::MatrixXd Q = qr.householderQ();
  return Q * lambda.asDiagonal() * Q.transpose();
}

// A matrix with k distinct eigenvalues has a minimal polynomial of degree k:
// the Krylov space is invariant after k steps, Lanczos breaks down there and
// the result is exact (Saad, Iterative Methods, Prop. 6.6 / sec. 6.3).
TEST(Lanczos, KDistinctEigenvaluesConvergeInKSteps) {
  for (int k : {1, 2, 3, 5, 8}) {
    const int n = 120;
    Eigen::VectorXd lambda(n);
    for (int i = 0; i < n; ++i) lambda[i] = 0.5 + 1.7 * (i % k);
    const Eigen::MatrixXd M = with_spectrum(lambda, 5u + static_cast<std::uint32_t>(k));
    const auto op = sqrt_test::view_of(M);
    const Eigen::VectorXd z = sqrt_test::gaussian(n, 9u);
    Eigen::VectorXd w(n);
    SqrtOptions opt;
    opt.method = SqrtMethod::lanczos;
    opt.tolerance = 1e-14;  // stopping can only come from the breakdown
    const SqrtReport rep = sqrt_apply(op, cspan(z), mspan(w), 1, opt);
    EXPECT_EQ(rep.iterations, k) << "k = " << k;
    EXPECT_TRUE(rep.breakdown);
    const Eigen::VectorXd ref = sqrt_test::principal_sqrt(M) * z;
    EXPECT_LE((w - ref).norm() / ref.norm(), 1e-11) << "k = " << k;
  }
}

// z an eigenvector: K_1 is invariant, one step, exact sqrt(lambda) z.
TEST(Lanczos, BreakdownOnEigenvector) {
  const auto x = sqrt_test::random_points(30, 0.1, 3u);
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(x, sqrt_test::radii(30, true, 4u));
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M);
  for (Eigen::Index idx : {Eigen::Index{0}, Eigen::Index{17}, M.rows() - 1}) {
    const Eigen::VectorXd z = 2.5 * es.eigenvectors().col(idx);
    Eigen::VectorXd w(M.rows());
    SqrtOptions opt;
    opt.method = SqrtMethod::lanczos;
    const SqrtReport rep = sqrt_apply(sqrt_test::view_of(M), cspan(z), mspan(w), 1, opt);
    EXPECT_EQ(rep.iterations, 1);
    EXPECT_TRUE(rep.breakdown);
    EXPECT_EQ(rep.error_estimate, 0.0);
    const Eigen::VectorXd ref = std::sqrt(es.eigenvalues()[idx]) * z;
    EXPECT_LE((w - ref).norm() / ref.norm(), 1e-12);
  }
}

// The identity: one step, w = z.
TEST(Lanczos, IdentityAndZeroVector) {
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(12, 12) * 4.0;
  const Eigen::VectorXd z = sqrt_test::gaussian(12, 1u);
  Eigen::VectorXd w(12);
  const SqrtReport rep = sqrt_apply(sqrt_test::view_of(I), cspan(z), mspan(w), 1, {});
  EXPECT_EQ(rep.iterations, 1);
  EXPECT_LE((w - 2.0 * z).norm(), 1e-14 * z.norm());
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(12);
  const SqrtReport rz = sqrt_apply(sqrt_test::view_of(I), cspan(zero), mspan(w), 1, {});
  EXPECT_EQ(rz.iterations, 0);
  EXPECT_EQ(rz.operator_applications, 0);
  EXPECT_EQ(w.norm(), 0.0);
}

// Block variant: identical to one-at-a-time, with one operator call per
// iteration serving every right-hand side still iterating.
TEST(Lanczos, BlockMatchesSingleWithOneCallPerIteration) {
  const std::size_t N = 80;
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(sqrt_test::random_points(N, 0.1, 8u), sqrt_test::radii(N, true, 2u));
  const auto n = M.rows();
  const std::size_t nrhs = 4;
  Eigen::MatrixXd Z(n, nrhs);
  for (std::size_t k = 0; k < nrhs; ++k) Z.col(static_cast<Eigen::Index>(k)) = sqrt_test::gaussian(n, 20u + k);
  Z.col(2) *= 1e-3;  // scaling must not matter for the relative test
  Eigen::MatrixXd W(n, nrhs);
  int calls = 0;
  auto op = sqrt_test::view_of(M);
  auto inner = op.apply;
  op.apply = [&](std::span<const double> x, std::span<double> y, std::size_t k) {
    ++calls;
    inner(x, y, k);
  };
  SqrtOptions opt;
  opt.tolerance = 1e-6;
  const SqrtReport rep = sqrt_apply(op, {Z.data(), static_cast<std::size_t>(Z.size())},
                                    {W.data(), static_cast<std::size_t>(W.size())}, nrhs, opt);
  EXPECT_EQ(calls, rep.operator_applications);
  EXPECT_EQ(rep.operator_applications, rep.iterations);
  EXPECT_LT(rep.vector_products, static_cast<long long>(nrhs) * rep.iterations + 1);
  int max_single = 0;
  for (std::size_t k = 0; k < nrhs; ++k) {
    const Eigen::VectorXd z = Z.col(static_cast<Eigen::Index>(k));
    Eigen::VectorXd w(n);
    const SqrtReport r1 = sqrt_apply(op, cspan(z), mspan(w), 1, opt);
    max_single = std::max(max_single, r1.iterations);
    EXPECT_LE((W.col(static_cast<Eigen::Index>(k)) - w).norm(), 1e-13 * w.norm());
  }
  EXPECT_EQ(rep.iterations, max_single);
}

// Results do not depend on the number of OpenMP threads (bit for bit), for
// a size where the inner products run in parallel chunks.
TEST(Lanczos, SameOutputForOneAndTwoThreads) {
  const Eigen::Index n = 30000;
  Eigen::VectorXd d(n);
  for (Eigen::Index i = 0; i < n; ++i) d[i] = 1.0 + std::sin(0.37 * i) * 0.9;
  rpyfmm::rpy::LinearOperatorView op;
  op.n = static_cast<std::size_t>(n);
  op.apply = [&](std::span<const double> x, std::span<double> y, std::size_t nrhs) {
    // Tridiagonal SPD (diagonally dominant) operator with coupling.
    for (std::size_t k = 0; k < nrhs; ++k)
      for (Eigen::Index i = 0; i < n; ++i) {
        const std::size_t o = k * static_cast<std::size_t>(n);
        double v = (1.5 + 2.5 * d[i]) * x[o + i];
        if (i > 0) v += 0.5 * x[o + i - 1];
        if (i + 1 < n) v += 0.5 * x[o + i + 1];
        y[o + i] = v;
      }
  };
  const Eigen::VectorXd z = sqrt_test::gaussian(2 * n, 77u);
  Eigen::VectorXd w1(2 * n), w2(2 * n);
  SqrtOptions opt;
  opt.tolerance = 1e-8;
  const int saved = omp_get_max_threads();
  for (SqrtMethod m : {SqrtMethod::lanczos, SqrtMethod::chebyshev}) {
    opt.method = m;
    omp_set_num_threads(1);
    const SqrtReport r1 = sqrt_apply(op, cspan(z), mspan(w1), 2, opt);
    omp_set_num_threads(2);
    const SqrtReport r2 = sqrt_apply(op, cspan(z), mspan(w2), 2, opt);
    EXPECT_EQ(r1.iterations, r2.iterations);
    EXPECT_EQ((w1 - w2).cwiseAbs().maxCoeff(), 0.0) << to_string(m);
  }
  omp_set_num_threads(saved);
}

// The stopping test (relative change < tol) vs the true error: the true error
// is below 10 tol and iterations grow as the tolerance shrinks.
TEST(Lanczos, StoppingTestTracksTrueError) {
  const std::size_t N = 150;
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(sqrt_test::random_points(N, 0.2, 6u), sqrt_test::radii(N, false, 0u));
  const Eigen::VectorXd z = sqrt_test::gaussian(M.rows(), 12u);
  const Eigen::VectorXd ref = sqrt_test::principal_sqrt(M) * z;
  int prev_it = 0;
  for (double tol : {1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9}) {
    Eigen::VectorXd w(M.rows());
    SqrtOptions opt;
    opt.tolerance = tol;
    const SqrtReport rep = sqrt_apply(sqrt_test::view_of(M), cspan(z), mspan(w), 1, opt);
    const double err = (w - ref).norm() / ref.norm();
    EXPECT_LE(err, 10 * tol) << "tol " << tol;
    EXPECT_GE(rep.iterations, prev_it);
    prev_it = rep.iterations;
  }
}

// Without reorthogonalization the method still converges on a well
// conditioned RPY matrix (the basis loses orthogonality only slowly).
TEST(Lanczos, WithoutReorthogonalization) {
  const std::size_t N = 100;
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(sqrt_test::random_points(N, 0.1, 16u), sqrt_test::radii(N, true, 3u));
  const Eigen::VectorXd z = sqrt_test::gaussian(M.rows(), 2u);
  const Eigen::VectorXd ref = sqrt_test::principal_sqrt(M) * z;
  Eigen::VectorXd w(M.rows());
  SqrtOptions opt;
  opt.tolerance = 1e-6;
  opt.reorthogonalize = false;
  sqrt_apply(sqrt_test::view_of(M), cspan(z), mspan(w), 1, opt);
  EXPECT_LE((w - ref).norm() / ref.norm(), 1e-5);
}

// max_iterations reached: throw by default, or return the iterate flagged
// not converged.
TEST(Lanczos, MaxIterations) {
  const std::size_t N = 100;
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(sqrt_test::random_points(N, 0.2, 1u), sqrt_test::radii(N, true, 3u));
  const Eigen::VectorXd z = sqrt_test::gaussian(M.rows(), 2u);
  Eigen::VectorXd w(M.rows());
  SqrtOptions opt;
  opt.tolerance = 1e-10;
  opt.max_iterations = 3;
  try {
    sqrt_apply(sqrt_test::view_of(M), cspan(z), mspan(w), 1, opt);
    FAIL() << "expected rpyfmm::Error";
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), rpyfmm::ErrorCode::numerical_failure);
    EXPECT_NE(std::string(e.what()).find("no convergence in 3 iterations"), std::string::npos) << e.what();
  }
  opt.throw_if_not_converged = false;
  const SqrtReport rep = sqrt_apply(sqrt_test::view_of(M), cspan(z), mspan(w), 1, opt);
  EXPECT_FALSE(rep.converged);
  EXPECT_EQ(rep.iterations, 3);
  EXPECT_GT(rep.error_estimate, 1e-10);
  EXPECT_TRUE(w.allFinite());
}

}  // namespace

TEST(Lanczos, ReorthogonalizedBasisStaysOrthonormal) {
  // Eigenvalues spread geometrically over 1e-8 ... 1: the largest Ritz values converge within a
  // few steps, and plain Lanczos then loses the orthogonality of its basis (Paige). With full
  // reorthogonalization (classical Gram-Schmidt twice) the basis of 80 steps stays orthonormal
  // to round-off: |V^T V - I| <= 1e-12 (n = 400, unit round-off 1.1e-16 times a few hundred
  // terms); without it the same run is far from orthonormal, so the test can tell the two apart.
  const int n = 400, steps = 80;
  Eigen::VectorXd lambda(n);
  for (int i = 0; i < n; ++i) lambda[i] = std::pow(10.0, -8.0 * i / (n - 1));
  const Eigen::VectorXd z = sqrt_test::gaussian(n, 5);
  auto basis_error = [&](bool reorthogonalize) {
    sqrt_detail::LanczosProcess process(n, reorthogonalize);
    process.start(z.data());
    Eigen::VectorXd y(n);
    for (int it = 0; it < steps; ++it) {
      y = lambda.cwiseProduct(Eigen::Map<const Eigen::VectorXd>(process.current(), n));
      EXPECT_FALSE(process.step(y.data(), "test", 0)) << "breakdown at step " << it;
    }
    Eigen::MatrixXd V(n, steps);
    for (int k = 0; k < steps; ++k) {
      Eigen::VectorXd unit = Eigen::VectorXd::Unit(steps, k);
      Eigen::VectorXd v(n);
      process.combine(unit, v.data());
      V.col(k) = v;
    }
    return (V.transpose() * V - Eigen::MatrixXd::Identity(steps, steps)).cwiseAbs().maxCoeff();
  };
  EXPECT_LE(basis_error(true), 1e-12);
  EXPECT_GE(basis_error(false), 1e-3);
}

TEST(Lanczos, GramSchmidtKernels) {
  // dots() gives dot() of every vector bit for bit (same chunks, same order), for lengths below,
  // at and above the chunk of 4096 and with 1 and 2 threads; subtract_combination() against the
  // sum written out.
  for (const std::size_t n : {std::size_t{7}, std::size_t{4096}, std::size_t{20011}}) {
    std::vector<std::vector<double>> v;
    for (std::uint32_t q = 0; q < 5; ++q) {
      const Eigen::VectorXd g = sqrt_test::gaussian(static_cast<Eigen::Index>(n), 10 + q);
      v.emplace_back(g.data(), g.data() + n);
    }
    const Eigen::VectorXd yv = sqrt_test::gaussian(static_cast<Eigen::Index>(n), 20);
    std::vector<double> y(yv.data(), yv.data() + n), h(v.size());
    const int saved = omp_get_max_threads();
    for (int threads : {1, 2}) {
      omp_set_num_threads(threads);
      sqrt_detail::dots(v, y.data(), n, h.data());
      for (std::size_t q = 0; q < v.size(); ++q) EXPECT_EQ(h[q], sqrt_detail::dot(v[q].data(), y.data(), n));
    }
    omp_set_num_threads(saved);
    std::vector<double> expected = y, got = y;
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t q = 0; q < v.size(); ++q) expected[i] -= h[q] * v[q][i];
    sqrt_detail::subtract_combination(v, h.data(), got.data(), n);
    for (std::size_t i = 0; i < n; ++i) EXPECT_NEAR(got[i], expected[i], 1e-13 * (1.0 + std::abs(expected[i])));
  }
}

namespace {

/// A Krylov space whose vectors live out of the iteration's reach, as device vectors do for the
/// CUDA PSE sampler: its "pointers" are handles (addresses in the first page, which any
/// dereference would fault on), resolved to host storage only inside the space's operations and
/// the product. Its inner products sum in another order than the host kernels (blocks of 7,
/// then the blocks), as a device reduction would.
class HandleSpace final : public sqrt_detail::KrylovSpace {
 public:
  explicit HandleSpace(std::size_t n) : n_(n) {}
  [[nodiscard]] std::size_t n() const override { return n_; }
  void clear() override { count_ = 0; }
  double* push() override {
    if (count_ == basis_.size()) basis_.emplace_back(n_);
    return handle(count_++);
  }
  [[nodiscard]] double* vector(std::size_t q) override { return handle(q); }
  [[nodiscard]] std::size_t basis_size() const override { return count_; }
  [[nodiscard]] double* work() override { return handle(kWork); }
  double dot(const double* x, const double* y) override {
    const double* a = data(x);
    const double* b = data(y);
    double total = 0.0;
    for (std::size_t lo = 0; lo < n_; lo += 7) {
      double block = 0.0;
      for (std::size_t i = lo; i < std::min(n_, lo + 7); ++i) block += a[i] * b[i];
      total += block;
    }
    return total;
  }
  void dots(std::size_t k, const double* y, double* h) override {
    for (std::size_t q = 0; q < k; ++q) h[q] = dot(handle(q), y);
  }
  void subtract_combination(std::size_t k, const double* h, double* y) override {
    for (std::size_t q = 0; q < k; ++q) axpy(-h[q], handle(q), y);
  }
  void axpy(double a, const double* x, double* y) override {
    const double* xs = data(x);
    double* ys = data(y);
    for (std::size_t i = 0; i < n_; ++i) ys[i] += a * xs[i];
  }
  void scale_into(double a, const double* x, double* out) override {
    const double* xs = data(x);
    double* o = data(out);
    for (std::size_t i = 0; i < n_; ++i) o[i] = a * xs[i];
  }
  void combine(std::size_t k, const double* c, double* out) override {
    double* o = data(out);
    std::fill(o, o + n_, 0.0);
    for (std::size_t q = 0; q < k; ++q) axpy(c[q], handle(q), out);
  }
  void require_finite(const double* y, const char* where, long long product) override {
    const double* v = data(y);
    for (std::size_t i = 0; i < n_; ++i)
      if (!std::isfinite(v[i]))
        rpyfmm::fail(rpyfmm::ErrorCode::numerical_failure, where, "non-finite product " + std::to_string(product));
  }
  /// Handles of the caller's vectors (input z, output w), and their storage.
  double* input() { return handle(kInput); }
  double* output() { return handle(kOutput); }
  /// The storage behind a handle.
  double* data(const double* h) {
    const auto id = (reinterpret_cast<std::uintptr_t>(h) - kBase) / 8;
    if (id == kWork) return work_.data();
    if (id == kInput) return input_.data();
    if (id == kOutput) return output_.data();
    return basis_.at(id).data();
  }

 private:
  static constexpr std::uintptr_t kBase = 64;
  static constexpr std::size_t kWork = 400, kInput = 401, kOutput = 402;
  static double* handle(std::size_t id) { return reinterpret_cast<double*>(kBase + 8 * id); }
  std::size_t n_;
  std::vector<std::vector<double>> basis_;
  std::size_t count_ = 0;
  std::vector<double> work_ = std::vector<double>(n_), input_ = std::vector<double>(n_),
                      output_ = std::vector<double>(n_);
};

}  // namespace

TEST(Lanczos, IterationOnAnotherMemorySpace) {
  // lanczos_sqrt_in_space touches vectors only through the space and the product (the CUDA
  // sampler's contract): on handle "pointers" it runs without faulting and gives the host
  // result, to round-off of the other summation order, with the same iteration count.
  const int N = 60;
  const Eigen::MatrixXd M = sqrt_test::rpy_matrix(sqrt_test::random_points(N, 0.3, 4u), sqrt_test::radii(N, false, 5u));
  const Eigen::VectorXd z = sqrt_test::gaussian(M.rows(), 6u);
  const auto n = static_cast<std::size_t>(M.rows());
  SqrtOptions opt;
  opt.method = SqrtMethod::lanczos;
  opt.tolerance = 1e-8;
  Eigen::VectorXd w_host(M.rows());
  const SqrtReport host = sqrt_apply(sqrt_test::view_of(M), cspan(z), mspan(w_host), 1, opt);

  HandleSpace space(n);
  std::copy_n(z.data(), n, space.data(space.input()));
  long long products = 0;
  const SqrtReport other = sqrt_detail::lanczos_sqrt_in_space(
      space,
      [&](const double* x, double* y) {
        ++products;
        Eigen::Map<Eigen::VectorXd>(space.data(y), M.rows()) =
            M * Eigen::Map<const Eigen::VectorXd>(space.data(x), M.rows());
      },
      space.input(), space.output(), opt);
  const Eigen::VectorXd w_other = Eigen::Map<const Eigen::VectorXd>(space.data(space.output()), M.rows());
  EXPECT_EQ(other.iterations, host.iterations);
  EXPECT_EQ(other.operator_applications, products);
  EXPECT_TRUE(other.converged);
  EXPECT_LT((w_other - w_host).norm() / w_host.norm(), 1e-12);
  // A second right-hand side in the same space (the basis memory is reused) and a zero vector.
  std::fill_n(space.data(space.input()), n, 0.0);
  const SqrtReport zero = sqrt_detail::lanczos_sqrt_in_space(
      space, [&](const double*, double*) { FAIL() << "no product for z = 0"; }, space.input(), space.output(), opt);
  EXPECT_EQ(zero.iterations, 0);
  EXPECT_EQ(Eigen::Map<const Eigen::VectorXd>(space.data(space.output()), M.rows()).norm(), 0.0);
}
