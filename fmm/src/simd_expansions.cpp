// P2M and L2P (with gradient and Hessian) vectorized over points (docs/theory/fmm.md, "Expansions";
// Guan, dissertation, Theorems 2.2.2 and 2.3.1).
// The sums of the one-point forms (tests/fmm/expansion_reference.hpp), reorganized: SIMD lanes =
// points, regular solid harmonics in structure-of-arrays form, coefficients broadcast.
#include <algorithm>

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
// The K sums of a combined group from its coefficients (curl_grad_div_coefficients: K = 6,
// grad_div_coefficients: K = 3), sum k added to o[row[k] * ld + t * 10 + column[k]], the columns
// l2p_block names (expansions.hpp); o: the group's first row, ld apart.
template <int K>
[[gnu::always_inline]] inline void l2p_combined(int p, const double* ab, const double* Rr, const double* Ri, int nt,
                                                double* o, std::size_t ld, const std::size_t (&row)[K],
                                                const std::size_t (&column)[K]) noexcept {
  const int nc = ncoef(p), used = ncoef(p - 1);  // the sums stop at degree p - 1
  double acc[K][W] = {};
  for (int i = 0; i < used; ++i)
    for (int k = 0; k < K; ++k) {
      const double al = ab[2 * k * nc + i], be = ab[(2 * k + 1) * nc + i];
      for (int t = 0; t < W; ++t) acc[k][t] += al * Rr[i * W + t] + be * Ri[i * W + t];
    }
  for (int k = 0; k < K; ++k)
    for (int t = 0; t < nt; ++t) o[row[k] * ld + t * 10 + column[k]] += acc[k][t];
}

// b_n^m of one density (zero outside 0 <= m <= n), as the lane formulas read it.
inline cplx coef(const cplx* b, int n, int m) noexcept {
  return m < 0 || m > n ? cplx{} : b[idx(n, m)];
}

// alpha_i, beta_i with sum_i alpha_i Re R_i + beta_i Im R_i = w . grad phi, added: the lane
// formula of l2p_gradient (gx = Re G1 - Re G2, gy = Im G1 + Im G2, gz = Re' c0 R) read per R_n^m.
void add_gradient_functional(int p, double inv_s, const cplx* bd, const double (&w)[3], double* al, double* be) {
  for (int n = 0; n + 1 <= p; ++n)
    for (int m = 0; m <= n; ++m) {
      const int i = idx(n, m);
      const double wm = m ? 2.0 : 1.0;
      const cplx c0 = coef(bd, n + 1, m), cp = coef(bd, n + 1, m + 1), cm = coef(bd, n + 1, m - 1);
      al[i] += inv_s * (w[0] * (cm.real() - cp.real()) + w[1] * (cm.imag() + cp.imag()) + w[2] * wm * c0.real());
      be[i] += inv_s * (w[0] * (cp.imag() - cm.imag()) + w[1] * (cm.real() + cp.real()) - w[2] * wm * c0.imag());
    }
}

// The same for w . (Hxx, Hyy, Hzz, Hxy, Hxz, Hyz) from the lane formula of l2p_hessian:
// Hxx = (Re K - zz)/2, Hyy = -(Re K + zz)/2, Hzz = zz, Hxy = Im K / 2, Hxz = Re J, Hyz = Im J.
void add_hessian_functional(int p, double inv_s2, const cplx* bd, const double (&w)[6], double* al, double* be) {
  const double czz = w[2] - 0.5 * (w[0] + w[1]), cKr = 0.5 * (w[0] - w[1]), cKi = 0.5 * w[3];
  const double cJr = w[4], cJi = w[5];
  for (int n = 0; n + 2 <= p; ++n)
    for (int m = 0; m <= n; ++m) {
      const int i = idx(n, m);
      const double wm = m ? 2.0 : 1.0;
      const cplx c0 = coef(bd, n + 2, m), cp = coef(bd, n + 2, m + 1), cpp = coef(bd, n + 2, m + 2);
      const cplx cm = coef(bd, n + 2, m - 1);
      // K1's term: b_{n+2}^{m-2} R_n^m, and for m = 1 - conj(b_{n+2}^1) R_n^1.
      const cplx k1 = m >= 2   ? coef(bd, n + 2, m - 2)
                      : m == 1 ? cplx(-bd[idx(n + 2, 1)].real(), bd[idx(n + 2, 1)].imag())
                               : cplx{};
      al[i] += inv_s2 * (czz * wm * c0.real() + cJr * (cm.real() - cp.real()) + cJi * (cm.imag() + cp.imag()) +
                         cKr * (k1.real() + cpp.real()) + cKi * (k1.imag() - cpp.imag()));
      be[i] += inv_s2 * (-czz * wm * c0.imag() + cJr * (cp.imag() - cm.imag()) + cJi * (cm.real() + cp.real()) -
                         cKr * (k1.imag() + cpp.imag()) + cKi * (k1.real() - cpp.real()));
    }
}
}  // namespace

