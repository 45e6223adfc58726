// LaplaceFmm features: separate targets, nd densities with per-density outputs, small N, duplicated
// points, permutation and thread-count invariance, plan reuse, far-field-only mode with the near-field
// structure, min_leaf_side guarantee, curl_grad_div and grad_div groups, bad input. References: the
// plain double loop of fmm_test_util.hpp.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <set>

#include "fmm_test_util.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "simd_levels.hpp"

using rpyfmm::Error;
using rpyfmm::fmm::all_outputs;
using rpyfmm::fmm::FmmOptions;
using rpyfmm::fmm::LaplaceFmm;

namespace {
FmmOptions opts(double eps, int leaf) {
  FmmOptions o;
  o.tolerance = eps;
  o.leaf_capacity = leaf;
  return o;
}
std::vector<double> eval(const LaplaceFmm& f, const std::vector<double>& q, std::size_t nd,
                         unsigned out = all_outputs) {
  std::vector<double> r(nd * f.num_targets() * 10);
  f.evaluate(q, nd, out, r);
  return r;
}
void expect_close_all(const std::vector<double>& fmm, const std::vector<double>& ref, std::size_t nd, std::size_t m,
                      double tol, const char* what) {
  std::vector<std::size_t> all(m);
  std::iota(all.begin(), all.end(), 0);
  for (std::size_t d = 0; d < nd; ++d) {
    EXPECT_LE(fmmtest::rel_l2(fmm, m, ref, all, d, 0, 1), tol) << what << " pot d=" << d;
    EXPECT_LE(fmmtest::rel_l2(fmm, m, ref, all, d, 1, 4), tol) << what << " grad d=" << d;
    EXPECT_LE(fmmtest::rel_l2(fmm, m, ref, all, d, 4, 10), tol) << what << " hess d=" << d;
  }
}
}  // namespace

TEST(FmmFeatures, TargetsDifferentFromSources) {
  const auto src = fmmtest::cube(2000, 11);
  auto tgt = fmmtest::cube(1500, 12);
  for (auto& v : tgt) v = 1.6 * v - 0.3;  // partly outside the sources' cube
  for (int k = 0; k < 30; ++k)            // some targets coincide with sources
    for (int c = 0; c < 3; ++c) tgt[3 * k + c] = src[3 * (7 * k) + c];
  for (double eps : {1e-3, 1e-6}) {
    LaplaceFmm f(opts(eps, 20));
    f.set_points(src, tgt);
    EXPECT_EQ(f.num_targets(), 1500u);
    const auto q = fmmtest::charges(2000, 1, 3);
    expect_close_all(eval(f, q, 1), fmmtest::direct(src, q, 1, tgt), 1, 1500, eps, "targets");
  }
}

TEST(FmmFeatures, SeveralDensitiesWithPerDensityOutputs) {
  const std::size_t n = 1000;
  const auto src = fmmtest::plummer(n, 13);
  for (std::size_t nd : {1u, 2u, 4u, 7u}) {  // 2, 4, 7: the lane-batched M2L, full and partial lanes
    LaplaceFmm f(opts(1e-6, 24));
    f.set_points(src);
    const auto q = fmmtest::charges(n, nd, 5);
    std::vector<unsigned> outs(nd);
    for (std::size_t d = 0; d < nd; ++d) outs[d] = unsigned(d % 7) + 1;
    std::vector<double> r(nd * n * 10, 123.0);
    f.evaluate(q, nd, outs, r);
    const auto ref = fmmtest::direct(src, q, nd, {});
    std::vector<std::size_t> all(n);
    std::iota(all.begin(), all.end(), 0);
    for (std::size_t d = 0; d < nd; ++d) {
      const unsigned o = outs[d];
      // One pass with nd densities equals nd single-density passes: the same operations, in another
      // order only in the lane-batched M2L (nd >= 2), hence to rounding.
      std::vector<double> qd(q.begin() + long(d * n), q.begin() + long((d + 1) * n));
      std::vector<double> rd(n * 10);
      const unsigned single[1] = {o};
      f.evaluate(qd, 1, single, rd);
      for (std::size_t i = 0; i < n * 10; ++i)
        EXPECT_NEAR(r[d * n * 10 + i], rd[i], 1e-13 * (1.0 + std::abs(rd[i]))) << "nd=" << nd << " d=" << d;
      if (o & 1u) {
        EXPECT_LE(fmmtest::rel_l2(r, n, ref, all, d, 0, 1), 1e-6);
      }
      if (o & 2u) {
        EXPECT_LE(fmmtest::rel_l2(r, n, ref, all, d, 1, 4), 1e-6);
      }
      if (o & 4u) {
        EXPECT_LE(fmmtest::rel_l2(r, n, ref, all, d, 4, 10), 1e-6);
      }
      // Unrequested columns are exactly zero.
      for (std::size_t t = 0; t < n; ++t) {
        const double* row = &r[(d * n + t) * 10];
        if (!(o & 1u)) {
          EXPECT_EQ(row[0], 0.0);
        }
        if (!(o & 2u)) {
          EXPECT_EQ(std::abs(row[1]) + std::abs(row[2]) + std::abs(row[3]), 0.0);
        }
        if (!(o & 4u)) {
          EXPECT_EQ(std::abs(row[4]) + std::abs(row[5]) + std::abs(row[6]) + std::abs(row[7]) + std::abs(row[8]) +
                        std::abs(row[9]),
                    0.0);
        }
      }
    }
  }
}

