// PSE wave-space precision (PseOptions::wave_precision): single-precision grids against double
// ones and against the direct Ewald sum; the automatic choice; what the CUDA backend accepts.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "../../rpy/src/pse/kernels_common.hpp"  // window weights, scale_mode_with
#include "../../rpy/src/pse/scale_line.hpp"
#include "ewald_reference.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "simd_levels.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

namespace {

std::vector<double> product(const PseRpy& op, const std::vector<double>& f) {
  std::vector<double> u(f.size());
  op.apply(f, u);
  return u;
}

PseOptions with_precision(double tolerance, WavePrecision precision) {
  PseOptions o;
  o.tolerance = tolerance;
  o.wave_precision = precision;
  return o;
}

/// Forces with components uniform in [-1, 1).
std::vector<double> random_forces(std::size_t n, unsigned seed) {
  auto f = pse_test::random_points(n, {2.0, 2.0, 2.0}, seed);
  for (auto& v : f) v -= 1.0;
  return f;
}

}  // namespace

TEST(PsePrecision, SingleAndDoubleWaveGridsAgree) {
  // The same operator with float and double grids: products and split samples (wave-space noise
  // included) differ by float round-off only. Bound 1e-6: float's unit round-off 6e-8 times the
  // growth of the spreading sums and the FFTs (measured 0.5-1.1e-7 on 1500 particles at
  // tolerances 1e-2 ... 1e-7), 10x below kSingleWaveTolerance.
  const std::array<double, 3> L = {24.0, 22.0, 26.0};
  const auto x = pse_test::random_points(1500, L, 71);
  const auto f = random_forces(1500, 72);
  for (double eps : {1e-2, 1e-3, 1e-5, 1e-7}) {
    PseRpy single(Geometry::periodic(L[0], L[1], L[2]), 1.0, with_precision(eps, WavePrecision::single_precision));
    PseRpy dbl(Geometry::periodic(L[0], L[1], L[2]), 1.0, with_precision(eps, WavePrecision::double_precision));
    single.set_positions(x, 1.0);
    dbl.set_positions(x, 1.0);
    ASSERT_TRUE(single.parameters().wave_single);
    ASSERT_FALSE(dbl.parameters().wave_single);
    // Same parameters apart from the precision: grids, supports, xi.
    EXPECT_EQ(single.parameters().grid, dbl.parameters().grid);
    EXPECT_EQ(single.parameters().support, dbl.parameters().support);
    EXPECT_EQ(single.parameters().xi, dbl.parameters().xi);
    const double d_product = pse_test::rel_l2(product(single, f), product(dbl, f));
    std::vector<double> w_single(f.size()), w_double(f.size()), u_single(f.size()), u_double(f.size());
    single.sample(3, 4, w_single);
    dbl.sample(3, 4, w_double);
    const double d_sample = pse_test::rel_l2(w_single, w_double);
    single.apply_wave(f, u_single);
    dbl.apply_wave(f, u_double);
    const double d_wave = pse_test::rel_l2(u_single, u_double);
    EXPECT_LT(d_product, 1e-6) << "eps " << eps;
    EXPECT_LT(d_sample, 1e-6) << "eps " << eps;
    EXPECT_LT(d_wave, 1e-6) << "eps " << eps;
    // ... and they do differ (the float path is really taken).
    EXPECT_GT(d_wave, 1e-10) << "eps " << eps;
    std::printf("eps %.0e: single vs double: product %.2e, sample %.2e, wave part %.2e\n", eps, d_product, d_sample,
                d_wave);
  }
}

TEST(PsePrecision, SingleGridsMeetTheToleranceAgainstEwaldSum) {
  // Float grids forced at every tolerance down to 1e-6 (below kSingleWaveTolerance the automatic
  // choice takes double): the error against the direct Ewald sum stays below eps (measured 0.2-0.5
  // eps), and at 1e-8, out of single's reach, below 1e-6, the floor SingleAndDoubleWaveGridsAgree
  // bounds (measured 6e-8).
  const std::array<double, 3> L = {14.0, 14.0, 14.0};
  const auto x = pse_test::random_points(30, L, 11);
  const auto f = random_forces(30, 12);
  const auto ref = pse_test::ewald_reference(x, 1.0, 1.0, L, f, 1.0);
  for (double eps : {1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-8}) {
    PseOptions o = with_precision(eps, WavePrecision::single_precision);
    o.xi = 1.0;
    PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
    op.set_positions(x, 1.0);
    const double err = pse_test::rel_l2(product(op, f), ref);
    EXPECT_LE(err, std::max(eps, 1e-6)) << op.parameters().summary();
    std::printf("eps %.0e: single-precision grids, error %.2e\n", eps, err);
  }
}

