// Direct Laplace sums (direct.hpp) against closed forms, finite differences
// and a plain double loop written here.
#include <gtest/gtest.h>
#include <omp.h>

#include <array>
#include <cmath>
#include <random>
#include <vector>

#include "rpyfmm/core/error.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "simd_levels.hpp"

using namespace rpyfmm::fmm;
using rpyfmm::Error;

namespace {

std::vector<double> random_points(std::size_t n, unsigned seed, double lo = -1.0, double hi = 1.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<double> p(n);
  for (auto& v : p) v = u(rng);
  return p;
}

std::vector<double> run(const std::vector<double>& s, const std::vector<double>& q, std::size_t nd,
                        const std::vector<double>& t, unsigned outputs = all_outputs) {
  const std::size_t m = t.empty() ? s.size() / 3 : t.size() / 3;
  std::vector<double> out(nd * m * result_width, -7.0);  // garbage: must be overwritten
  laplace_direct(s, q, nd, t, outputs, out);
  return out;
}

// Plain reference: phi = sum q/r, grad phi = -sum q r/r^3, hess = sum q (3 r r^T/r^5 - I/r^3), r = x - y.
std::array<double, 10> reference_at(const double* x, const std::vector<double>& s, const double* q) {
  std::array<double, 10> o{};
  for (std::size_t j = 0; j < s.size() / 3; ++j) {
    const double r[3] = {x[0] - s[3 * j], x[1] - s[3 * j + 1], x[2] - s[3 * j + 2]};
    const double d = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    if (d == 0.0) continue;
    o[0] += q[j] / d;
    for (int c = 0; c < 3; ++c) o[1 + c] -= q[j] * r[c] / (d * d * d);
    const int pa[6] = {0, 1, 2, 0, 0, 1}, pb[6] = {0, 1, 2, 1, 2, 2};
    for (int k = 0; k < 6; ++k) {
      o[4 + k] += q[j] * (3 * r[pa[k]] * r[pb[k]] / std::pow(d, 5) - (pa[k] == pb[k] ? 1.0 : 0.0) / std::pow(d, 3));
    }
  }
  return o;
}

// Every test runs at each instruction-set level the machine has (scalar, AVX2, AVX-512).
class LaplaceDirect : public rpyfmm::test::SimdLevelTest {};

}  // namespace

INSTANTIATE_TEST_SUITE_P(Kernels, LaplaceDirect, ::testing::ValuesIn(rpyfmm::test::all_simd_levels()),
                         rpyfmm::test::simd_level_param_name);

// The levels agree to rounding (1/sqrt within a few ulp; sums in another order).
TEST(LaplaceDirectPaths, EveryLevelAgreesWithScalar) {
  const std::size_t n = 1500, nd = 2;
  const auto s = random_points(3 * n, 21);
  const auto q = random_points(nd * n, 22);
  const auto t = random_points(3 * 100, 23, -1.2, 1.2);
  for (std::size_t ndd : {std::size_t{1}, nd}) {
    const std::vector<double> qq(q.begin(), q.begin() + ndd * n);
    std::vector<double> b;
    {
      const rpyfmm::ScopedSimdLevel scalar(rpyfmm::SimdLevel::scalar);
      b = run(s, qq, ndd, t);
    }
    std::array<double, 10> scale{};
    for (std::size_t i = 0; i < b.size(); ++i) scale[i % 10] = std::max(scale[i % 10], std::abs(b[i]));
    for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
      const rpyfmm::ScopedSimdLevel scope(level);
      const auto a = run(s, qq, ndd, t);
      for (std::size_t i = 0; i < b.size(); ++i)
        EXPECT_NEAR(a[i], b[i], 1e-13 * scale[i % 10]) << i << " at " << rpyfmm::simd_level_name(level);
    }
  }
}

// Two charges: at source 0 only source 1 acts (self pair skipped).
TEST_P(LaplaceDirect, TwoChargesClosedForm) {
  const double d = 2.0, q0 = 1.5, q1 = -0.5;
  const std::vector<double> s = {0, 0, 0, d, 0, 0}, q = {q0, q1};
  const auto out = run(s, q, 1, {});
  // at x0 = 0, r = x0 - x1 = (-d, 0, 0): phi = q1/d, grad = -q1 r/d^3 = (q1/d^2, 0, 0),
  // hess = q1 (3 rr/d^5 - I/d^3) = q1/d^3 diag(2, -1, -1).
  const std::array<double, 10> e0 = {
      q1 / d, q1 / (d * d), 0, 0, 2 * q1 / (d * d * d), -q1 / (d * d * d), -q1 / (d * d * d), 0, 0, 0};
  const std::array<double, 10> e1 = {
      q0 / d, -q0 / (d * d), 0, 0, 2 * q0 / (d * d * d), -q0 / (d * d * d), -q0 / (d * d * d), 0, 0, 0};
  for (int c = 0; c < 10; ++c) {
    EXPECT_NEAR(out[c], e0[c], 1e-15) << c;
    EXPECT_NEAR(out[10 + c], e1[c], 1e-15) << c;
  }
}

