// Statistical BD tests with HI (dense reference RPY + Cholesky): a few seconds in
// Release, labelled `slow` so the sanitizer run skips them.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "dense_rpy.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"

using namespace rpyfmm::bd;
using rpyfmm::rpy::make_mobility;
using rpyfmm::rpy::MobilityMethod;
using rpyfmm::rpy::MobilitySpec;
constexpr double pi = std::numbers::pi;

namespace {
// Tiny systems, many steps: one thread avoids OpenMP start-up costs per step on busy machines.
struct OneThread : ::testing::Environment {
  void SetUp() override { omp_set_num_threads(1); }
};
const auto* const one_thread = ::testing::AddGlobalTestEnvironment(new OneThread);

std::vector<double> line_of_particles(std::size_t n, double spacing) {
  std::vector<double> x(3 * n, 0.0);
  for (std::size_t i = 0; i < n; ++i) x[3 * i] = spacing * static_cast<double>(i);
  return x;
}

ForceField trapped(const std::vector<double>& centres, double k) {
  ForceField ff;
  ff.add_callback([centres, k](std::span<const double> x, std::uint64_t, std::span<double> f) {
    for (std::size_t i = 0; i < x.size(); ++i) f[i] += -k * (x[i] - centres[i]);
  });
  return ff;
}
}  // namespace

// With HI the stationary distribution is still Boltzmann, variance kT/k per axis.
// For traps K = k I the EM covariance solves C = A C A + 2 kT dt M, A = I - k dt M,
// i.e. C = (kT/k) (I - k dt M / 2)^{-1} (M at the trap centres; stiff traps keep M
// nearly constant). n particles `spacing` apart on a line, k dt mu0 = 0.1: the mean over the
// coordinates of the measured variance / C_qq, and of the measured variance / (kT/k).
namespace {
struct TrapRatios {
  double to_em = 0.0;
  double to_continuous = 0.0;
};
TrapRatios trap_variance_ratios(std::unique_ptr<rpyfmm::rpy::MobilityOperator> op, std::size_t n, double spacing,
                                int steps, std::uint64_t seed) {
  const double k = 10.0, kT = 1.0, mu0 = 1.0 / (6 * pi), dt = 0.1 / (k * mu0);
  auto centres = line_of_particles(n, spacing);
  Integrator bd(std::move(op), trapped(centres, k), {.dt = dt, .kT = kT, .seed = seed}, centres,
                std::vector<std::uint32_t>(n, 0));
  bdtest::DenseRpy ref;
  ref.set_positions(centres, 1.0);
  const auto m = ref.assemble_dense();
  Eigen::MatrixXd M = Eigen::Map<const Eigen::MatrixXd>(m.data(), 3 * n, 3 * n);
  const Eigen::MatrixXd C = kT / k * (Eigen::MatrixXd::Identity(3 * n, 3 * n) - 0.5 * k * dt * M).inverse();
  bd.run(100);
  std::vector<double> sum2(3 * n, 0.0);
  for (int s = 0; s < steps; ++s) {
    bd.step();
    for (std::size_t q = 0; q < 3 * n; ++q) sum2[q] += std::pow(bd.positions()[q] - centres[q], 2);
  }
  TrapRatios r;
  for (std::size_t q = 0; q < 3 * n; ++q) {
    r.to_em += sum2[q] / steps / C(static_cast<Eigen::Index>(q), static_cast<Eigen::Index>(q)) / (3.0 * n);
    r.to_continuous += sum2[q] / steps / (kT / k) / (3.0 * n);
  }
  return r;
}
}  // namespace

// 8 particles 4a apart (strong HI), 20000 steps: ~24 x 20000 / 20 = 24000 effective samples,
// relative error ~0.9%; tolerance 4% (covers the variation of M over the thermal spread
// sqrt(kT/k) = 0.3 a too).
TEST(BdStatistics, HarmonicTrapVarianceWithHi) {
  const TrapRatios r = trap_variance_ratios(std::make_unique<bdtest::DenseRpy>(), 8, 4.0, 20000, 9);
  EXPECT_NEAR(r.to_em, 1.0, 0.04);
  EXPECT_NEAR(r.to_continuous, 1.0, 0.08);  // the continuous-time answer kT/k, up to the O(dt) bias
}