TEST(PsePrecision, AutomaticChoiceFollowsTheTolerance) {
  const std::array<double, 3> L = {20.0, 20.0, 20.0};
  const auto choose = [&](double eps, WavePrecision w) {
    return choose_parameters(with_precision(eps, w), 1.0, L, 1000);
  };
  EXPECT_TRUE(choose(1e-3, WavePrecision::automatic).wave_single);
  EXPECT_TRUE(choose(kSingleWaveTolerance, WavePrecision::automatic).wave_single);
  EXPECT_FALSE(choose(0.99 * kSingleWaveTolerance, WavePrecision::automatic).wave_single);
  EXPECT_FALSE(choose(1e-3, WavePrecision::double_precision).wave_single);
  EXPECT_TRUE(choose(1e-7, WavePrecision::single_precision).wave_single);
  // Float grids and spectra take half the bytes (the weight cache and c(k) stay double).
  const auto s = choose(1e-3, WavePrecision::single_precision);
  const auto d = choose(1e-3, WavePrecision::double_precision);
  EXPECT_EQ(s.grid, d.grid);
  EXPECT_LT(static_cast<double>(s.memory_bytes), 0.6 * static_cast<double>(d.memory_bytes));
  EXPECT_NE(s.summary().find("wave grids single"), std::string::npos);
  EXPECT_NE(d.summary().find("wave grids double"), std::string::npos);
  // A value outside the enumeration is refused.
  EXPECT_THROW(choose(1e-3, static_cast<WavePrecision>(7)), rpyfmm::Error);
}

// The CUDA backend follows wave_precision as the CPU does (single-precision grids too): with a
// device the option is taken (the agreement with the CPU: test_pse_cuda.cpp); without one the
// constructor refuses for that reason, not for the precision.
TEST(PsePrecision, CudaBackendFollowsWavePrecision) {
  for (WavePrecision precision : {WavePrecision::single_precision, WavePrecision::double_precision}) {
    const PseOptions o = with_precision(1e-3, precision);
    if (PseRpyCuda::device_available()) {
      PseRpyCuda op(Geometry::periodic(20.0), 1.0, o);
      op.set_positions(std::vector<double>{1.0, 2.0, 3.0, 7.0, 8.0, 9.0}, 1.0);
      EXPECT_EQ(op.parameters().wave_single, precision == WavePrecision::single_precision);
      continue;
    }
    try {
      PseRpyCuda op(Geometry::periodic(20.0), 1.0, o);
      FAIL() << "PseRpyCuda constructed without a usable device";
    } catch (const rpyfmm::Error& e) {
      EXPECT_EQ(e.code(), rpyfmm::ErrorCode::not_supported);
      EXPECT_EQ(std::string(e.what()).find("wave_precision"), std::string::npos) << e.what();
    }
  }
}

