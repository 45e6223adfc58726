// PSE grand mobility with rotation ([U; W] = M [F; T], docs/theory/pse.md "Rotation") against an
// independent direct Ewald sum (ewald_rotation_reference.hpp), its own consistency (xi independence,
// agreement with the translational reference and product), symmetry and positive definiteness of
// the 6N matrix, repeatability, and the split sampler's 6N covariance.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Dense>
#include <cmath>
#include <numbers>

#include "ewald_reference.hpp"
#include "ewald_rotation_reference.hpp"
#include "pse_sampler_util.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/rotation_real_space.hpp"
#include "rpyfmm/rpy/random.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;
using pse_test::rel_l2;

namespace {

constexpr double kPi = std::numbers::pi;

/// 24 random spheres (overlaps included) plus an overlapping pair, a touching pair and a pair
/// across the periodic x boundary.
std::vector<double> configuration(const std::array<double, 3>& L) {
  std::vector<double> x = {2.0, 2.0, 2.0, 2.0,        2.0, 3.1,   // overlap, r = 1.1a
                           5.0, 5.0, 5.0, 7.0,        5.0, 5.0,   // touching, r = 2a
                           0.3, 6.0, 6.0, L[0] - 0.6, 6.0, 6.0};  // across the boundary, r = 0.9a
  const auto extra = pse_test::random_points(24, L, 17);
  x.insert(x.end(), extra.begin(), extra.end());
  return x;
}

std::vector<double> loads(std::size_t n, unsigned seed) {
  auto v = pse_test::random_points(n, {2.0, 2.0, 2.0}, seed);
  for (auto& e : v) e -= 1.0;
  return v;
}

pse_test::GrandVectors product(const PseRpy& op, const std::vector<double>& F, const std::vector<double>& T) {
  pse_test::GrandVectors out{std::vector<double>(F.size()), std::vector<double>(F.size())};
  op.apply(F, T, out.u, out.w);
  return out;
}

}  // namespace

TEST(PseRotationReference, IndependentOfSplittingAndConsistentWithTranslationalReference) {
  // The reference's real and wave halves change with xi; their sum must not.
  const std::array<double, 3> L = {9.0, 10.0, 11.0};
  const auto x = configuration(L);
  const std::size_t n3 = x.size();
  const auto F = loads(n3 / 3, 3), T = loads(n3 / 3, 4);
  const auto a = pse_test::ewald_rotation_reference(x, 1.0, 1.0, L, F, T, 0.6);
  const auto b = pse_test::ewald_rotation_reference(x, 1.0, 1.0, L, F, T, 1.3);
  EXPECT_LT(rel_l2(a.u, b.u), 1e-11);
  EXPECT_LT(rel_l2(a.w, b.w), 1e-11);
  // With T = 0, U is the translational periodic RPY product of the plain Ewald reference.
  const std::vector<double> zero(n3, 0.0);
  const auto c = pse_test::ewald_rotation_reference(x, 1.0, 1.0, L, F, zero, 0.9);
  EXPECT_LT(rel_l2(c.u, pse_test::ewald_reference(x, 1.0, 1.0, L, F, 0.9)), 1e-11);
}

TEST(PseRotationRealSpace, KernelMatchesReferenceQuadratureInEveryRegime) {
  // The operator's Gauss-Legendre transform against the reference's trapezoidal one, free part
  // subtracted: overlapping (r < 2a), touching, far, and the self term.
  for (const double xi : {0.5, 1.0, 3.0}) {
    for (const double r : {0.0, 0.01, 0.7, 1.5, 2.0, 2.5, 4.0}) {
      const RotationCoefficients got = rotation_real_space(r, xi, 1.0);
      const auto wave = pse_test::wave_in_real_space(r, xi, 1.0);
      RotationCoefficients want{-wave.c, 1.0 / (8.0 * kPi) - wave.h, -wave.k};
      if (r > 0.0) {
        const RpyRotationScalars s = rpy_rotation_scalars(r, 1.0, 1.0);
        want = {s.ut - wave.c, s.h - wave.h, s.k - wave.k};
      }
      const double unit = 1.0 / (8.0 * kPi);  // the self coefficient, the largest
      EXPECT_NEAR(got.c, want.c, 1e-13 * unit) << "xi " << xi << " r " << r;
      EXPECT_NEAR(got.h, want.h, 1e-13 * unit) << "xi " << xi << " r " << r;
      EXPECT_NEAR(got.k, want.k, 1e-13 * unit) << "xi " << xi << " r " << r;
    }
  }
}