TEST(FmmFeatures, TinyN) {
  for (std::size_t n : {1u, 2u, 3u}) {
    const auto src = fmmtest::cube(n, 20 + unsigned(n));
    LaplaceFmm f(opts(1e-6, 0));
    f.set_points(src);
    const auto q = fmmtest::charges(n, 2, 1);
    const auto r = eval(f, q, 2);
    const auto ref = fmmtest::direct(src, q, 2, {});
    for (std::size_t i = 0; i < r.size(); ++i) EXPECT_NEAR(r[i], ref[i], 1e-12 * (1 + std::abs(ref[i]))) << n;
  }
}

TEST(FmmFeatures, DuplicatedPoints) {
  auto base = fmmtest::cube(600, 31);
  std::vector<double> src;
  for (int rep = 0; rep < 3; ++rep) src.insert(src.end(), base.begin(), base.end());
  // plus 200 copies of one point (a box that can never be split)
  for (int k = 0; k < 200; ++k) src.insert(src.end(), {0.25, 0.5, 0.75});
  const std::size_t n = src.size() / 3;
  for (double eps : {1e-3, 1e-9}) {
    LaplaceFmm f(opts(eps, 16));
    f.set_points(src);
    const auto q = fmmtest::charges(n, 1, 2);
    expect_close_all(eval(f, q, 1), fmmtest::direct(src, q, 1, {}), 1, n, eps, "duplicates");
  }
}

TEST(FmmFeatures, PermutationAndThreadInvariance) {
  const auto src = fmmtest::sphere(2000, 41);
  const auto q = fmmtest::charges(2000, 2, 4);
  std::vector<std::size_t> perm(2000);
  std::iota(perm.begin(), perm.end(), 0);
  std::shuffle(perm.begin(), perm.end(), std::mt19937(5));
  std::vector<double> src2(src.size()), q2(q.size());
  for (std::size_t i = 0; i < 2000; ++i) {
    for (int c = 0; c < 3; ++c) src2[3 * i + c] = src[3 * perm[i] + c];
    for (int d = 0; d < 2; ++d) q2[d * 2000 + i] = q[d * 2000 + perm[i]];
  }
  LaplaceFmm f(opts(1e-6, 20));
  f.set_points(src);
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto r1 = eval(f, q, 2);
  omp_set_num_threads(2);
  const auto r2 = eval(f, q, 2);
  omp_set_num_threads(saved);
  EXPECT_EQ(r1, r2);  // bitwise: every box/target is summed by one thread in a fixed order
  LaplaceFmm g(opts(1e-6, 20));
  g.set_points(src2);
  const auto rp = eval(g, q2, 2);
  double worst = 0, scale = 0;
  for (std::size_t i = 0; i < 2000; ++i)
    for (int d = 0; d < 2; ++d)
      for (int c = 0; c < 10; ++c) {
        worst = std::max(worst, std::abs(rp[(d * 2000 + i) * 10 + c] - r1[(d * 2000 + perm[i]) * 10 + c]));
        scale = std::max(scale, std::abs(r1[(d * 2000 + perm[i]) * 10 + c]));
      }
  EXPECT_LE(worst, 1e-12 * scale);  // same tree, summation order within leaves may differ
}