TEST(PsePrecision, WindowWeightRecurrenceMatchesExponentials) {
  // The CPU wave space computes the Gaussian window weights by the fast-Gaussian-gridding
  // recurrence (two exponentials per axis); the CUDA kernels by one exponential per point.
  // Same first index, and weights within 1e-12 relative, over positions across the box (wrapped
  // windows included), supports 4-16 and window widths 0.5-1.5 grid spacings. Neither is exact:
  // both round the distance d = x_l - x to ~ulp(x) (7e-15 at x = 35), which changes the exponent
  // d^2 / 2 sigma^2 by up to |d| ulp(x) / sigma^2 (~3e-13 at the edge of a 16-point window of
  // width 0.5 h); the products of the recurrence add P ulps. Far below the 1e-8 the tolerance
  // range needs.
  const int n = 50;
  const double h = 0.7;
  for (int P : {4, 6, 7, 12, 16}) {
    for (double sigma_over_h : {0.5, 1.0, 1.5}) {
      const double sigma = sigma_over_h * h, inv_2s2 = 1.0 / (2.0 * sigma * sigma);
      std::vector<double> tail(static_cast<std::size_t>(P)), exact(tail.size()), fast(tail.size());
      for (int l = 0; l < P; ++l) tail[static_cast<std::size_t>(l)] = std::exp(-(l * h) * (l * h) * inv_2s2);
      const auto x = pse_test::random_points(400, {n * h, n * h, n * h}, 91);
      for (double xi : x) {
        const int s_exact = detail::window_weights(xi, h, P, n, inv_2s2, exact.data());
        const int s_fast = detail::window_weights_recurrence(xi, h, P, n, inv_2s2, tail.data(), fast.data());
        ASSERT_EQ(s_exact, s_fast) << "x = " << xi;
        for (std::size_t l = 0; l < exact.size(); ++l)
          ASSERT_NEAR(fast[l], exact[l], 1e-12 * exact[l]) << "P = " << P << ", x = " << xi << ", l = " << l;
      }
    }
  }
}

namespace {

/// scale_line against scale_mode_with (the GPU's per-mode function) on every line of a small
/// half spectrum of type Real, for each combination of deterministic part and noise; returns the
/// largest difference relative to the largest value.
template <class Real>
double scale_line_vs_per_mode(bool deterministic, bool noisy) {
  const std::array<int, 3> n = {6, 5, 8};  // odd and even sizes: Nyquist planes and k = 0
  detail::ModeGeometry g{};
  const std::array<double, 3> L = {3.0, 2.5, 4.0};
  for (int d = 0; d < 3; ++d) {
    g.n[d] = n[static_cast<std::size_t>(d)];
    g.two_pi_L[d] = 2.0 * 3.14159265358979323846 / L[static_cast<std::size_t>(d)];
  }
  g.nzh = n[2] / 2 + 1;
  g.modes = static_cast<std::size_t>(n[0] * n[1] * g.nzh);
  g.comp_stride = 2 * g.modes;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::vector<double> ck(g.modes);
  std::vector<Real> spec(3 * g.comp_stride);
  for (auto& v : spec) v = static_cast<Real>(uni(rng));
  for (std::size_t i = 0; i < g.modes; ++i) ck[i] = i % 7 == 3 ? 0.0 : 0.5 + 0.5 * uni(rng);
  ck[0] = 0.0;
  auto per_mode = spec;
  auto by_line = spec;
  const double factor = 0.7;
  const std::size_t nzh = static_cast<std::size_t>(g.nzh);
  std::vector<Real> z(6 * nzh);
  std::vector<char> rep_flag(nzh);
  std::vector<Real> sign(nzh);
  for (int ix = 0; ix < n[0]; ++ix) {
    for (int iy = 0; iy < n[1]; ++iy) {
      const std::size_t base = (static_cast<std::size_t>(ix) * static_cast<std::size_t>(n[1]) + iy) * nzh;
      for (std::size_t iz = 0; iz < nzh; ++iz) {
        std::uint64_t lin, rep;
        detail::mode_pair(ix, iy, static_cast<int>(iz), g, lin, rep);
        rep_flag[iz] = lin == rep;
        sign[iz] = rep_flag[iz] ? Real(1) : Real(-1);
        Real zm[6];
        if constexpr (std::is_same_v<Real, float>) {
          normal6f(11, 3, detail::kStreamWave, rep, zm);
        } else {
          normal6(11, 3, detail::kStreamWave, rep, zm);
        }
        for (std::size_t c = 0; c < 6; ++c) z[c * nzh + iz] = zm[c];
        detail::scale_mode_with(ix, iy, static_cast<int>(iz), base + iz, g, ck.data(), per_mode.data(), deterministic,
                                noisy ? zm : static_cast<const Real*>(nullptr), rep_flag[iz] != 0, factor);
      }
      detail::ModeLine<Real> line;
      line.ix = ix;
      line.iy = iy;
      line.ck = ck.data();
      line.spec = by_line.data();
      line.deterministic = deterministic;
      line.z = noisy ? z.data() : nullptr;
      line.z_stride = nzh;
      line.sign = sign.data();
      line.noise_factor = factor;
      detail::scale_line(g, line);
    }
  }
  double worst = 0.0, largest = 0.0;
  for (std::size_t i = 0; i < spec.size(); ++i) {
    worst = std::max(worst, std::abs(static_cast<double>(per_mode[i]) - static_cast<double>(by_line[i])));
    largest = std::max(largest, std::abs(static_cast<double>(per_mode[i])));
    // Modes with c(k) = 0 (k = 0, Nyquist planes) are exact zeros in both.
    if (ck[(i % g.comp_stride) / 2] == 0.0) {
      EXPECT_EQ(per_mode[i], Real(0)) << "element " << i;
      EXPECT_EQ(by_line[i], Real(0)) << "element " << i;
    }
  }
  EXPECT_GT(largest, 0.1);
  return worst / largest;
}

}  // namespace