// Three unit charges at the corners of an equilateral triangle of side 1 in the
// xy-plane, target on the axis at height h: phi = 3/sqrt(R^2 + h^2), R = 1/sqrt(3),
// the field is along z: d phi/dz = -3 h/(R^2 + h^2)^{3/2}; by symmetry
// hxx = hyy = -hzz/2 and the off-diagonal entries vanish;
// hzz = 3 (3h^2/s^5 - 1/s^3), s = sqrt(R^2 + h^2).
TEST_P(LaplaceDirect, ThreeChargesClosedForm) {
  const double R = 1.0 / std::sqrt(3.0), h = 0.8;
  std::vector<double> s;
  for (int k = 0; k < 3; ++k) {
    const double th = 2 * M_PI * k / 3;
    s.insert(s.end(), {R * std::cos(th), R * std::sin(th), 0.0});
  }
  const std::vector<double> t = {0, 0, h};
  const auto out = run(s, {1, 1, 1}, 1, t);
  const double sd = std::sqrt(R * R + h * h);
  const double hzz = 3 * (3 * h * h / std::pow(sd, 5) - 1 / std::pow(sd, 3));
  // tolerance: rounding of O(1) sums
  EXPECT_NEAR(out[col_pot], 3 / sd, 1e-14);
  EXPECT_NEAR(out[col_gx], 0, 1e-14);
  EXPECT_NEAR(out[col_gy], 0, 1e-14);
  EXPECT_NEAR(out[col_gz], -3 * h / std::pow(sd, 3), 1e-14);
  EXPECT_NEAR(out[col_hzz], hzz, 1e-13);
  EXPECT_NEAR(out[col_hxx], -hzz / 2, 1e-13);
  EXPECT_NEAR(out[col_hyy], -hzz / 2, 1e-13);
  EXPECT_NEAR(out[col_hxy], 0, 1e-13);
  EXPECT_NEAR(out[col_hxz], 0, 1e-13);
  EXPECT_NEAR(out[col_hyz], 0, 1e-13);
}

// Gradient = central differences of the potential, Hessian = central differences
// of the gradient; step h = 1e-5 on O(1) distances gives O(h^2) ~ 1e-10 truncation
// plus ~1e-11 rounding: tolerance 1e-7 relative.
TEST_P(LaplaceDirect, GradientAndHessianMatchFiniteDifferences) {
  const auto s = random_points(3 * 20, 1);
  const auto q = random_points(20, 2);
  const std::vector<double> t = {2.0, 1.5, -1.7, -2.2, 0.3, 1.9};
  const auto out = run(s, q, 1, t);
  const double h = 1e-5;
  for (int i = 0; i < 2; ++i) {
    for (int c = 0; c < 3; ++c) {
      auto tp = std::vector<double>(t.begin() + 3 * i, t.begin() + 3 * i + 3), tm = tp;
      tp[c] += h;
      tm[c] -= h;
      const auto op = run(s, q, 1, tp), om = run(s, q, 1, tm);
      const double scale = std::abs(out[10 * i + col_pot]) + 1;
      EXPECT_NEAR(out[10 * i + 1 + c], (op[col_pot] - om[col_pot]) / (2 * h), 1e-7 * scale);
      // d/dx_c of gradient component b gives H(b, c)
      const int hidx[3][3] = {{col_hxx, col_hxy, col_hxz}, {col_hxy, col_hyy, col_hyz}, {col_hxz, col_hyz, col_hzz}};
      for (int b = 0; b < 3; ++b) {
        EXPECT_NEAR(out[10 * i + hidx[b][c]], (op[1 + b] - om[1 + b]) / (2 * h), 1e-7 * scale) << b << c;
      }
    }
  }
}

