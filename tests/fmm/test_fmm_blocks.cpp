// Building blocks of the FMM against independent references (docs/theory/fmm.md): solid harmonics
// vs the classical Legendre recurrence, P2M/M2P and P2L/L2P with gradient and Hessian vs direct sums,
// the vectorized P2M/L2P vs their one-point forms (expansion_reference.hpp),
// M2M exactness, L2L, rotations, the plane-wave M2L chain for one box pair at all 189 offsets and all
// four tables, and the merge-and-shift group table.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <random>

#include "expansion_reference.hpp"
#include "fmm_test_util.hpp"
#include "rpyfmm/fmm/detail/expansions.hpp"
#include "rpyfmm/fmm/detail/planewave.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

using namespace rpyfmm::fmm::detail;

namespace {
double fact(int k) {
  double f = 1;
  for (int i = 2; i <= k; ++i) f *= i;
  return f;
}
// Associated Legendre function with the Condon-Shortley phase, by the classical recurrence in
// cos(theta) (long double), independent of the Cartesian recurrences under test.
double legendre_cs(int n, int m, double x) {
  long double pmm = 1.0L;
  const long double sq = std::sqrt(1.0L - (long double)x * x);
  for (int i = 1; i <= m; ++i) pmm *= -(2.0L * i - 1.0L) * sq;
  if (n == m) return double(pmm);
  long double p1 = x * (2.0L * m + 1.0L) * pmm;
  if (n == m + 1) return double(p1);
  long double p0 = pmm;
  for (int k = m + 2; k <= n; ++k) {
    const long double p2 = ((2.0L * k - 1.0L) * x * p1 - (k + m - 1.0L) * p0) / (k - m);
    p0 = p1;
    p1 = p2;
  }
  return double(p1);
}
struct Pts {
  std::vector<double> xyz, q;
};
// n random charges in a box of side s at center c, the 8 corners (just inside) included.
Pts box_charges(int n, const double* c, double s, unsigned seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5), uq(-1, 1);
  Pts p;
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) p.xyz.push_back(c[k] + s * (i < 8 ? 0.4999 * (((i >> k) & 1) ? 1 : -1) : u(g)));
    p.q.push_back(uq(g));
  }
  return p;
}
}  // namespace

TEST(FmmBlocks, SolidHarmonicsMatchLegendre) {
  const int p = 50;
  const Harmonics H(p + 2);
  std::vector<cplx> R(ncoef(p)), S(ncoef(p));
  const double pts[][3] = {{0.3, -0.2, 0.25}, {0.0, 0.0, 0.7}, {0.0, 0.0, -0.6}, {-0.5, 0.1, 0.0}};
  for (const auto& v : pts) {
    H.regular(p, v[0], v[1], v[2], R.data());
    const double r = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    H.singular(p, v[0] / (r * r) * 2.0, v[1] / (r * r) * 2.0, v[2] / (r * r) * 2.0, S.data());  // |.| = 2/r > 1
    const double rs = 2.0 / r;
    const double ct = v[2] / r, ph = std::atan2(v[1], v[0]);
    for (int n = 0; n <= p; ++n)
      for (int m = 0; m <= n; ++m) {
        const double P = legendre_cs(n, m, ct);
        const cplx e(std::cos(m * ph), std::sin(m * ph));
        const cplx Rref = std::pow(r, n) * P * e / fact(n + m);
        const cplx Sref = fact(n - m) * P * e / std::pow(rs, n + 1);
        // Relative to the bounds |R| <= r^n / c_n^m, |S| <= c_n^m / r^(n+1): near a root of
        // P_n^m a pointwise relative error is meaningless.
        const double cnm = std::sqrt(fact(n - m) * fact(n + m));
        EXPECT_LE(std::abs(R[idx(n, m)] - Rref), 1e-13 * std::pow(r, n) / cnm) << n << " " << m;
        EXPECT_LE(std::abs(S[idx(n, m)] - Sref), 1e-13 * cnm / std::pow(rs, n + 1)) << n << " " << m;
      }
  }
}