// The same trap with the free-space PSE operator (OpenPseRpy, tolerance 1e-3) and its split
// sampler, which a BD step with method "pse" in open geometry takes: the variances against the
// same C (with M from the exact sums; the operator's error, <= 1e-3, is far below the statistical
// one). 4 particles 3a apart, 6000 steps: ~12 x 6000 / 20 = 3600 effective samples, relative
// error ~2.4%; tolerance 4 standard errors (10%).
TEST(BdStatistics, HarmonicTrapVarianceWithOpenPse) {
  MobilitySpec spec;
  spec.method = MobilityMethod::pse;
  auto op = make_mobility(spec, 4);
  ASSERT_EQ(op->name(), "pse-open");
  EXPECT_NEAR(trap_variance_ratios(std::move(op), 4, 3.0, 6000, 19).to_em, 1.0, 0.10);
}

// Relative diffusion of a pair at fixed separation r (one step from the same
// configuration, K = 20000 independent steps keyed by step number): the relative
// displacement has variance 2 dt * 2 kT (mu0 - (f + g)) along the line of centres and
// 2 dt * 2 kT (mu0 - f) across it (M_12 = f I + g rr). Relative standard error of a
// variance from K samples: sqrt(2/K) = 1%; tolerance 5%. Free draining would give
// 2 dt * 2 kT mu0, 50% more at r = 3a: the test distinguishes.
TEST(BdStatistics, PairRelativeDiffusionIsRpy) {
  const double a = 1.0, r = 3.0, kT = 1.0, dt = 0.01;
  std::vector<double> x{0, 0, 0, r, 0, 0};
  const int K = 20000;  // ~0.1 ms each
  double var_par = 0, var_perp = 0;
  for (int s = 0; s < K; ++s) {
    Integrator bd(std::make_unique<bdtest::DenseRpy>(), ForceField(), {.dt = dt, .kT = kT, .seed = 3}, x, {0, 0}, {},
                  static_cast<std::uint64_t>(s));
    bd.step();
    const auto p = bd.positions();
    var_par += std::pow((p[3] - p[0]) - r, 2);
    var_perp += 0.5 * (std::pow(p[4] - p[1], 2) + std::pow(p[5] - p[2], 2));
  }
  var_par /= K;
  var_perp /= K;
  const double mu0 = 1 / (6 * pi * a);
  const double f = (1 + 2 * a * a / (3 * r * r)) / (8 * pi * r), g = (1 - 2 * a * a / (r * r)) / (8 * pi * r);
  EXPECT_NEAR(var_par / (4 * kT * dt * (mu0 - f - g)), 1.0, 0.05);
  EXPECT_NEAR(var_perp / (4 * kT * dt * (mu0 - f)), 1.0, 0.05);
}

// Periodic BD with PSE hydrodynamics: one sphere in a cube of side L = 5a diffuses with the
// periodic self-mobility mu(L) = mu0 (1 - 2.837297 a/L + (4 pi/3)(a/L)^3) (Hasimoto; exact for
// RPY; docs/theory/pse.md), 0.466 mu0 here. 600 steps x 3 axes of independent Gaussian increments give
// the per-step variance 2 kT mu dt with relative standard error sqrt(2/1800) = 3.3%; tolerance
// 12% (~3.6 sigma) — the free-space value would be off by a factor 2.1.
TEST(BdStatistics, PeriodicPseDiffusionIsHasimoto) {
  MobilitySpec spec;
  spec.method = MobilityMethod::pse;
  spec.tolerance = 1e-3;
  spec.geometry = rpyfmm::rpy::Geometry::periodic(5.0);
  IntegratorOptions o{.dt = 0.01, .kT = 1.0, .seed = 21};
  Integrator bd(make_mobility(spec, 1), ForceField(), o, std::vector<double>{1.0, 2.0, 3.0},
                std::vector<std::uint32_t>{0});
  double sum2 = 0.0;
  const int steps = 600;
  for (int s = 0; s < steps; ++s) {
    const std::vector<double> before(bd.positions().begin(), bd.positions().end());
    bd.step();
    for (int k = 0; k < 3; ++k) sum2 += std::pow(bd.positions()[k] - before[k], 2);
  }
  const double a_over_l = 0.2;
  const double mu = (1.0 - 2.837297 * a_over_l + 4.0 * pi / 3.0 * std::pow(a_over_l, 3)) / (6.0 * pi);
  const double variance = sum2 / (3.0 * steps);
  EXPECT_NEAR(variance / (2.0 * o.kT * mu * o.dt), 1.0, 0.12);
  EXPECT_EQ(bd.mobility().name(), "pse");
}