TEST(FmmFeatures, PlanReuse) {
  const auto src = fmmtest::cube(2000, 51);
  LaplaceFmm f(opts(1e-6, 20));
  f.set_points(src);
  const auto qa = fmmtest::charges(2000, 1, 1), qb = fmmtest::charges(2000, 1, 2);
  const auto ra = eval(f, qa, 1), rb = eval(f, qb, 1), ra2 = eval(f, qa, 1);
  EXPECT_EQ(ra, ra2);
  LaplaceFmm g(opts(1e-6, 20));
  g.set_points(src);
  EXPECT_EQ(rb, eval(g, qb, 1));
  const auto t = f.last_timings();
  for (const char* k : {"tree", "p2m", "m2m", "m2l", "l2l", "l2p", "p2p", "total"}) EXPECT_TRUE(t.count(k)) << k;
  const auto st = f.stats();
  EXPECT_GE(st.levels, 3);
  EXPECT_GT(st.memory_bytes, 0u);
}

// The measured per-leaf cost: each target's share of its leaf's time in the leaf passes (L2P, W
// list and far boxes summed directly, P2P), in input order. Bounded by those passes' wall time
// times the threads (each leaf is timed on the thread that ran it), positive somewhere, cleared by
// set_points; the results do not depend on it.
TEST(FmmFeatures, LastTargetCostsShareTheLeafPassesMeasuredTime) {
  const auto src = fmmtest::plummer(6000, 71), tgt = fmmtest::cube(3000, 72);
  LaplaceFmm f(opts(1e-6, 20));
  f.set_points(src, tgt);
  EXPECT_TRUE(f.last_target_costs().empty());
  const auto q = fmmtest::charges(6000, 1, 3);
  const auto r = eval(f, q, 1);
  const std::vector<double> costs = f.last_target_costs();
  ASSERT_EQ(costs.size(), 3000u);
  double sum = 0.0;
  for (const double c : costs) {
    EXPECT_TRUE(std::isfinite(c) && c >= 0.0) << c;
    sum += c;
  }
  const auto t = f.last_timings();
  const double leaf_passes = t.at("l2p") + t.at("wx_far") + t.at("p2p");
  EXPECT_GT(sum, 0.0);
  EXPECT_LE(sum, leaf_passes * omp_get_max_threads() * 1.05 + 1e-4);
  EXPECT_EQ(eval(f, q, 1), r);  // measuring changes no result
  f.set_points(src, tgt);
  EXPECT_TRUE(f.last_target_costs().empty());
}

