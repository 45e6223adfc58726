// P2M and L2P (with gradient and Hessian) vectorized over points (docs/theory/fmm.md, "Expansions";
// Guan, dissertation, Theorems 2.2.2 and 2.3.1).
// The sums of the one-point forms (tests/fmm/expansion_reference.hpp), reorganized: SIMD lanes =
// points, regular solid harmonics in structure-of-arrays form, coefficients broadcast.
#include "rpyfmm/core/simd_dispatch.hpp"
#include "rpyfmm/fmm/detail/expansions.hpp"

namespace rpyfmm::fmm::detail {

namespace {
constexpr int W = kL2PLanes;

struct Acc {
  double re[W], im[W];
};

// acc += b * R_i (complex), lanes.
inline void cmac(Acc& a, double br, double bi, const double* Rr, const double* Ri) noexcept {
  for (int t = 0; t < W; ++t) {
    a.re[t] += br * Rr[t] - bi * Ri[t];
    a.im[t] += br * Ri[t] + bi * Rr[t];
  }
}
// acc += w Re(b R_i), lanes.
inline void rmac(double* a, double w, double br, double bi, const double* Rr, const double* Ri) noexcept {
  for (int t = 0; t < W; ++t) a[t] += w * (br * Rr[t] - bi * Ri[t]);
}
// Regular solid harmonics of W points, structure of arrays: Rr/Ri[idx(n,m) * W + lane].
inline void regular_soa(int p, const double* rec, const double* x, const double* y, const double* z, const double* rho2,
                        double* Rr, double* Ri) noexcept {
  for (int m = 0; m <= p; ++m) {
    if (m > 0) {
      double* pr = Rr + idx(m, m) * W;
      double* pi = Ri + idx(m, m) * W;
      const double* qr = Rr + idx(m - 1, m - 1) * W;
      const double* qi = Ri + idx(m - 1, m - 1) * W;
      const double f = -1.0 / (2.0 * m);
      for (int t = 0; t < W; ++t) {
        pr[t] = f * (x[t] * qr[t] - y[t] * qi[t]);
        pi[t] = f * (x[t] * qi[t] + y[t] * qr[t]);
      }
    }
    if (m + 1 <= p) {
      double* pr = Rr + idx(m + 1, m) * W;
      double* pi = Ri + idx(m + 1, m) * W;
      const double* qr = Rr + idx(m, m) * W;
      const double* qi = Ri + idx(m, m) * W;
      for (int t = 0; t < W; ++t) {
        pr[t] = z[t] * qr[t];
        pi[t] = z[t] * qi[t];
      }
    }
    for (int n = m + 1; n < p; ++n) {
      double* pr = Rr + idx(n + 1, m) * W;
      double* pi = Ri + idx(n + 1, m) * W;
      const double* ar = Rr + idx(n, m) * W;
      const double* ai = Ri + idx(n, m) * W;
      const double* cr = Rr + idx(n - 1, m) * W;
      const double* ci = Ri + idx(n - 1, m) * W;
      const double f = rec[idx(n + 1, m)], g = double(2 * n + 1);
      for (int t = 0; t < W; ++t) {
        pr[t] = (g * z[t] * ar[t] - rho2[t] * cr[t]) * f;
        pi[t] = (g * z[t] * ai[t] - rho2[t] * ci[t]) * f;
      }
    }
  }
}
// The regular solid harmonics of the lanes' scaled offsets u (nt valid lanes; the others at 0).
[[gnu::always_inline]] inline void regular_lanes(int p, const double* rec, int nt, const double* ux, const double* uy,
                                                 const double* uz, double* Rr, double* Ri) noexcept {
  double x[W], y[W], z[W], rho2[W];
  for (int t = 0; t < W; ++t) {
    x[t] = t < nt ? ux[t] : 0.0;
    y[t] = t < nt ? uy[t] : 0.0;
    z[t] = t < nt ? uz[t] : 0.0;
    rho2[t] = x[t] * x[t] + y[t] * y[t] + z[t] * z[t];
    Rr[t] = 1.0;
    Ri[t] = 0.0;
  }
  regular_soa(p, rec, x, y, z, rho2, Rr, Ri);
}

// L2P potential of the lanes: phi = sum_{n,m} Re'(b_n^m R_n^m), added to o[t * 10].
[[gnu::always_inline]] inline void l2p_potential(int p, const cplx* bd, const double* Rr, const double* Ri, int nt,
                                                 double* o) noexcept {
  double phi[W] = {};
  for (int n = 0; n <= p; ++n)
    for (int m = 0; m <= n; ++m) {
      const int i = idx(n, m);
      rmac(phi, m ? 2.0 : 1.0, bd[i].real(), bd[i].imag(), Rr + i * W, Ri + i * W);
    }
  for (int t = 0; t < nt; ++t) o[t * 10] += phi[t];
}

// L2P gradient of the lanes from the coefficients one degree up (Guan, Theorem 2.3.1), added to
// o[t * 10 + 1 .. 3].
[[gnu::always_inline]] inline void l2p_gradient(int p, double inv_s, const cplx* bd, const double* Rr, const double* Ri,
                                                int nt, double* o) noexcept {
  double dz[W] = {};
  Acc g1{}, g2{};
  for (int n = 0; n + 1 <= p; ++n)
    for (int m = 0; m <= n; ++m) {
      const int i = idx(n, m);
      const double* rr = Rr + i * W;
      const double* ri = Ri + i * W;
      const cplx c0 = bd[idx(n + 1, m)], cp = bd[idx(n + 1, m + 1)];
      rmac(dz, m ? 2.0 : 1.0, c0.real(), c0.imag(), rr, ri);
      if (m >= 1) {
        const cplx cm = bd[idx(n + 1, m - 1)];
        cmac(g1, cm.real(), cm.imag(), rr, ri);
      }
      cmac(g2, cp.real(), cp.imag(), rr, ri);
    }
  for (int t = 0; t < nt; ++t) {
    o[t * 10 + 1] += (g1.re[t] - g2.re[t]) * inv_s;  // G = G1 - conj(G2)
    o[t * 10 + 2] += (g1.im[t] + g2.im[t]) * inv_s;
    o[t * 10 + 3] += dz[t] * inv_s;
  }
}

// L2P Hessian of the lanes from the coefficients two degrees up (Guan, Theorem 2.3.1), added to
// o[t * 10 + 4 .. 9] (xx, yy, zz, xy, xz, yz).
[[gnu::always_inline]] inline void l2p_hessian(int p, double inv_s2, const cplx* bd, const double* Rr, const double* Ri,
                                               int nt, double* o) noexcept {
  double dzz[W] = {};
  Acc j1{}, j2{}, k1{}, k3{};
  for (int n = 0; n + 2 <= p; ++n)
    for (int m = 0; m <= n; ++m) {
      const int i = idx(n, m);
      const double* rr = Rr + i * W;
      const double* ri = Ri + i * W;
      const cplx c0 = bd[idx(n + 2, m)], cp = bd[idx(n + 2, m + 1)], cpp = bd[idx(n + 2, m + 2)];
      rmac(dzz, m ? 2.0 : 1.0, c0.real(), c0.imag(), rr, ri);
      if (m >= 1) {
        const cplx cm = bd[idx(n + 2, m - 1)];
        cmac(j1, cm.real(), cm.imag(), rr, ri);
      }
      cmac(j2, cp.real(), cp.imag(), rr, ri);
      if (m >= 2) {
        const cplx cmm = bd[idx(n + 2, m - 2)];
        cmac(k1, cmm.real(), cmm.imag(), rr, ri);
      }
      if (m == 1) {
        const cplx c1 = bd[idx(n + 2, 1)];
        cmac(k1, -c1.real(), c1.imag(), rr, ri);  // - conj(b_{n+2}^1) R_n^1
      }
      cmac(k3, cpp.real(), cpp.imag(), rr, ri);
    }
  for (int t = 0; t < nt; ++t) {
    const double zz = dzz[t] * inv_s2;
    const double Jr = (j1.re[t] - j2.re[t]) * inv_s2, Ji = (j1.im[t] + j2.im[t]) * inv_s2;  // J = J1 - conj(J2)
    const double Kr = (k1.re[t] + k3.re[t]) * inv_s2, Ki = (k1.im[t] - k3.im[t]) * inv_s2;  // K = K1 + conj(K3)
    double* r = o + t * 10;
    r[4] += 0.5 * (Kr - zz);
    r[5] += -0.5 * (Kr + zz);
    r[6] += zz;
    r[7] += 0.5 * Ki;
    r[8] += Jr;
    r[9] += Ji;
  }
}
}  // namespace

void p2m_block(int p, const double* rec, const double* cn, int np, const double* ux, const double* uy, const double* uz,
               const double* q, std::size_t ldq, std::size_t nd, cplx* Mh, double* scratch) noexcept {
  return simd_dispatch([=]() RPYFMM_SIMD_BODY {
    const int nc = ncoef(p);
    double* Rr = scratch;
    double* Ri = scratch + std::size_t(nc) * W;
    regular_lanes(p, rec, np, ux, uy, uz, Rr, Ri);
    for (std::size_t d = 0; d < nd; ++d) {
      double qd[W];
      for (int t = 0; t < W; ++t) qd[t] = t < np ? q[d * ldq + t] : 0.0;  // padded lanes carry no charge
      cplx* M = Mh + d * nc;
      for (int i = 0; i < nc; ++i) {
        double re = 0.0, im = 0.0;
        for (int t = 0; t < W; ++t) {
          re += qd[t] * Rr[i * W + t];
          im += qd[t] * Ri[i * W + t];
        }
        M[i] += cplx(cn[i] * re, -cn[i] * im);  // q c conj(R)
      }
    }
  });
}

void l2p_block(int p, double s, const double* rec, const cplx* b, std::size_t nd, const unsigned* flags, int nt,
               const double* ux, const double* uy, const double* uz, double* out, std::size_t ld,
               double* scratch) noexcept {
  return simd_dispatch([=]() RPYFMM_SIMD_BODY {
    const int nc = ncoef(p);
    double* Rr = scratch;
    double* Ri = scratch + std::size_t(nc) * W;
    regular_lanes(p, rec, nt, ux, uy, uz, Rr, Ri);
    const double inv_s = 1.0 / s, inv_s2 = inv_s * inv_s;
    for (std::size_t d = 0; d < nd; ++d) {
      const cplx* bd = b + d * nc;
      double* o = out + d * ld;
      if (flags[d] & kPotential) l2p_potential(p, bd, Rr, Ri, nt, o);
      if (flags[d] & kGradient) l2p_gradient(p, inv_s, bd, Rr, Ri, nt, o);
      if (flags[d] & kHessian) l2p_hessian(p, inv_s2, bd, Rr, Ri, nt, o);
    }
  });
}

}  // namespace rpyfmm::fmm::detail
