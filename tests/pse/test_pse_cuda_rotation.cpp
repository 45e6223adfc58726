// PSE with rotation on CUDA against the CPU operator (docs/theory/pse.md Sec. 5): products with
// torques, the device-array entry point and the 6N split sampler agree with PseRpy to the bounds of
// the translational CUDA tests (test_pse_cuda.cpp), and the device sampler's covariance is the
// grand mobility. Skips cleanly without a usable device (cuda_test_device.hpp).
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <span>
#include <vector>

#include "cuda_test_device.hpp"
#include "ewald_reference.hpp"
#include "pse_sampler_util.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"
#include "rpyfmm/rpy/random.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

namespace {

/// Uniform vectors in [-1, 1)^3 per particle.
std::vector<double> centred(std::size_t n, unsigned seed) {
  auto v = pse_test::random_points(n, {2.0, 2.0, 2.0}, seed);
  for (auto& c : v) c -= 1.0;
  return v;
}

/// The split samplers of both back ends: the same up to round-off with the same Lanczos iteration
/// count, else to about the Lanczos tolerance (as test_pse_cuda.cpp).
double sampler_bound(const SqrtReport& c, const SqrtReport& g, double tolerance) {
  return c.iterations == g.iterations ? 1e-10 : 10.0 * tolerance;
}

/// [U; W] of `cpu` and `gpu` for (f, t) agree to `bound` (relative l2 each).
void expect_products_agree(const MobilityOperator& cpu, const MobilityOperator& gpu, const std::vector<double>& f,
                           const std::vector<double>& t, double bound, const char* what) {
  std::vector<double> uc(f.size()), wc(f.size()), ug(f.size()), wg(f.size());
  cpu.apply(f, t, uc, wc);
  gpu.apply(f, t, ug, wg);
  EXPECT_LT(pse_test::rel_l2(ug, uc), bound) << what << ": U";
  EXPECT_LT(pse_test::rel_l2(wg, wc), bound) << what << ": W";
}

}  // namespace

// Double-precision grids: products with torques agree to 1e-12 (the translational bound) with the
// host neighbour lists and with the device cell list, in a cube and a rectangular box with a
// coincident and an overlapping pair, after moves; the device-array entry point likewise; the split
// sampler of the 6N covariance to the sampler bound.
TEST(PseCudaRotation, CpuAndGpuAgree) {
  REQUIRE_DEVICE();
  for (const std::array<double, 3>& L :
       {std::array<double, 3>{16.0, 16.0, 16.0}, std::array<double, 3>{12.0, 15.0, 10.0}}) {
    auto x = pse_test::random_points(500, L, 91);
    for (int d = 0; d < 3; ++d) {
      x[3 * 7 + d] = x[3 * 3 + d];                  // coincident
      x[3 * 9 + d] = x[3 * 4 + d] + 0.4 * (d + 1);  // overlapping
    }
    const auto f = centred(500, 92), t = centred(500, 93);
    PseOptions o;
    o.tolerance = 1e-6;
    o.xi = 1.0;
    o.wave_precision = WavePrecision::double_precision;
    const Geometry g = Geometry::periodic(L[0], L[1], L[2]);
    PseRpy cpu(g, 1.0, o);
    PseRpyCuda lists(g, 1.0, o, PseCudaOptions{.device_cell_list = false});
    PseRpyCuda cells(g, 1.0, o, PseCudaOptions{.device_cell_list = true});
    ASSERT_TRUE(lists.supports_rotation());
    cpu.set_positions(x, 1.0);
    lists.set_positions(x, 1.0);
    cells.set_positions(x, 1.0);
    expect_products_agree(cpu, lists, f, t, 1e-12, "host lists");
    expect_products_agree(cpu, cells, f, t, 1e-12, "device cell list");
#ifdef RPYFMM_HAVE_CUDA_PSE
    {
      std::vector<double> uc(f.size()), wc(f.size());
      cpu.apply(f, t, uc, wc);
      pse_test::DeviceVector df(f), dt(t), du(f.size()), dw(f.size());
      cells.apply_device(df.get(), dt.get(), du.get(), dw.get());
      EXPECT_LT(pse_test::rel_l2(du.host(), uc), 1e-12) << "apply_device: U";
      EXPECT_LT(pse_test::rel_l2(dw.host(), wc), 1e-12) << "apply_device: W";
    }
#endif
    std::vector<double> wtc(f.size()), wrc(f.size()), wtg(f.size()), wrg(f.size());
    const SqrtReport rc = cpu.apply_sqrt_rotation(f, t, wtc, wrc);
    for (const PseRpyCuda* gpu : {&lists, &cells}) {
      const SqrtReport rg = gpu->apply_sqrt_rotation(f, t, wtg, wrg);
      EXPECT_EQ(rg.method, SqrtMethod::split);
      EXPECT_LT(pse_test::rel_l2(wtg, wtc), sampler_bound(rc, rg, o.tolerance))
          << rc.iterations << " vs " << rg.iterations;
      EXPECT_LT(pse_test::rel_l2(wrg, wrc), sampler_bound(rc, rg, o.tolerance))
          << rc.iterations << " vs " << rg.iterations;
    }
    auto moved = x;
    for (std::size_t i = 0; i < moved.size(); ++i) moved[i] += 0.7 * std::sin(1.3 * double(i));
    cpu.set_positions(moved, 1.0);
    cells.set_positions(moved, 1.0);
    expect_products_agree(cpu, cells, f, t, 1e-12, "moved");
  }
}