TEST(FmmFeatures, FarFieldOnlyPlusNearFieldStructureIsComplete) {
  const auto src = fmmtest::plummer(1500, 61);
  auto tgt = fmmtest::plummer(600, 62);
  // export_direct_far: the W/X direct sums move to the caller too (more pairs, none twice).
  std::size_t pairs_without_export = 0;
  for (const bool exported : {false, true})
    for (const bool separate : {false, true}) {
      const std::vector<double>& T = separate ? tgt : std::vector<double>{};
      FmmOptions o = opts(1e-6, 24);
      o.near_field = false;
      o.export_direct_far = exported;
      LaplaceFmm f(o);
      f.set_points(src, T);
      const std::size_t m = f.num_targets();
      const auto q = fmmtest::charges(1500, 1, 9);
      auto r = eval(f, q, 1);
      const auto& nf = f.near_field();
      const std::set<std::pair<std::uint32_t, std::uint32_t>> distinct(nf.pairs.begin(), nf.pairs.end());
      EXPECT_EQ(distinct.size(), nf.pairs.size());
      if (!exported && !separate) pairs_without_export = nf.pairs.size();
      if (exported && !separate) {
        EXPECT_GT(nf.pairs.size(), pairs_without_export);
      }
      // Every source and target is in exactly one leaf.
      std::vector<int> seen_s(1500, 0), seen_t(m, 0);
      for (std::size_t l = 0; l < nf.num_leaves(); ++l) {
        for (auto i : nf.sources(l)) ++seen_s[i];
        for (auto i : nf.targets(l)) ++seen_t[i];
      }
      EXPECT_TRUE(std::all_of(seen_s.begin(), seen_s.end(), [](int c) { return c == 1; }));
      EXPECT_TRUE(std::all_of(seen_t.begin(), seen_t.end(), [](int c) { return c == 1; }));
      // Caller-side exact near field over the pairs.
      const std::vector<double>& TT = separate ? tgt : src;
      for (const auto& [tl, sl] : nf.pairs)
        for (auto i : nf.targets(tl))
          for (auto j : nf.sources(sl)) {
            const double dx = TT[3 * i] - src[3 * j], dy = TT[3 * i + 1] - src[3 * j + 1],
                         dz = TT[3 * i + 2] - src[3 * j + 2];
            const double r2 = dx * dx + dy * dy + dz * dz;
            if (r2 == 0) continue;
            const double rr = std::sqrt(r2), r3 = rr * r2, r5 = r3 * r2;
            double* o2 = &r[i * 10];
            o2[0] += q[j] / rr;
            o2[1] -= q[j] * dx / r3;
            o2[2] -= q[j] * dy / r3;
            o2[3] -= q[j] * dz / r3;
            o2[4] += q[j] * (3 * dx * dx / r5 - 1 / r3);
            o2[5] += q[j] * (3 * dy * dy / r5 - 1 / r3);
            o2[6] += q[j] * (3 * dz * dz / r5 - 1 / r3);
            o2[7] += q[j] * 3 * dx * dy / r5;
            o2[8] += q[j] * 3 * dx * dz / r5;
            o2[9] += q[j] * 3 * dy * dz / r5;
          }
      expect_close_all(r, fmmtest::direct(src, q, 1, separate ? tgt : std::vector<double>{}), 1, m, 1e-6, "far+near");
    }
}

TEST(FmmFeatures, MinLeafSideKeepsClosePairsInTheNearField) {
  const auto src = fmmtest::plummer(1500, 71);
  const double a = 0.3;
  FmmOptions o = opts(1e-6, 4);
  o.min_leaf_side = a;
  LaplaceFmm f(o);
  f.set_points(src);
  const auto& nf = f.near_field();
  std::vector<std::size_t> leaf_of(1500);
  for (std::size_t l = 0; l < nf.num_leaves(); ++l)
    for (auto i : nf.sources(l)) leaf_of[i] = l;
  std::set<std::pair<std::size_t, std::size_t>> pairs;
  for (const auto& pr : nf.pairs) pairs.insert({pr.first, pr.second});
  std::size_t close = 0;
  for (std::size_t i = 0; i < 1500; ++i)
    for (std::size_t j = 0; j < 1500; ++j) {
      const double dx = src[3 * i] - src[3 * j], dy = src[3 * i + 1] - src[3 * j + 1],
                   dz = src[3 * i + 2] - src[3 * j + 2];
      if (dx * dx + dy * dy + dz * dz < a * a) {
        ++close;
        ASSERT_TRUE(pairs.count({leaf_of[i], leaf_of[j]})) << i << " " << j;
      }
    }
  EXPECT_GT(close, 1500u);
  EXPECT_GT(f.stats().leaves, 8u);  // the option did not just disable the tree
}