TEST(PseRotationRealSpace, TableWithinItsTolerance) {
  const double xi = 0.8, a = 1.0, r_cut = real_space_cutoff(1e-7, xi, a), eps_t = 1e-7;
  const PseRotationTable table(xi, a, r_cut, eps_t);
  const double unit_c = 1.0 / (6.0 * kPi * a * a), unit_hk = unit_c / a;
  for (double r = 0.0; r < r_cut; r += 0.0173 * a) {
    const RotationCoefficients t = table(r), e = rotation_real_space(r, xi, a);
    EXPECT_NEAR(t.c, e.c, 1.5 * eps_t * unit_c) << r;
    EXPECT_NEAR(t.h, e.h, 1.5 * eps_t * unit_hk) << r;
    EXPECT_NEAR(t.k, e.k, 1.5 * eps_t * unit_hk) << r;
  }
}

/// Relative l2 error of [U; a W] (the 6N product in the samplers' scaling S = diag(I, a I), in which
/// the tolerance means the same for translation and rotation, docs/theory/pse.md "Rotation").
double scaled_error(const pse_test::GrandVectors& got, const pse_test::GrandVectors& ref, double a) {
  double num = 0.0, den = 0.0;
  for (std::size_t k = 0; k < ref.u.size(); ++k) {
    num += (got.u[k] - ref.u[k]) * (got.u[k] - ref.u[k]) + a * a * (got.w[k] - ref.w[k]) * (got.w[k] - ref.w[k]);
    den += ref.u[k] * ref.u[k] + a * a * ref.w[k] * ref.w[k];
  }
  return std::sqrt(num / den);
}

TEST(PseRotation, WithinToleranceOfEwaldReference) {
  // The relative error of the scaled 6N product [U; a W] for loads [F; T / a] is <= tolerance, for
  // forces alone, torques alone and both; single-precision wave grids at 1e-3 and 1e-5, double ones
  // at 1e-7. (Per block, the couplings alone, W from F and U from T, have no self term and carry up
  // to ~2x the tolerance relative to their own, smaller norm: the parameters bound errors on the
  // scale of the self mobilities.)
  const std::array<double, 3> L = {9.0, 10.0, 11.0};
  const auto x = configuration(L);
  const std::size_t n3 = x.size();
  const std::vector<double> zero(n3, 0.0);
  const auto F = loads(n3 / 3, 5), T = loads(n3 / 3, 6);
  for (const double eps : {1e-3, 1e-5, 1e-7}) {
    PseOptions o;
    o.tolerance = eps;
    PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.3, o);
    op.set_positions(x, 1.0);
    for (int kind = 0; kind < 3; ++kind) {
      const auto& f = kind == 1 ? zero : F;
      const auto& t = kind == 0 ? zero : T;
      const auto ref = pse_test::ewald_rotation_reference(x, 1.0, 1.3, L, f, t, 0.8);
      const auto got = product(op, f, t);
      EXPECT_LE(scaled_error(got, ref, 1.0), eps)
          << "eps " << eps << " loads " << kind << " (U " << rel_l2(got.u, ref.u) << ", W " << rel_l2(got.w, ref.w)
          << ") " << op.parameters().summary();
      if (kind == 2) {  // both loads: each block on its own within the tolerance
        EXPECT_LE(rel_l2(got.u, ref.u), eps) << "U, eps " << eps;
        EXPECT_LE(rel_l2(got.w, ref.w), eps) << "W, eps " << eps;
      }
    }
  }
}

