// PSE split sampler statistics (label slow): covariance of M_r^{1/2} z1 + M_w^{1/2} z2
// equals M, and the Fourier-space noise alone has covariance M_w (fixed seeds).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "ewald_reference.hpp"
#include "pse_sampler_util.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/random.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;
using pse_test::dense;
using pse_test::SmallSystem;

namespace {

/// max_ij |C_ij - M_ij| / sqrt(M_ii M_jj): the standard error of C_ij is <= sqrt(2 / n_s).
double covariance_error(const Eigen::MatrixXd& C, const Eigen::MatrixXd& M) {
  double worst = 0.0;
  for (Eigen::Index i = 0; i < M.rows(); ++i)
    for (Eigen::Index j = 0; j < M.cols(); ++j)
      worst = std::max(worst, std::abs(C(i, j) - M(i, j)) / std::sqrt(M(i, i) * M(j, j)));
  return worst;
}

/// fill_normal's values (normal3 per particle), serially: the statistical loops call it
/// thousands of times on tiny vectors.
void normals(std::vector<double>& z, std::uint64_t seed, std::uint64_t step, std::uint32_t stream = 0) {
  for (std::size_t i = 0; i < z.size() / 3; ++i) normal3(seed, step, stream, i, &z[3 * i]);
}

}  // namespace

TEST(PseSampler, SplitSampleCovarianceEqualsM) {
  // Both wave-grid precisions: double, and single (the automatic choice at this tolerance).
  for (const auto precision : {WavePrecision::double_precision, WavePrecision::single_precision}) {
    SCOPED_TRACE(precision == WavePrecision::single_precision ? "single-precision wave grids" : "double");
    const SmallSystem s;
    PseOptions o = s.options();
    o.wave_precision = precision;
    PseRpy op(Geometry::periodic(s.L[0], s.L[1], s.L[2]), 1.0, o);
    op.set_positions(s.x, 1.0);
    const Eigen::MatrixXd M = dense(op);
    const int ns = 5000;
    const auto n = static_cast<Eigen::Index>(s.x.size());
    Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n, n);
    Eigen::MatrixXd Cz = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd mean = Eigen::VectorXd::Zero(n);
    std::vector<double> w(s.x.size()), z(s.x.size()), v(s.x.size());
    for (int k = 0; k < ns; ++k) {
      op.sample(2024, static_cast<std::uint64_t>(k), w);  // keyed (seed, step)
      const Eigen::Map<const Eigen::VectorXd> e(w.data(), n);
      C += e * e.transpose();
      mean += e;
      normals(z, 77, static_cast<std::uint64_t>(k));  // apply_sqrt: z1 = z, z2 from hash(z)
      const SqrtReport rep = op.apply_sqrt(z, v);
      EXPECT_EQ(rep.method, SqrtMethod::split);
      const Eigen::Map<const Eigen::VectorXd> ev(v.data(), n);
      Cz += ev * ev.transpose();
    }
    C /= ns;
    Cz /= ns;
    mean /= ns;
    const double bound = 5.0 * std::sqrt(2.0 / ns);  // 5 standard errors
    EXPECT_LT(covariance_error(C, M), bound);
    EXPECT_LT(covariance_error(Cz, M), bound);
    for (Eigen::Index i = 0; i < n; ++i) EXPECT_LT(std::abs(mean(i)) / std::sqrt(M(i, i)), 5.0 / std::sqrt(ns));
    // The sample is a deterministic function of its key / of z.
    std::vector<double> w2(w.size());
    op.sample(2024, 3, w);
    op.sample(2024, 3, w2);
    EXPECT_EQ(w, w2);
  }
}

TEST(PseSampler, WaveNoiseAloneHasCovarianceMw) {
  // Isolates the Fourier-space noise (conjugate symmetry, scaling, projection): the sample
  // minus its real-space part (Lanczos on M_r with the documented z1 = fill_normal(seed,
  // step, stream 1), recomputed here) must have covariance M_w.
  const SmallSystem s;
  PseRpy op(Geometry::periodic(s.L[0], s.L[1], s.L[2]), 1.0, s.options());
  op.set_positions(s.x, 1.0);
  const auto n = static_cast<Eigen::Index>(s.x.size());
  Eigen::MatrixXd Mw(n, n);
  {
    Eigen::MatrixXd I = Eigen::MatrixXd::Identity(n, n);
    op.wave_space_operator().apply(std::span<const double>(I.data(), I.size()), std::span<double>(Mw.data(), Mw.size()),
                                   static_cast<std::size_t>(n));
  }
  SqrtOptions so;
  so.method = SqrtMethod::lanczos;
  so.tolerance = op.parameters().lanczos_tolerance;
  const int ns = 5000;
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n, n);
  std::vector<double> zero(s.x.size(), 0.0), u(s.x.size()), y(s.x.size()), z1(s.x.size());
  for (int k = 0; k < ns; ++k) {
    const double scale = 1.7;  // BD's sqrt(2 kT/dt): covariance scale^2 M_w
    op.apply_with_noise(zero, scale, 99, static_cast<std::uint64_t>(k), u);
    normals(z1, 99, static_cast<std::uint64_t>(k), 1);
    sqrt_apply(op.real_space_operator(), z1, y, 1, so);
    Eigen::VectorXd e(n);

    for (Eigen::Index i = 0; i < n; ++i)
      e(i) = (u[static_cast<std::size_t>(i)] - scale * y[static_cast<std::size_t>(i)]) / scale;
    C += e * e.transpose();
  }
  C /= ns;
  EXPECT_LT(covariance_error(C, Mw), 5.0 * std::sqrt(2.0 / ns));
}

TEST(PseSampler, RotationSplitSampleCovarianceEqualsGrandMobility) {
  // E[w w^T] = M for w = [w_t; w_r] by the split sampler, z keyed per sample; entries compared
  // in the S-scaled units (torque rows and columns times a) to 5x the standard error of the
  // largest entry.
  const std::array<double, 3> L = {6.0, 6.0, 6.0};
  const std::vector<double> x = {1.0, 1.0, 1.0, 2.2, 1.5, 1.0, 4.0, 4.0, 3.0};
  const double a = 0.8;
  PseOptions o;
  o.tolerance = 1e-4;
  PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
  op.set_positions(x, a);
  const Eigen::Index n6 = 18;
  Eigen::MatrixXd M = pse_test::grand_matrix(op);
  Eigen::VectorXd s = Eigen::VectorXd::Ones(n6);
  s.tail(9).setConstant(a);
  M = s.asDiagonal() * M * s.asDiagonal();
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n6, n6);
  const int samples = 12000;
  std::vector<double> z(18), wt(9), wr(9);
  SqrtOptions so;
  so.method = SqrtMethod::split;
  for (int k = 0; k < samples; ++k) {
    fill_normal(z, 11, static_cast<std::uint64_t>(k));
    const SqrtReport rep = op.apply_sqrt_rotation(std::span(z).first(9), std::span(z).last(9), wt, wr, so);
    ASSERT_EQ(rep.method, SqrtMethod::split);
    Eigen::VectorXd w(n6);
    for (int c = 0; c < 9; ++c) {
      w(c) = wt[static_cast<std::size_t>(c)];
      w(9 + c) = a * wr[static_cast<std::size_t>(c)];
    }
    C += w * w.transpose();
  }
  C /= samples;
  const double m = M.diagonal().maxCoeff();
  EXPECT_LE((C - M).cwiseAbs().maxCoeff(), 5.0 * m * std::sqrt(2.0 / samples));
}