TEST(PsePrecision, LineScalingMatchesPerModeScaling) {
  // The CPU's vectorized line loop against the per-mode function the GPU runs: the same
  // operations, so differences are round-off (fused multiply-adds where the vector ISA has
  // them): below 1e-14 for double spectra, 1e-6 (a few float ulps) for float ones. With the
  // AVX-512 kernels, the AVX2 ones and the portable loop (each where the machine has it).
  for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
    const rpyfmm::ScopedSimdLevel scope(level);
    const char* kernels = rpyfmm::simd_level_name(level);
    for (const bool det : {true, false}) {
      for (const bool noisy : {true, false}) {
        if (!det && !noisy) continue;  // nothing to scale (the wave space never asks)
        EXPECT_LT(scale_line_vs_per_mode<double>(det, noisy), 1e-14) << det << noisy << kernels;
        EXPECT_LT(scale_line_vs_per_mode<float>(det, noisy), 1e-6) << det << noisy << kernels;
      }
    }
  }
}

TEST(PsePrecision, LineNoiseKeysMatchModePair) {
  // The vectorized keys and conjugation signs of a line against mode_pair, mode by mode, on odd
  // and even grid sizes (Nyquist planes, the k = 0 line, self-conjugate modes), on each build.
  for (const std::array<int, 3> n : {std::array<int, 3>{6, 5, 8}, std::array<int, 3>{7, 4, 9}}) {
    detail::ModeGeometry g{};
    for (int d = 0; d < 3; ++d) g.n[d] = n[static_cast<std::size_t>(d)];
    g.nzh = n[2] / 2 + 1;
    g.modes = static_cast<std::size_t>(n[0] * n[1] * g.nzh);
    g.comp_stride = 2 * g.modes;
    const auto nzh = static_cast<std::size_t>(g.nzh);
    for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
      const rpyfmm::ScopedSimdLevel scope(level);
      const char* kernels = rpyfmm::simd_level_name(level);
      int conjugates = 0;
      for (int ix = 0; ix < n[0]; ++ix) {
        for (int iy = 0; iy < n[1]; ++iy) {
          std::vector<std::uint64_t> rep(nzh);
          std::vector<float> sign(nzh);
          std::vector<double> sign_d(nzh);
          detail::line_noise_keys(g, ix, iy, rep.data(), sign.data());
          detail::line_noise_keys(g, ix, iy, rep.data(), sign_d.data());
          for (std::size_t iz = 0; iz < nzh; ++iz) {
            std::uint64_t lin, ref;
            detail::mode_pair(ix, iy, static_cast<int>(iz), g, lin, ref);
            EXPECT_EQ(rep[iz], ref) << ix << " " << iy << " " << iz << " kernels " << kernels;
            EXPECT_EQ(sign[iz], lin == ref ? 1.0f : -1.0f) << ix << " " << iy << " " << iz;
            EXPECT_EQ(sign_d[iz], lin == ref ? 1.0 : -1.0) << ix << " " << iy << " " << iz;
            conjugates += lin != ref;
          }
        }
      }
      EXPECT_GT(conjugates, 0);
    }
  }
}
