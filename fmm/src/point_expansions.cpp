// Scaled local expansions from points (P2L), the scaling of coefficients, and the evaluation of a
// multipole with gradient and Hessian (M2P) (docs/theory/fmm.md, expansions and derivatives; Guan,
// dissertation, Theorems 2.2.2-2.2.3 and §2.3). P2M and L2P run vectorized over points
// (simd_expansions.cpp).
#include <cmath>

#include "rpyfmm/fmm/detail/expansions.hpp"

namespace rpyfmm::fmm::detail {

void p2l(const Harmonics& H, int p, double s, const double* c, const double* xyz, const double* q, std::size_t ldq,
         std::size_t nd, std::size_t n, cplx* Lh, cplx* S) {
  const double inv_s = 1.0 / s;
  const double* ic = H.inv_c_table();
  const int nc = ncoef(p);
  for (std::size_t j = 0; j < n; ++j) {
    H.singular(p, (xyz[3 * j] - c[0]) * inv_s, (xyz[3 * j + 1] - c[1]) * inv_s, (xyz[3 * j + 2] - c[2]) * inv_s, S);
    for (int i = 0; i < nc; ++i) S[i] = (inv_s * ic[i]) * std::conj(S[i]);
    for (std::size_t d = 0; d < nd; ++d) {
      const double qj = q[d * ldq + j];
      cplx* out = Lh + d * nc;
      for (int i = 0; i < nc; ++i) out[i] += qj * S[i];
    }
  }
}

void local_to_b(const Harmonics& H, int p, const cplx* Lh, cplx* b) noexcept {
  const double* cn = H.c_table();
  for (int i = 0; i < ncoef(p); ++i) b[i] = Lh[i] * cn[i];
}

void multipole_to_a(const Harmonics& H, int p, const cplx* Mh, cplx* a) noexcept {
  const double* ic = H.inv_c_table();
  for (int i = 0; i < ncoef(p); ++i) a[i] = Mh[i] * ic[i];
}

// M2P with gradient and Hessian (Guan, §2.3 and Theorem 2.2.2): a = Mh / c, S = S_n^m((x-c)/s)
// up to degree p+2.
void m2p_eval(int p, double s, const cplx* a, const cplx* S, unsigned flags, double* out) noexcept {
  const double inv_s = 1.0 / s;
  if (flags & kPotential) {
    double phi = 0.0;
    for (int n = 0; n <= p; ++n) phi += re_prime(a + idx(n, 0), S + idx(n, 0), n);
    out[0] += phi * inv_s;
  }
  if (flags & kGradient) {
    double dz = 0.0;
    cplx G1 = 0.0, G2 = 0.0;
    for (int n = 0; n <= p; ++n) {
      const cplx* an = a + idx(n, 0);
      const cplx* Sn = S + idx(n + 1, 0);
      dz += re_prime(an, Sn, n);
      for (int m = 0; m <= n; ++m) G1 += an[m] * Sn[m + 1];
      for (int m = 1; m <= n; ++m) G2 += an[m] * Sn[m - 1];
    }
    const cplx G = G1 - std::conj(G2);
    const double s2 = inv_s * inv_s;
    out[1] += G.real() * s2;
    out[2] += G.imag() * s2;
    out[3] += -dz * s2;
  }
  if (flags & kHessian) {
    double dzz = 0.0;
    cplx J1 = 0.0, J2 = 0.0, K1 = 0.0, K3 = 0.0;
    for (int n = 0; n <= p; ++n) {
      const cplx* an = a + idx(n, 0);
      const cplx* Sn = S + idx(n + 2, 0);
      dzz += re_prime(an, Sn, n);
      for (int m = 0; m <= n; ++m) J1 += an[m] * Sn[m + 1];
      for (int m = 1; m <= n; ++m) J2 += an[m] * Sn[m - 1];
      for (int m = 0; m <= n; ++m) K1 += an[m] * Sn[m + 2];
      if (n >= 1) K1 -= std::conj(an[1]) * Sn[1];
      for (int m = 2; m <= n; ++m) K3 += an[m] * Sn[m - 2];
    }
    const cplx J = -(J1 - std::conj(J2));
    const cplx K = K1 + std::conj(K3);
    finish_hessian(dzz, J, K, inv_s * inv_s * inv_s, out);
  }
}

}  // namespace rpyfmm::fmm::detail