// P2M + M2P and P2L + L2P with gradient/Hessian vs direct sums, at two absolute scales (catches a
// missing 1/s), side 1 and 1e-3.
TEST(FmmBlocks, FormAndEvaluateWithDerivatives) {
  const int p = 30;
  const Harmonics& H = Harmonics::cached(p + 2);
  for (double L : {1.0, 1e-3}) {
    const double c[3] = {0.1 * L, -0.2 * L, 0.3 * L}, s = L;
    const auto src = box_charges(40, c, s, 3);
    std::vector<cplx> Mh(ncoef(p)), a(ncoef(p)), T(ncoef(p + 2));
    fmmtest::p2m_reference(H, p, s, c, src.xyz.data(), src.q.data(), 0, 1, 40, Mh.data(), T.data());
    multipole_to_a(H, p, Mh.data(), a.data());
    // targets 3 box sides away: ratio (sqrt(3)/2)/3 -> truncation ~ 0.29^31 ~ 1e-17
    std::vector<double> tg = {c[0] + 3 * s,   c[1] + 0.5 * s, c[2] - 0.7 * s,
                              c[0] - 1.2 * s, c[1] - 3.1 * s, c[2] + 0.2 * s};
    const auto ref = fmmtest::direct(src.xyz, src.q, 1, tg);
    for (int t = 0; t < 2; ++t) {
      double out[10] = {};
      H.singular(p + 2, (tg[3 * t] - c[0]) / s, (tg[3 * t + 1] - c[1]) / s, (tg[3 * t + 2] - c[2]) / s, T.data());
      m2p_eval(p, s, a.data(), T.data(), 7u, out);
      for (int k = 0; k < 10; ++k)
        EXPECT_NEAR(out[k], ref[t * 10 + k],
                    1e-12 * std::abs(ref[t * 10]) /
                        std::pow(L, k == 0  ? 0
                                    : k < 4 ? 1
                                            : 2))
            << "M2P L=" << L << " k=" << k;
      EXPECT_NEAR(out[4] + out[5] + out[6], 0.0, 1e-12 / (L * L * L));
    }
    // P2L from far sources, L2P at points inside the box.
    const double cf[3] = {c[0] + 3 * s, c[1], c[2] + 0.5 * s};
    const auto far = box_charges(40, cf, s, 4);
    std::vector<cplx> Lh(ncoef(p)), b(ncoef(p));
    p2l(H, p, s, c, far.xyz.data(), far.q.data(), 0, 1, 40, Lh.data(), T.data());
    local_to_b(H, p, Lh.data(), b.data());
    const auto inside = box_charges(6, c, s, 5);
    const auto ref2 = fmmtest::direct(far.xyz, far.q, 1, inside.xyz);
    for (int t = 0; t < 6; ++t) {
      double out[10] = {};
      H.regular(p, (inside.xyz[3 * t] - c[0]) / s, (inside.xyz[3 * t + 1] - c[1]) / s,
                (inside.xyz[3 * t + 2] - c[2]) / s, T.data());
      fmmtest::l2p_reference(p, s, b.data(), T.data(), 7u, out);
      for (int k = 0; k < 10; ++k)
        EXPECT_NEAR(out[k], ref2[t * 10 + k],
                    1e-10 * std::abs(ref2[t * 10]) /
                        std::pow(L, k == 0  ? 0
                                    : k < 4 ? 1
                                            : 2))
            << "L2P L=" << L << " k=" << k;
    }
  }
}