TEST(PseRotation, ForceOnlyVelocitiesEqualTheTranslationalProduct) {
  const std::array<double, 3> L = {9.0, 10.0, 11.0};
  const auto x = configuration(L);
  const auto F = loads(x.size() / 3, 7);
  const std::vector<double> zero(x.size(), 0.0);
  for (const auto& [precision, roundoff] :
       {std::pair{WavePrecision::double_precision, 1e-13}, std::pair{WavePrecision::single_precision, 1e-6}}) {
    PseOptions o;
    o.tolerance = 1e-4;
    o.wave_precision = precision;
    PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
    op.set_positions(x, 1.0);
    std::vector<double> u(x.size());
    op.apply(F, u);
    EXPECT_LT(rel_l2(product(op, F, zero).u, u), roundoff);
  }
}

TEST(PseRotation, GrandMatrixIsSymmetricPositiveDefinite) {
  const std::array<double, 3> L = {7.0, 7.0, 8.0};
  std::vector<double> x = {1.0, 1.0, 1.0, 1.0, 1.0, 1.4, 3.0, 3.0, 3.0, 4.2, 3.0, 3.0,
                           6.8, 5.0, 5.0, 0.5, 5.0, 5.0, 2.0, 6.0, 2.0, 2.0, 6.0, 4.0};
  const auto extra = pse_test::random_points(4, L, 9);
  x.insert(x.end(), extra.begin(), extra.end());
  PseOptions o;
  o.tolerance = 1e-6;
  o.wave_precision = WavePrecision::double_precision;  // symmetric to double round-off
  PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
  op.set_positions(x, 1.0);
  const Eigen::MatrixXd M = pse_test::grand_matrix(op);
  const double scale = M.cwiseAbs().maxCoeff();
  EXPECT_LE((M - M.transpose()).cwiseAbs().maxCoeff(), 1e-12 * scale);
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(0.5 * (M + M.transpose()));
  EXPECT_GT(es.eigenvalues().minCoeff(), 1e-4 * es.eigenvalues().maxCoeff());
}

TEST(PseRotation, RepeatableBitForBitAndIndependentOfThreadCount) {
  const std::array<double, 3> L = {9.0, 10.0, 11.0};
  const auto x = configuration(L);
  const auto F = loads(x.size() / 3, 8), T = loads(x.size() / 3, 9);
  PseOptions o;
  o.tolerance = 1e-4;
  PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
  op.set_positions(x, 1.0);
  const auto first = product(op, F, T);
  std::vector<double> u(x.size()), w(x.size());
  op.apply(F, u);  // translational products and samples in between
  op.sample(1, 2, w);
  const auto again = product(op, F, T);
  EXPECT_EQ(first.u, again.u);
  EXPECT_EQ(first.w, again.w);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto one = product(op, F, T);
  omp_set_num_threads(threads);
  EXPECT_EQ(first.u, one.u);
  EXPECT_EQ(first.w, one.w);
}

TEST(PseRotation, SplitSamplerIsKeyedByItsNoise) {
  // The split sampler on the 6N operator: a deterministic function of z (the wave part keyed by
  // its hash); its covariance is tested in test_pse_statistics.cpp (slow label).
  const std::array<double, 3> L = {9.0, 10.0, 11.0};
  const auto x = configuration(L);
  const std::size_t n3 = x.size();
  PseOptions o;
  o.tolerance = 1e-4;
  PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
  op.set_positions(x, 1.0);
  std::vector<double> z(2 * n3), w1(2 * n3), w2(2 * n3), w3(2 * n3);
  fill_normal(z, 4, 5);
  SqrtOptions so;
  so.method = SqrtMethod::split;
  const auto sample = [&](std::vector<double>& w) {
    return op.apply_sqrt_rotation(std::span(z).first(n3), std::span(z).last(n3), std::span(w).first(n3),
                                  std::span(w).last(n3), so);
  };
  const SqrtReport rep = sample(w1);
  EXPECT_EQ(rep.method, SqrtMethod::split);
  EXPECT_GT(rep.iterations, 0);
  sample(w2);
  EXPECT_EQ(w1, w2);
  z[0] += 1e-3;
  sample(w3);
  EXPECT_NE(w1, w3);
}