TEST_P(LaplaceDirect, HessianTraceIsZeroAndMatchesPlainLoop) {
  const std::size_t n = 700, nt = 90;  // more sources than one internal block
  const auto s = random_points(3 * n, 3);
  const auto q = random_points(n, 4);
  const auto t = random_points(3 * nt, 5, -1.5, 1.5);
  for (const auto& tt : {t, std::vector<double>{}}) {
    const auto out = run(s, q, 1, tt);
    const std::size_t m = tt.empty() ? n : nt;
    for (std::size_t i = 0; i < m; ++i) {
      const double* o = &out[10 * i];
      const double scale = std::abs(o[col_hxx]) + std::abs(o[col_hyy]) + std::abs(o[col_hzz]);
      EXPECT_NEAR(o[col_hxx] + o[col_hyy] + o[col_hzz], 0.0, 1e-12 * scale);
      const auto ref = reference_at(tt.empty() ? &s[3 * i] : &tt[3 * i], s, q.data());
      for (int c = 0; c < 10; ++c) {
        // different summation order only; close pairs make terms large: relative to the row's scale
        EXPECT_NEAR(o[c], ref[c], 1e-11 * (std::abs(ref[c]) + scale + 1)) << i << " " << c;
      }
    }
  }
}

TEST_P(LaplaceDirect, TargetsEqualToSourcesSkipSelfPair) {
  const std::size_t n = 50;
  const auto s = random_points(3 * n, 6);
  const auto q = random_points(n, 7);
  EXPECT_EQ(run(s, q, 1, {}), run(s, q, 1, s));  // bitwise: identical arithmetic
}

TEST_P(LaplaceDirect, TargetOnASourceSkipsThatPair) {
  const std::vector<double> s = {0, 0, 0, 1, 0, 0, 0, 2, 0};
  const std::vector<double> q = {1, 2, 3};
  const std::vector<double> t = {1, 0, 0};  // on source 1
  const auto out = run(s, q, 1, t);
  // only sources 0 and 2: distances 1 and sqrt(5)
  EXPECT_NEAR(out[col_pot], 1.0 + 3.0 / std::sqrt(5.0), 1e-15);
  const auto ref = reference_at(t.data(), s, q.data());
  for (int c = 0; c < 10; ++c) EXPECT_NEAR(out[c], ref[c], 1e-14);
}

TEST_P(LaplaceDirect, SeveralChargeVectorsEqualSeparateCalls) {
  const std::size_t n = 600, nd = 4, nt = 40;
  const auto s = random_points(3 * n, 8);
  const auto q = random_points(nd * n, 9);
  const auto t = random_points(3 * nt, 10);
  for (unsigned outputs : {1u, 2u, 4u, 7u}) {
    const auto all = run(s, q, nd, t, outputs);
    for (std::size_t d = 0; d < nd; ++d) {
      const std::vector<double> qd(q.begin() + d * n, q.begin() + (d + 1) * n);
      const auto one = run(s, qd, 1, t, outputs);
      // the shared-geometry path sums sources in blocks (another order): rounding
      // relative to the largest value of that column over all targets
      std::array<double, 10> scale{};
      for (std::size_t i = 0; i < one.size(); ++i) scale[i % 10] = std::max(scale[i % 10], std::abs(one[i]));
      for (std::size_t i = 0; i < one.size(); ++i) {
        EXPECT_NEAR(all[d * nt * 10 + i], one[i], 1e-13 * scale[i % 10]) << d << " " << i;
      }
    }
  }
}

TEST_P(LaplaceDirect, OutputSelectionZeroesTheRest) {
  const std::size_t n = 64;
  const auto s = random_points(3 * n, 11);
  const auto q = random_points(n, 12);
  const auto full = run(s, q, 1, {});
  for (unsigned outputs = 1; outputs <= 7; ++outputs) {
    const auto part = run(s, q, 1, {}, outputs);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t c = 0; c < 10; ++c) {
        const bool want = (c == 0 && (outputs & potential)) || (c >= 1 && c <= 3 && (outputs & gradient)) ||
                          (c >= 4 && (outputs & hessian));
        if (want) {
          EXPECT_NEAR(part[10 * i + c], full[10 * i + c], 1e-13 * (std::abs(full[10 * i + c]) + 1));
        } else {
          EXPECT_EQ(part[10 * i + c], 0.0);
        }
      }
    }
  }
}

TEST_P(LaplaceDirect, ResultIndependentOfThreadCount) {
  const std::size_t n = 1000;
  const auto s = random_points(3 * n, 13);
  const auto q = random_points(2 * n, 14);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto a = run(s, q, 2, {});
  omp_set_num_threads(3);
  const auto b = run(s, q, 2, {});
  omp_set_num_threads(saved);
  EXPECT_EQ(a, b);
}