// The vectorized P2M and L2P of the library (whole and partial lane blocks, two densities) match
// the one-point forms.
TEST(FmmBlocks, VectorizedP2MAndL2PMatchOnePointForms) {
  const int p = 20, nc = ncoef(p);
  const Harmonics& H = Harmonics::cached(p + 2);
  const double c[3] = {0.3, -0.1, 0.2}, s = 0.5;
  const std::size_t n = 13, nd = 2;
  auto pts = box_charges(int(n), c, s, 7);
  const auto more = box_charges(int(n), c, s, 8);
  pts.q.insert(pts.q.end(), more.q.begin(), more.q.end());  // density 1
  std::vector<cplx> ref(nd * nc), got(nd * nc), R(nc);
  fmmtest::p2m_reference(H, p, s, c, pts.xyz.data(), pts.q.data(), n, nd, n, ref.data(), R.data());
  std::vector<double> scratch(2 * std::size_t(nc) * kL2PLanes);
  double ux[kL2PLanes], uy[kL2PLanes], uz[kL2PLanes];
  auto lanes = [&](std::size_t j0) {  // scaled offsets of the points j0 ... j0 + kL2PLanes - 1
    const int np = int(std::min<std::size_t>(kL2PLanes, n - j0));
    for (int t = 0; t < np; ++t) {
      ux[t] = (pts.xyz[3 * (j0 + t)] - c[0]) / s;
      uy[t] = (pts.xyz[3 * (j0 + t) + 1] - c[1]) / s;
      uz[t] = (pts.xyz[3 * (j0 + t) + 2] - c[2]) / s;
    }
    return np;
  };
  for (std::size_t j0 = 0; j0 < n; j0 += kL2PLanes) {
    const int np = lanes(j0);
    p2m_block(p, H.regular_recurrence(), H.c_table(), np, ux, uy, uz, &pts.q[j0], n, nd, got.data(), scratch.data());
  }
  for (int i = 0; i < int(nd) * nc; ++i) EXPECT_NEAR(std::abs(got[i] - ref[i]), 0.0, 1e-13 * (1 + std::abs(ref[i])));

  // L2P of the multipoles read as local coefficients b: any coefficients will do for the comparison.
  const unsigned flags[2] = {7u, 3u};
  std::vector<double> out_ref(nd * n * 10, 0.0), out(nd * n * 10, 0.0);
  for (std::size_t t = 0; t < n; ++t) {
    H.regular(p, (pts.xyz[3 * t] - c[0]) / s, (pts.xyz[3 * t + 1] - c[1]) / s, (pts.xyz[3 * t + 2] - c[2]) / s,
              R.data());
    for (std::size_t d = 0; d < nd; ++d)
      fmmtest::l2p_reference(p, s, &ref[d * nc], R.data(), flags[d], &out_ref[(d * n + t) * 10]);
  }
  for (std::size_t t0 = 0; t0 < n; t0 += kL2PLanes) {
    const int nt = lanes(t0);
    l2p_block(p, s, H.regular_recurrence(), ref.data(), nd, flags, nt, ux, uy, uz, &out[t0 * 10], n * 10,
              scratch.data());
  }
  for (std::size_t i = 0; i < out.size(); ++i)
    EXPECT_NEAR(out[i], out_ref[i], 1e-12 * (1 + std::abs(out_ref[i]))) << "entry " << i;
}

TEST(FmmBlocks, RotationsAreUnitaryAndPreserveValues) {
  const int p = 20;
  const Rotation A = Rotation::about_y(p, 0.7);
  const Rotation B(p, {0, 0, 1, 1, 0, 0, 0, 1, 0});  // Q_Y, generic complex path
  for (const Rotation* R : {&A, &B})
    for (int n = 0; n <= p; ++n)
      for (int i = -n; i <= n; ++i)
        for (int j = -n; j <= n; ++j) {
          cplx dot = 0;
          for (int k = -n; k <= n; ++k) dot += R->entry(n, i, k) * std::conj(R->entry(n, j, k));
          EXPECT_NEAR(std::abs(dot - cplx(i == j ? 1.0 : 0.0)), 0.0, 1e-13);
        }
  // D^n_00 of Ry(t) is P_n(cos t).
  for (int n = 0; n <= p; ++n) EXPECT_NEAR(A.entry(n, 0, 0).real(), std::legendre(unsigned(n), std::cos(0.7)), 1e-13);
}