// An enlarged root anchored at the points' low corner (FmmOptions::root_scale, used by FmmRpy's
// fitted leaf grid) changes only the tree: results stay within eps of the direct sums, with
// targets apart from the sources too, and the leaf side is root_scale x side / 2^level.
TEST(FmmFeatures, RootScaleFitsTheLeafGrid) {
  const auto src = fmmtest::cube(3000, 21);
  auto tgt = fmmtest::cube(800, 22);
  for (auto& v : tgt) v = 1.2 * v - 0.1;
  const auto q = fmmtest::charges(3000, 2, 23);
  const auto ref_src = fmmtest::direct(src, q, 2, {}), ref_tgt = fmmtest::direct(src, q, 2, tgt);
  for (double scale : {8.0 / 7.0, 1.6, 1.99}) {
    for (double eps : {1e-3, 1e-6}) {
      FmmOptions o = opts(eps, 30);
      o.root_scale = scale;
      LaplaceFmm f(o);
      f.set_points(src);
      expect_close_all(eval(f, q, 2), ref_src, 2, 3000, eps, "sources");
      f.set_points(src, tgt);
      expect_close_all(eval(f, q, 2), ref_tgt, 2, 800, eps, "targets");
    }
  }
  // 3000 uniform points, at most 60 per leaf: the bounding cube gives 4^3 = 64 leaves of ~47
  // points; with root_scale = 8/5 the cloud spans 5^3 = 125 level-3 boxes of ~24, one leaf each
  // except where a level-2 box of the boundary layer holds only two of them (<= 60 points) and
  // stays whole.
  FmmOptions o = opts(1e-3, 60);
  LaplaceFmm plain(o);
  plain.set_points(src);
  o.root_scale = 1.6;
  LaplaceFmm fitted(o);
  fitted.set_points(src);
  EXPECT_EQ(plain.stats().leaves, 64u);
  EXPECT_GT(fitted.stats().leaves, 100u);
  EXPECT_LE(fitted.stats().leaves, 125u);
}

namespace {
// The results of the same densities with the `grouped` and with the `raw` flags on one plan
// (leaves of 24 points, 1e-6) at an instruction-set level, in mode 0 (near field), 1 (far field
// only) or 2 (W/X direct sums exported); `what` names the case.
struct GroupedRuns {
  std::vector<double> grouped, raw;
  std::string what;
};
GroupedRuns grouped_and_raw(const std::vector<double>& src, const std::vector<double>& q, std::size_t nd,
                            const std::vector<unsigned>& grouped, const std::vector<unsigned>& raw,
                            rpyfmm::SimdLevel level, int mode) {
  const rpyfmm::ScopedSimdLevel scope(level);
  FmmOptions o = opts(1e-6, 24);
  o.near_field = mode == 0;
  o.export_direct_far = mode == 2;
  LaplaceFmm f(o);
  f.set_points(src);
  const std::size_t n = src.size() / 3;
  GroupedRuns runs{std::vector<double>(nd * n * 10, 123.0), std::vector<double>(nd * n * 10),
                   std::string(rpyfmm::simd_level_name(level)) + " mode " + std::to_string(mode)};
  f.evaluate(q, nd, grouped, runs.grouped);
  f.evaluate(q, nd, raw, runs.raw);
  return runs;
}

// curl and grad div of the group (phi_1, phi_2, phi_3) starting at density d, from its gradient
// and Hessian columns, by their definitions: (curl Phi)_c = eps_cab d_a phi_b, (grad div Phi)_c =
// sum_m d_c d_m phi_m. Returns m x 6.
std::vector<double> curl_grad_div_of(const std::vector<double>& r, std::size_t d, std::size_t m) {
  constexpr std::size_t hessian_column[3][3] = {{4, 7, 8}, {7, 5, 9}, {8, 9, 6}};
  const auto row = [&](std::size_t k, std::size_t t) { return &r[((d + k) * m + t) * 10]; };
  std::vector<double> out(6 * m, 0.0);
  for (std::size_t t = 0; t < m; ++t)
    for (std::size_t c = 0; c < 3; ++c) {
      const std::size_t c1 = (c + 1) % 3, c2 = (c + 2) % 3;
      out[6 * t + c] = row(c2, t)[1 + c1] - row(c1, t)[1 + c2];
      for (std::size_t k = 0; k < 3; ++k) out[6 * t + 3 + c] += row(k, t)[hessian_column[c][k]];
    }
  return out;
}
}  // namespace