// Single-precision wave grids (automatic at tolerance 1e-4): float round-off, bound 1e-5 as the
// translational SinglePrecisionGridsAgree.
TEST(PseCudaRotation, SinglePrecisionGridsAgree) {
  REQUIRE_DEVICE();
  const std::array<double, 3> L{12.0, 15.0, 10.0};
  const auto x = pse_test::random_points(400, L, 94);
  const auto f = centred(400, 95), t = centred(400, 96);
  PseOptions o;
  o.tolerance = 1e-4;
  const Geometry g = Geometry::periodic(L[0], L[1], L[2]);
  PseRpy cpu(g, 1.0, o);
  PseRpyCuda gpu(g, 1.0, o);
  cpu.set_positions(x, 1.0);
  gpu.set_positions(x, 1.0);
  ASSERT_TRUE(gpu.parameters().wave_single);
  expect_products_agree(cpu, gpu, f, t, 1e-5, "single-precision grids");
}

// E[w w^T] = M for w = [w_t; w_r] from the device's split sampler, z keyed per sample, with M the
// CPU operator's grand matrix (which the device's equals to 1e-12, CpuAndGpuAgree); entries in the
// S-scaled units (torque rows and columns times a) within 5 standard errors of the largest entry,
// as the CPU's RotationSplitSampleCovarianceEqualsGrandMobility (test_pse_statistics.cpp).
TEST(PseCudaRotation, SplitSamplerCovarianceEqualsGrandMobility) {
  REQUIRE_DEVICE();
  const std::array<double, 3> L = {6.0, 6.0, 6.0};
  const std::vector<double> x = {1.0, 1.0, 1.0, 2.2, 1.5, 1.0, 4.0, 4.0, 3.0};
  const double a = 0.8;
  PseOptions o;
  o.tolerance = 1e-4;
  const Geometry g = Geometry::periodic(L[0], L[1], L[2]);
  PseRpy cpu(g, 1.0, o);
  PseRpyCuda gpu(g, 1.0, o);
  cpu.set_positions(x, a);
  gpu.set_positions(x, a);
  const Eigen::Index n6 = 18;
  Eigen::VectorXd s = Eigen::VectorXd::Ones(n6);
  s.tail(9).setConstant(a);
  const Eigen::MatrixXd M = s.asDiagonal() * pse_test::grand_matrix(cpu) * s.asDiagonal();
  Eigen::MatrixXd C = Eigen::MatrixXd::Zero(n6, n6);
  const int samples = 6000;
  std::vector<double> z(18), wt(9), wr(9);
  for (int k = 0; k < samples; ++k) {
    fill_normal(z, 11, static_cast<std::uint64_t>(k));
    gpu.apply_sqrt_rotation(std::span(z).first(9), std::span(z).last(9), wt, wr);
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