// M2M is exact for degrees <= p: M2M(P2M about the child) == P2M about the parent, all 8 children.
TEST(FmmBlocks, M2MIsExactAndL2LMatchesDirect) {
  for (int p : {12, 25}) {
    const Harmonics& H = Harmonics::cached(p + 2);
    const ChildTranslations T(p);
    const double s = 0.25, cp[3] = {0.3, 0.1, -0.2};
    std::vector<cplx> work(2 * ncoef(p)), scratch(ncoef(p + 2));
    for (int o = 0; o < 8; ++o) {
      const double cc[3] = {cp[0] + ((o & 1) ? 0.25 : -0.25) * 2 * s, cp[1] + ((o & 2) ? 0.25 : -0.25) * 2 * s,
                            cp[2] + ((o & 4) ? 0.25 : -0.25) * 2 * s};
      const auto src = box_charges(20, cc, s, 10 + o);
      std::vector<cplx> Mc(ncoef(p)), Mp(ncoef(p)), Mref(ncoef(p));
      fmmtest::p2m_reference(H, p, s, cc, src.xyz.data(), src.q.data(), 0, 1, 20, Mc.data(), scratch.data());
      fmmtest::p2m_reference(H, p, 2 * s, cp, src.xyz.data(), src.q.data(), 0, 1, 20, Mref.data(), scratch.data());
      T.m2m(o, Mc.data(), Mp.data(), work.data());
      double err = 0, mx = 0;
      for (int i = 0; i < ncoef(p); ++i) {
        err = std::max(err, std::abs(Mp[i] - Mref[i]));
        mx = std::max(mx, std::abs(Mref[i]));
      }
      EXPECT_LE(err, 1e-13 * mx) << "p=" << p << " octant " << o;
      // L2L: local of far sources at the parent, shifted to the child, vs direct at child points.
      const double cf[3] = {cp[0] + 6 * s, cp[1] - 2 * s, cp[2]};
      const auto far = box_charges(30, cf, 2 * s, 20 + o);
      std::vector<cplx> Lp(ncoef(p)), Lc(ncoef(p)), b(ncoef(p));
      p2l(H, p, 2 * s, cp, far.xyz.data(), far.q.data(), 0, 1, 30, Lp.data(), scratch.data());
      T.l2l(o, Lp.data(), Lc.data(), work.data());
      local_to_b(H, p, Lc.data(), b.data());
      const auto pts = box_charges(5, cc, s, 30 + o);
      const auto ref = fmmtest::direct(far.xyz, far.q, 1, pts.xyz);
      for (int t = 0; t < 5; ++t) {
        double out[10] = {};
        H.regular(p, (pts.xyz[3 * t] - cc[0]) / s, (pts.xyz[3 * t + 1] - cc[1]) / s, (pts.xyz[3 * t + 2] - cc[2]) / s,
                  scratch.data());
        fmmtest::l2p_reference(p, s, b.data(), scratch.data(), 1u, out);
        EXPECT_NEAR(out[0], ref[t * 10], std::pow(0.35, p) * 60) << "L2L p=" << p;
      }
    }
  }
}