// Groups flagged curl_grad_div give the curl and grad div of their gradient and Hessian columns to
// rounding, at every instruction-set level, with the near field, without it and with the W/X direct
// sums exported; the other densities are untouched, the rest of the group's rows zero.
TEST(FmmFeatures, CurlGradDivGroupsFoldTheGradientsAndHessians) {
  using rpyfmm::fmm::curl_grad_div;
  const std::size_t n = 1500, nd = 7;
  const auto src = fmmtest::plummer(n, 71);
  const auto q = fmmtest::charges(n, nd, 72);
  const std::vector<unsigned> grouped = {all_outputs,   curl_grad_div, curl_grad_div, curl_grad_div,
                                         curl_grad_div, curl_grad_div, curl_grad_div};
  const std::vector<unsigned> raw = {all_outputs, 6u, 6u, 6u, 6u, 6u, 6u};
  const auto ref = fmmtest::direct(src, q, nd, {});
  for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels())
    for (int mode = 0; mode < 3; ++mode) {
      const auto [r, rr, what] = grouped_and_raw(src, q, nd, grouped, raw, level, mode);
      for (std::size_t i = 0; i < n * 10; ++i) ASSERT_EQ(r[i], rr[i]) << what;
      for (std::size_t d : {1u, 4u}) {
        const auto expected = curl_grad_div_of(rr, d, n);
        double scale = 0.0;
        for (double v : expected) scale = std::max(scale, std::abs(v));
        for (std::size_t t = 0; t < n; ++t) {
          const double* row = &r[(d * n + t) * 10];
          for (int k = 0; k < 6; ++k) ASSERT_NEAR(row[1 + k], expected[6 * t + std::size_t(k)], 1e-13 * scale) << what;
          EXPECT_EQ(std::abs(row[0]) + std::abs(row[7]) + std::abs(row[8]) + std::abs(row[9]), 0.0) << what;
          for (std::size_t k = 0; k < 10; ++k) {
            ASSERT_EQ(r[((d + 1) * n + t) * 10 + k], 0.0) << what;
            ASSERT_EQ(r[((d + 2) * n + t) * 10 + k], 0.0) << what;
          }
        }
        if (mode == 0) {  // against the direct sums' curl and grad div
          const auto exact = curl_grad_div_of(ref, d, n);
          double err[2] = {}, norm[2] = {};
          for (std::size_t t = 0; t < n; ++t)
            for (int k = 0; k < 6; ++k) {
              const double e = r[(d * n + t) * 10 + 1 + std::size_t(k)] - exact[6 * t + std::size_t(k)];
              err[k / 3] += e * e;
              norm[k / 3] += exact[6 * t + std::size_t(k)] * exact[6 * t + std::size_t(k)];
            }
          EXPECT_LE(std::sqrt(err[0] / norm[0]), 1e-6) << what << " curl";
          EXPECT_LE(std::sqrt(err[1] / norm[1]), 1e-6) << what << " grad div";
        }
      }
    }
}

namespace {
// grad div of the group (phi_1, phi_2, phi_3) starting at density d, from its Hessian columns:
// (grad div Phi)_c = sum_m d_c d_m phi_m. Returns m x 3.
std::vector<double> grad_div_of(const std::vector<double>& r, std::size_t d, std::size_t m) {
  const auto both = curl_grad_div_of(r, d, m);
  std::vector<double> out(3 * m);
  for (std::size_t t = 0; t < m; ++t) std::copy_n(&both[6 * t + 3], 3, &out[3 * t]);
  return out;
}
}  // namespace