TEST_P(LaplaceDirect, P2PAccumulates) {
  const std::size_t n = 30;
  const auto s = random_points(3 * n, 15);
  const auto q = random_points(n, 16);
  const auto t = random_points(3 * 5, 17, 2.0, 3.0);
  std::vector<double> sx(n), sy(n), sz(n), tx(5), ty(5), tz(5);
  for (std::size_t j = 0; j < n; ++j) sx[j] = s[3 * j], sy[j] = s[3 * j + 1], sz[j] = s[3 * j + 2];
  for (std::size_t j = 0; j < 5; ++j) tx[j] = t[3 * j], ty[j] = t[3 * j + 1], tz[j] = t[3 * j + 2];
  std::vector<double> out(50, 1.0);
  laplace_p2p_add({sx.data(), sy.data(), sz.data(), n}, q.data(), n, 1, {tx.data(), ty.data(), tz.data(), 5},
                  all_outputs, out.data(), 50);
  const auto ref = run(s, q, 1, t);
  for (std::size_t i = 0; i < 50; ++i) EXPECT_NEAR(out[i], ref[i] + 1.0, 1e-13 * (std::abs(ref[i]) + 1));
}

TEST_P(LaplaceDirect, RejectsBadInput) {
  const std::vector<double> s = {0, 0, 0, 1, 0, 0}, q = {1, 1};
  std::vector<double> out(20);
  auto call = [&](const std::vector<double>& ss, const std::vector<double>& qq, std::size_t nd,
                  const std::vector<double>& tt, unsigned outputs,
                  std::vector<double>& oo) { laplace_direct(ss, qq, nd, tt, outputs, oo); };
  EXPECT_THROW(call({}, {}, 1, {}, 7, out), Error);           // N = 0
  EXPECT_THROW(call({0, 0, 0, 1}, q, 1, {}, 7, out), Error);  // not a multiple of 3
  EXPECT_THROW(call(s, {1}, 1, {}, 7, out), Error);           // charges too short
  EXPECT_THROW(call(s, q, 2, {}, 7, out), Error);             // nd x N mismatch
  EXPECT_THROW(call(s, q, 0, {}, 7, out), Error);             // nd = 0
  EXPECT_THROW(call(s, q, 1, {0, 0}, 7, out), Error);         // targets not multiple of 3
  EXPECT_THROW(call(s, q, 1, {}, 0, out), Error);             // empty output mask
  EXPECT_THROW(call(s, q, 1, {}, 8, out), Error);             // unknown output bit
  std::vector<double> small(19);
  EXPECT_THROW(call(s, q, 1, {}, 7, small), Error);                   // results too short
  EXPECT_THROW(call({0, 0, 0, 1, NAN, 0}, q, 1, {}, 7, out), Error);  // NaN source
  EXPECT_THROW(call(s, {1, INFINITY}, 1, {}, 7, out), Error);         // Inf charge
  std::vector<double> out1(10);
  EXPECT_THROW(call(s, q, 1, {0, NAN, 0}, 7, out1), Error);  // NaN target
  try {
    call(s, {1, NAN}, 1, {}, 7, out);
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("charges"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(call(s, q, 1, {}, 7, out));
  // a single source is fine: zero at itself, 1/r at a target
  std::vector<double> o1(10);
  laplace_direct(std::vector<double>{0, 0, 0}, std::vector<double>{2.0}, 1, std::vector<double>{}, 7, o1);
  for (double v : o1) EXPECT_EQ(v, 0.0);
}

// Overflowing r^2 gives the zero limit (not NaN); tiny separations stay exact as
// long as r^2 and 1/r^5 are normal numbers (|r| in ~[1e-60, 1e154]).
TEST_P(LaplaceDirect, ExtremeSeparationsStayFinite) {
  for (double d : {1e-150, 1e-60, 1e150, 1e170, 1e300}) {
    const auto out = run({0, 0, 0, d, 0, 0}, {1.0, 2.0}, 1, {}, potential);
    const double expect = d < 1e154 ? 1.0 / d : 0.0;
    EXPECT_NEAR(out[col_pot], 2 * expect, 1e-14 * 2 * expect) << d;
    EXPECT_NEAR(out[10 + col_pot], expect, 1e-14 * expect) << d;
    if (d < 1e-60) continue;  // 1/r^5 overflows in the Hessian below ~1e-62
    const auto all = run({0, 0, 0, d, 0, 0}, {1.0, 2.0}, 1, {});
    for (double v : all) EXPECT_TRUE(std::isfinite(v)) << d;
  }
}