// One source box (side 1/8, 60 charges incl. corners) and a target box at each of the 189
// V-list offsets; normalized error of the plane-wave M2L chain + L2P <= 0.5 eps for each table.
TEST(FmmBlocks, PlaneWaveM2LAllOffsetsAllTables) {
  for (double eps : {1e-3, 1e-6, 1e-9, 1e-12}) {
    const int p = rpyfmm::fmm::fmm_order_for(eps), nodes = rpyfmm::fmm::fmm_planewave_nodes_for(eps);
    const Harmonics& H = Harmonics::cached(p + 2);
    const PlaneWave& pw = PlaneWave::cached(p, nodes);
    const double s = 0.125, cs[3] = {0.2, -0.1, 0.05};
    const auto src = box_charges(60, cs, s, 77);
    std::vector<cplx> Mh(ncoef(p)), Mt(ncoef(p)), Mf(ncoef(p)), work(ncoef(p)), T(ncoef(p + 2));
    fmmtest::p2m_reference(H, p, s, cs, src.xyz.data(), src.q.data(), 0, 1, 60, Mh.data(), T.data());
    for (int i = 0; i < ncoef(p); ++i) Mt[i] = Mh[i] / s;
    const int K = pw.sum_fourier(), Mp = pw.sum_physical();
    std::vector<cplx> Fu(K), Fd(K), W(Mp), G(K), Z(K, 0.0), Lf(ncoef(p)), L(ncoef(p)), b(ncoef(p));
    double worst = 0;
    int npairs = 0;
    for (int dz = -3; dz <= 3; ++dz)
      for (int dy = -3; dy <= 3; ++dy)
        for (int dx = -3; dx <= 3; ++dx) {
          if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) < 2) continue;
          ++npairs;
          int f, sign;
          if (std::abs(dz) >= 2)
            f = 0, sign = dz > 0 ? 1 : -1;
          else if (std::abs(dy) >= 2)
            f = 1, sign = dy > 0 ? 1 : -1;
          else
            f = 2, sign = dx > 0 ? 1 : -1;
          pw.to_frame(f, Mt.data(), Mf.data(), work.data());
          pw.m2f(Mf.data(), Fu.data(), Fd.data());
          pw.f2p(sign > 0 ? Fu.data() : Fd.data(), W.data());
          const auto d = PlaneWave::frame_offset(f, {dx, dy, dz});
          const cplx* sh = sign > 0 ? pw.shift(d[0], d[1], d[2]) : pw.shift(-d[0], -d[1], -d[2]);
          for (int j = 0; j < Mp; ++j) W[j] *= sh[j];
          pw.p2f(W.data(), G.data());
          pw.f2l(sign > 0 ? G.data() : Z.data(), sign > 0 ? Z.data() : G.data(), Lf.data());
          pw.from_frame(f, Lf.data(), L.data());
          local_to_b(H, p, L.data(), b.data());
          const double ct[3] = {cs[0] + dx * s, cs[1] + dy * s, cs[2] + dz * s};
          const auto tg = box_charges(38, ct, s, 5);
          for (int t = 0; t < 38; ++t) {
            double out[10] = {}, exact = 0, scale = 0;
            H.regular(p, (tg.xyz[3 * t] - ct[0]) / s, (tg.xyz[3 * t + 1] - ct[1]) / s, (tg.xyz[3 * t + 2] - ct[2]) / s,
                      T.data());
            fmmtest::l2p_reference(p, s, b.data(), T.data(), 1u, out);
            for (int j = 0; j < 60; ++j) {
              const double r = std::hypot(tg.xyz[3 * t] - src.xyz[3 * j], tg.xyz[3 * t + 1] - src.xyz[3 * j + 1],
                                          tg.xyz[3 * t + 2] - src.xyz[3 * j + 2]);
              exact += src.q[j] / r;
              scale += std::abs(src.q[j]) / r;
            }
            worst = std::max(worst, std::abs(out[0] - exact) / scale);
          }
        }
    EXPECT_EQ(npairs, 316);  // all offsets in {-3..3}^3 with max |d_i| >= 2: a superset of every child's 189
    EXPECT_LE(worst, 0.5 * eps) << "eps " << eps;
    std::printf("plane-wave M2L eps=%.0e p=%d nlams=%d: max normalized error %.2e\n", eps, p, pw.nlams(), worst);
  }
}