// Groups flagged grad_div give grad div of their Hessian columns to rounding, and each density's
// own potential and gradient exactly as without the flag, at every instruction-set level, with
// the near field, without it and with the W/X direct sums exported; a curl_grad_div group ahead of
// them and the ungrouped densities are untouched, the other Hessian columns of the group zero.
TEST(FmmFeatures, GradDivGroupsFoldTheHessians) {
  using rpyfmm::fmm::curl_grad_div;
  using rpyfmm::fmm::grad_div;
  constexpr unsigned pot = rpyfmm::fmm::potential, grad = rpyfmm::fmm::gradient, hess = rpyfmm::fmm::hessian;
  const std::size_t n = 1500, nd = 11;
  const auto src = fmmtest::plummer(n, 73);
  const auto q = fmmtest::charges(n, nd, 74);
  const std::vector<unsigned> grouped = {
      all_outputs, curl_grad_div, curl_grad_div, curl_grad_div, grad_div | pot | grad, grad_div | grad, grad_div | pot,
      grad_div,    grad_div,      grad_div,      pot | grad};
  std::vector<unsigned> raw = {all_outputs, 6u, 6u, 6u, 0u, 0u, 0u, 0u, 0u, 0u, pot | grad};
  for (std::size_t d = 4; d < 10; ++d) raw[d] = (grouped[d] & (pot | grad)) | hess;
  const auto ref = fmmtest::direct(src, q, nd, {});
  for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels())
    for (int mode = 0; mode < 3; ++mode) {
      const auto [r, rr, what] = grouped_and_raw(src, q, nd, grouped, raw, level, mode);
      for (std::size_t d : {0u, 10u})
        for (std::size_t i = d * n * 10; i < (d + 1) * n * 10; ++i) ASSERT_EQ(r[i], rr[i]) << what << " density " << d;
      const auto curl = curl_grad_div_of(rr, 1, n);
      double curl_scale = 0.0;
      for (double v : curl) curl_scale = std::max(curl_scale, std::abs(v));
      for (std::size_t t = 0; t < n; ++t)
        for (std::size_t k = 0; k < 6; ++k)
          ASSERT_NEAR(r[(n + t) * 10 + 1 + k], curl[6 * t + k], 1e-13 * curl_scale) << what << " curl_grad_div group";
      for (std::size_t d : {4u, 7u}) {
        const auto expected = grad_div_of(rr, d, n);
        double scale = 0.0;
        for (double v : expected) scale = std::max(scale, std::abs(v));
        for (std::size_t t = 0; t < n; ++t)
          for (std::size_t k = 0; k < 3; ++k) {
            const double* row = &r[((d + k) * n + t) * 10];
            for (std::size_t c = 0; c < 4; ++c) ASSERT_EQ(row[c], rr[((d + k) * n + t) * 10 + c]) << what;
            ASSERT_NEAR(r[(d * n + t) * 10 + 4 + k], expected[3 * t + k], 1e-13 * scale) << what;
            for (std::size_t c = k == 0 ? 7 : 4; c < 10; ++c) ASSERT_EQ(row[c], 0.0) << what << " column " << c;
          }
        if (mode == 0) {  // against the direct sums' grad div
          const auto exact = grad_div_of(ref, d, n);
          double err = 0.0, norm = 0.0;
          for (std::size_t t = 0; t < n; ++t)
            for (std::size_t k = 0; k < 3; ++k) {
              const double e = r[(d * n + t) * 10 + 4 + k] - exact[3 * t + k];
              err += e * e;
              norm += exact[3 * t + k] * exact[3 * t + k];
            }
          EXPECT_LE(std::sqrt(err / norm), 1e-6) << what << " grad div, group " << d;
        }
      }
    }
}

// filled_result_columns names exactly the columns evaluate fills: every other column is 0 at every
// target, and each named column is nonzero at some target (random charges at distinct points give
// nonzero sums almost surely), for plain, curl_grad_div and grad_div densities at every
// instruction-set level, with the near field and without it. Callers move these columns alone
// (DistributedLaplaceFmm's results between ranks), so a column evaluate fills but the list misses
// would be lost there.
TEST(FmmFeatures, FilledResultColumnsAreThoseEvaluateFills) {
  using rpyfmm::fmm::curl_grad_div;
  using rpyfmm::fmm::grad_div;
  constexpr unsigned pot = rpyfmm::fmm::potential, grad = rpyfmm::fmm::gradient, hess = rpyfmm::fmm::hessian;
  const std::size_t n = 800;
  const std::vector<unsigned> outputs = {
      all_outputs, curl_grad_div, curl_grad_div, curl_grad_div, grad_div | pot | grad, grad_div | grad, grad_div | pot,
      pot,         grad,          hess,          pot | hess};
  const std::size_t nd = outputs.size();
  const auto src = fmmtest::plummer(n, 91);
  const auto q = fmmtest::charges(n, nd, 92);
  const auto filled = rpyfmm::fmm::filled_result_columns(outputs);
  ASSERT_EQ(filled.size(), nd);
  for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels())
    for (bool near : {true, false}) {
      const rpyfmm::ScopedSimdLevel scoped(level);
      FmmOptions o = opts(1e-6, 24);
      o.near_field = near;
      LaplaceFmm f(o);
      f.set_points(src);
      std::vector<double> r(nd * n * 10, 123.0);  // evaluate overwrites every column
      f.evaluate(q, nd, outputs, r);
      for (std::size_t d = 0; d < nd; ++d)
        for (std::size_t c = 0; c < 10; ++c) {
          const bool listed = std::ranges::find(filled[d], c) != filled[d].end();
          bool nonzero = false;
          for (std::size_t t = 0; t < n; ++t) nonzero = nonzero || r[(d * n + t) * 10 + c] != 0.0;
          EXPECT_EQ(nonzero, listed) << "density " << d << " column " << c << " near field " << near;
        }
    }
}