// (grad div)_c = sum_m H(phi_m)_cm (laplace_fmm.hpp), a linear form in the b coefficients.
void grad_div_coefficients(int p, double s, const cplx* b, double* ab) noexcept {
  const int nc = ncoef(p);
  std::fill_n(ab, kGradDivPerGroup * std::size_t(nc), 0.0);
  const double inv_s = 1.0 / s, inv_s2 = inv_s * inv_s;
  // Hessian columns xx, yy, zz, xy, xz, yz: row c of H(phi_m) in column m.
  constexpr double rows[3][3][6] = {{{1, 0, 0, 0, 0, 0}, {0, 0, 0, 1, 0, 0}, {0, 0, 0, 0, 1, 0}},
                                    {{0, 0, 0, 1, 0, 0}, {0, 1, 0, 0, 0, 0}, {0, 0, 0, 0, 0, 1}},
                                    {{0, 0, 0, 0, 1, 0}, {0, 0, 0, 0, 0, 1}, {0, 0, 1, 0, 0, 0}}};
  for (int c = 0; c < 3; ++c)
    for (int m = 0; m < 3; ++m)
      add_hessian_functional(p, inv_s2, b + m * nc, rows[c][m], ab + 2 * c * nc, ab + (2 * c + 1) * nc);
}

// curl_x = d_y phi_3 - d_z phi_2, curl_y = d_z phi_1 - d_x phi_3, curl_z = d_x phi_2 - d_y phi_1,
// each a linear form in the b coefficients, then the grad div sums (grad_div_coefficients).
void curl_grad_div_coefficients(int p, double s, const cplx* b, double* ab) noexcept {
  const int nc = ncoef(p);
  std::fill_n(ab, (kCombinedPerGroup - kGradDivPerGroup) * std::size_t(nc), 0.0);
  const double inv_s = 1.0 / s;
  const cplx* phi[3] = {b, b + nc, b + 2 * nc};
  const auto grad = [&](int k, int m, const double(&w)[3]) {
    add_gradient_functional(p, inv_s, phi[m], w, ab + 2 * k * nc, ab + (2 * k + 1) * nc);
  };
  grad(0, 2, {0, 1, 0}), grad(0, 1, {0, 0, -1});
  grad(1, 0, {0, 0, 1}), grad(1, 2, {-1, 0, 0});
  grad(2, 1, {1, 0, 0}), grad(2, 0, {0, -1, 0});
  grad_div_coefficients(p, s, b, ab + (kCombinedPerGroup - kGradDivPerGroup) * nc);
}

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
               const double* ux, const double* uy, const double* uz, double* out, std::size_t ld, double* scratch,
               const double* combined) noexcept {
  return simd_dispatch([=]() RPYFMM_SIMD_BODY {
    const int nc = ncoef(p);
    double* Rr = scratch;
    double* Ri = scratch + std::size_t(nc) * W;
    regular_lanes(p, rec, nt, ux, uy, uz, Rr, Ri);
    const double inv_s = 1.0 / s, inv_s2 = inv_s * inv_s;
    const double* group = combined;
    std::size_t grad_div_member = 0;  // grad_div densities seen: groups of three
    for (std::size_t d = 0; d < nd; ++d) {
      const cplx* bd = b + d * nc;
      double* o = out + d * ld;
      if (flags[d] == kCurlGradDiv) {
        constexpr std::size_t row[6] = {2, 0, 1, 0, 1, 2}, column[6] = {2, 3, 1, 4, 5, 6};
        l2p_combined<6>(p, group, Rr, Ri, nt, o, ld, row, column);
        group += kCombinedPerGroup * std::size_t(nc);
        d += 2;
        continue;
      }
      // A grad_div density's potential and gradient take the same code as any other density's.
      if (flags[d] & kPotential) l2p_potential(p, bd, Rr, Ri, nt, o);
      if (flags[d] & kGradient) l2p_gradient(p, inv_s, bd, Rr, Ri, nt, o);
      if (flags[d] & kHessian) l2p_hessian(p, inv_s2, bd, Rr, Ri, nt, o);
      if ((flags[d] & kGradDiv) && grad_div_member++ % 3 == 0) {  // the first density of its group
        constexpr std::size_t row[3] = {0, 1, 2}, column[3] = {4, 5, 6};
        l2p_combined<3>(p, group, Rr, Ri, nt, o, ld, row, column);
        group += kGradDivPerGroup * std::size_t(nc);
      }
    }
  });
}

}  // namespace rpyfmm::fmm::detail