// The lane versions of the rotations (batched M2L, several densities) equal apply / apply_adjoint
// applied to each lane, for a y-rotation (real kernels) and a general rotation (lane-by-lane path),
// with truncated orders as the M2L uses them. Tolerance: the same sums in another order.
TEST(FmmBlocks, LaneRotationsMatchOneDensityRotations) {
  const int p = 12, D = Rotation::kLanes, nc = ncoef(p);
  const Rotation A = Rotation::about_y(p, 0.7);
  const Rotation B(p, {0, 0, 1, 1, 0, 0, 0, 1, 0});
  std::mt19937_64 g(3);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<cplx> x(std::size_t(D) * nc);
  for (int d = 0; d < D; ++d)
    for (int n = 0; n <= p; ++n)
      for (int m = 0; m <= n; ++m) x[std::size_t(d) * nc + idx(n, m)] = cplx(u(g), m == 0 ? 0.0 : u(g));
  std::vector<double> xr(std::size_t(D) * nc), xi(xr.size()), yr(xr.size()), yi(xr.size());
  for (int d = 0; d < D; ++d)
    for (int i = 0; i < nc; ++i) {
      xr[std::size_t(i) * D + d] = x[std::size_t(d) * nc + i].real();
      xi[std::size_t(i) * D + d] = x[std::size_t(d) * nc + i].imag();
    }
  for (const Rotation* R : {&A, &B})
    for (int mmax : {p + 1, 5})
      for (bool adjoint : {false, true}) {
        if (adjoint)
          R->apply_adjoint_lanes(xr.data(), xi.data(), yr.data(), yi.data(), mmax);
        else
          R->apply_lanes(xr.data(), xi.data(), yr.data(), yi.data(), mmax);
        std::vector<cplx> in(nc), out(nc);
        for (int d = 0; d < D; ++d) {
          for (int i = 0; i < nc; ++i) in[i] = x[std::size_t(d) * nc + i];
          if (adjoint) {
            // apply_adjoint reads only orders m' < mmax_in: give both the same input.
            for (int n = 0; n <= p; ++n)
              for (int m = mmax; m <= n; ++m) in[idx(n, m)] = 0.0;
          }
          if (adjoint)
            R->apply_adjoint(in.data(), out.data(), mmax);
          else
            R->apply(in.data(), out.data(), mmax);
          for (int i = 0; i < nc; ++i)
            EXPECT_NEAR(std::abs(cplx(yr[std::size_t(i) * D + d], yi[std::size_t(i) * D + d]) - out[i]), 0.0, 1e-13)
                << (R == &A ? "about_y" : "general") << " mmax=" << mmax << " adjoint=" << adjoint << " i=" << i;
        }
      }
}