TEST(FmmFeatures, BadInput) {
  auto expect_error = [](auto&& fn, const char* needle) {
    try {
      fn();
      ADD_FAILURE() << "no throw: " << needle;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error([] { LaplaceFmm f(opts(1.0, 0)); }, "tolerance");
  expect_error([] { LaplaceFmm f(opts(1e-16, 0)); }, "tolerance");
  expect_error([] { LaplaceFmm f(opts(std::nan(""), 0)); }, "tolerance");
  expect_error([] { LaplaceFmm f(opts(1e-6, -1)); }, "leaf_capacity");
  for (double scale : {0.5, 9.0, std::nan("")}) {
    FmmOptions o = opts(1e-6, 0);
    o.root_scale = scale;
    expect_error([&] { LaplaceFmm f(o); }, "root_scale");
  }
  LaplaceFmm f(opts(1e-6, 0));
  std::vector<double> x = fmmtest::cube(10, 1), q(10, 1.0), r(100);
  expect_error([&] { f.evaluate(q, 1, all_outputs, r); }, "set_points");
  expect_error([&] { f.set_points({}); }, "N = 0");
  expect_error([&] { f.set_points(std::vector<double>(7, 0.0)); }, "multiple of 3");
  auto bad = x;
  bad[13] = std::nan("");
  expect_error([&] { f.set_points(bad); }, "sources entry (4, 1) is NaN");
  bad[13] = INFINITY;
  expect_error([&] { f.set_points(x, bad); }, "targets entry (4, 1) is infinite");
  f.set_points(x);
  expect_error([&] { f.evaluate(std::vector<double>(9, 1.0), 1, all_outputs, r); }, "charges");
  std::vector<double> r99(99);
  expect_error([&] { f.evaluate(q, 1, all_outputs, r99); }, "results");
  expect_error([&] { f.evaluate(q, 1, 8u, r); }, "outputs[0]");
  expect_error([&] { f.evaluate(q, 1, 0u, r); }, "outputs[0]");
  // curl_grad_div and grad_div in groups of three: cut short at the end, or mixed with other flags;
  // grad_div with potential | gradient only.
  const std::vector<double> q3(30, 1.0);
  std::vector<double> r3(300);
  using rpyfmm::fmm::curl_grad_div;
  using rpyfmm::fmm::grad_div;
  const unsigned gpg = grad_div | rpyfmm::fmm::potential | rpyfmm::fmm::gradient;
  const std::pair<std::vector<unsigned>, const char*> bad_groups[] = {
      {{all_outputs, curl_grad_div, curl_grad_div}, "groups of three consecutive densities, from outputs[1]"},
      {{curl_grad_div, curl_grad_div, all_outputs}, "from outputs[0]"},
      {{9u, 9u, 9u}, "outputs[0]"},
      {{all_outputs, grad_div, gpg}, "groups of three consecutive densities, from outputs[1]"},
      {{grad_div, curl_grad_div, grad_div}, "from outputs[0]"},
      {{grad_div | rpyfmm::fmm::hessian, grad_div, grad_div}, "from outputs[0]"},
      {{grad_div | curl_grad_div, grad_div, grad_div}, "outputs[0]"}};
  for (const auto& [flags, needle] : bad_groups) expect_error([&] { f.evaluate(q3, 3, flags, r3); }, needle);
  EXPECT_NO_THROW(f.evaluate(q3, 3, curl_grad_div, r3));
  EXPECT_NO_THROW(f.evaluate(q3, 3, std::vector<unsigned>{gpg, grad_div, grad_div | rpyfmm::fmm::gradient}, r3));
  auto qn = q;
  qn[3] = std::nan("");
  expect_error([&] { f.evaluate(qn, 1, all_outputs, r); }, "charges");
  EXPECT_NO_THROW(f.evaluate(q, 1, all_outputs, r));
}