// Half-node storage. For real charges W(a + pi) = conj(W(a)) and so do the shift factors, so
// F2P at the stored nodes j < M_k/2, the stored shift factors and P2F from them must reproduce the
// full-circle formulas evaluated here at all M_k nodes (independent sums, no symmetry used).
// Tolerance 1e-12 relative to the largest value: both sides are the same sums in another order.
TEST(FmmBlocks, HalfNodePlaneWavesMatchFullCircle) {
  for (double eps : {1e-3, 1e-6, 1e-9, 1e-12}) {
    const int p = rpyfmm::fmm::fmm_order_for(eps), nodes = rpyfmm::fmm::fmm_planewave_nodes_for(eps);
    const Harmonics& H = Harmonics::cached(p + 2);
    const PlaneWave& pw = PlaneWave::cached(p, nodes);
    const double s = 1.0, cs[3] = {0.0, 0.0, 0.0};
    const auto src = box_charges(40, cs, s, 11);
    std::vector<cplx> Mh(ncoef(p)), Mf(ncoef(p)), work(ncoef(p)), T(ncoef(p + 2));
    fmmtest::p2m_reference(H, p, s, cs, src.xyz.data(), src.q.data(), 0, 1, 40, Mh.data(), T.data());
    pw.to_frame(1, Mh.data(), Mf.data(), work.data());  // a rotated frame: all orders m populated
    const int K = pw.sum_fourier(), Mp = pw.sum_physical();
    std::vector<cplx> Fu(K), Fd(K), W(Mp), V(Mp), G(K);
    pw.m2f(Mf.data(), Fu.data(), Fd.data());
    pw.f2p(Fu.data(), W.data());
    const int dx = 1, dy = -2, dz = 3;
    const cplx* sh = pw.shift(dx, dy, dz);
    for (int j = 0; j < Mp; ++j) V[j] = W[j] * sh[j];
    pw.p2f(V.data(), G.data());
    int stored = 0;
    for (int k = 0; k < pw.nlams(); ++k) {
      const int Kk = pw.fourier_modes(k), Mk = pw.angle_nodes(k);
      ASSERT_EQ(Mk % 2, 0);
      stored += Mk / 2;
      const cplx* F = &Fu[pw.fourier_offset(k)];
      std::vector<cplx> Vfull(Mk);
      double scale = 0;
      for (int j = 0; j < Mk; ++j) {
        const double a = 2.0 * std::numbers::pi * j / Mk, lam = pw.lambda(k);
        cplx w = F[0];  // W(a) = sum_{|m| < K} F(m) e^{i m a}, F(-m) = (-1)^m conj(F(m))
        for (int m = 1; m < Kk; ++m)
          w += F[m] * std::polar(1.0, m * a) + ((m & 1) ? -1.0 : 1.0) * std::conj(F[m]) * std::polar(1.0, -m * a);
        const cplx shift = std::exp(-lam * dz) * std::polar(1.0, lam * (dx * std::cos(a) + dy * std::sin(a)));
        Vfull[j] = w * shift;
        scale = std::max(scale, std::abs(w));
        if (j < Mk / 2) {
          EXPECT_LE(std::abs(W[pw.physical_offset(k) + j] - w), 1e-12 * scale) << "F2P k=" << k << " j=" << j;
          EXPECT_LE(std::abs(sh[pw.physical_offset(k) + j] - shift), 1e-12 * std::abs(shift)) << "shift k=" << k;
        } else {
          EXPECT_LE(std::abs(Vfull[j] - std::conj(Vfull[j - Mk / 2])), 1e-12 * scale) << "symmetry k=" << k;
        }
      }
      double vmax = 0;
      for (const auto& v : Vfull) vmax = std::max(vmax, std::abs(v));
      for (int m = 0; m < Kk; ++m) {
        cplx g = 0.0;  // G(m) = (1/M) sum_{j < M} V_j e^{-i m a_j}
        for (int j = 0; j < Mk; ++j) g += Vfull[j] * std::polar(1.0, -m * 2.0 * std::numbers::pi * j / Mk);
        g /= double(Mk);
        EXPECT_LE(std::abs(G[pw.fourier_offset(k) + m] - g), 1e-12 * vmax) << "P2F eps=" << eps << " k=" << k;
      }
    }
    EXPECT_EQ(stored, Mp);
  }
}

// Merge-and-shift groups. Every child receives each of its 189 V-pairs exactly once, along an
// axis on which the pair is separated by >= 2 boxes, with the sign of the offset.
TEST(FmmBlocks, MergeGroupsCoverEveryVPairOnce) {
  const auto& g = merge_groups();
  for (int oct = 0; oct < 8; ++oct) {
    const int c[3] = {oct & 1, (oct >> 1) & 1, (oct >> 2) & 1};
    int count = 0;
    for (int az = -2; az <= 3; ++az)
      for (int ay = -2; ay <= 3; ++ay)
        for (int ax = -2; ax <= 3; ++ax) {
          const int d[3] = {c[0] - ax, c[1] - ay, c[2] - az};
          const bool vpair = std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])}) >= 2;
          int hits = 0;
          for (int f = 0; f < 3; ++f) {
            const auto& e = g[merge_position(ax, ay, az)][f];
            if (!(e.mask & (1u << oct))) continue;
            ++hits;
            const int along = f == 0 ? d[2] : f == 1 ? d[1] : d[0];
            EXPECT_GE(std::abs(along), 2);
            EXPECT_EQ(e.sign, along > 0 ? 1 : -1);
          }
          EXPECT_EQ(hits, vpair ? 1 : 0) << ax << ay << az << " child " << oct;
          count += hits;
        }
    EXPECT_EQ(count, 189);
  }
}
