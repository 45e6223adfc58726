// Formation and evaluation of scaled multipole and local expansions (PLANEWAVE.md §1.3-§1.4,
// §6.1 L2P with gradient/Hessian, §6.2 M2P with gradient/Hessian, §6.3 P2M/P2L).
#include <cmath>

#include "rpyfmm/fmm/detail/expansions.hpp"

namespace rpyfmm::fmm::detail {

void p2m(const Harmonics& H, int p, double s, const double* c, const double* xyz, const double* q,
         std::size_t ldq, std::size_t nd, std::size_t n, cplx* Mh, cplx* R) {
  const double inv_s = 1.0 / s;
  const double* cn = H.c_table();
  const int nc = ncoef(p);
  for (std::size_t j = 0; j < n; ++j) {
    H.regular(p, (xyz[3 * j] - c[0]) * inv_s, (xyz[3 * j + 1] - c[1]) * inv_s, (xyz[3 * j + 2] - c[2]) * inv_s, R);
    for (int i = 0; i < nc; ++i) R[i] = cn[i] * std::conj(R[i]);
    for (std::size_t d = 0; d < nd; ++d) {
      const double qj = q[d * ldq + j];
      cplx* out = Mh + d * nc;
      for (int i = 0; i < nc; ++i) out[i] += qj * R[i];
    }
  }
}

void p2l(const Harmonics& H, int p, double s, const double* c, const double* xyz, const double* q,
         std::size_t ldq, std::size_t nd, std::size_t n, cplx* Lh, cplx* S) {
  const double inv_s = 1.0 / s;
  const double* ic = H.inv_c_table();
  const int nc = ncoef(p);
  for (std::size_t j = 0; j < n; ++j) {
    H.singular(p, (xyz[3 * j] - c[0]) * inv_s, (xyz[3 * j + 1] - c[1]) * inv_s, (xyz[3 * j + 2] - c[2]) * inv_s,
               S);
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

namespace {
// Re'(A_n, B_n) with A shifted in degree: sum_m omega_m Re(A_{na}^m B_{nb}^m), m <= mmax.
inline double re_prime(const cplx* A, const cplx* B, int mmax) noexcept {
  double acc = A[0].real() * B[0].real() - A[0].imag() * B[0].imag();
  double acc2 = 0.0;
  for (int m = 1; m <= mmax; ++m) acc2 += A[m].real() * B[m].real() - A[m].imag() * B[m].imag();
  return acc + 2.0 * acc2;
}
inline void finish_hessian(double dzz, cplx J, cplx K, double scale, double* out) noexcept {
  dzz *= scale;
  J *= scale;
  K *= scale;
  out[4] += 0.5 * (K.real() - dzz);
  out[5] += -0.5 * (K.real() + dzz);
  out[6] += dzz;
  out[7] += 0.5 * K.imag();
  out[8] += J.real();
  out[9] += J.imag();
}
}  // namespace

// §6.1: b = Lh c, R = R_n^m((x-c)/s).
void l2p_eval(int p, double s, const cplx* b, const cplx* R, unsigned flags, double* out) noexcept {
  if (flags & kPotential) {
    double phi = 0.0;
    for (int n = 0; n <= p; ++n) phi += re_prime(b + idx(n, 0), R + idx(n, 0), n);
    out[0] += phi;
  }
  if (flags & kGradient) {
    double dz = 0.0;
    cplx G1 = 0.0, G2 = 0.0;
    for (int n = 0; n + 1 <= p; ++n) {
      const cplx* bn = b + idx(n + 1, 0);
      const cplx* Rn = R + idx(n, 0);
      dz += re_prime(bn, Rn, n);
      for (int m = 1; m <= n; ++m) G1 += bn[m - 1] * Rn[m];
      for (int m = 0; m <= n; ++m) G2 += bn[m + 1] * Rn[m];
    }
    const cplx G = G1 - std::conj(G2);
    const double inv_s = 1.0 / s;
    out[1] += G.real() * inv_s;
    out[2] += G.imag() * inv_s;
    out[3] += dz * inv_s;
  }
  if (flags & kHessian) {
    double dzz = 0.0;
    cplx J1 = 0.0, J2 = 0.0, K1 = 0.0, K2 = 0.0, K3 = 0.0;
    for (int n = 0; n + 2 <= p; ++n) {
      const cplx* bn = b + idx(n + 2, 0);
      const cplx* Rn = R + idx(n, 0);
      dzz += re_prime(bn, Rn, n);
      for (int m = 1; m <= n; ++m) J1 += bn[m - 1] * Rn[m];
      for (int m = 0; m <= n; ++m) J2 += bn[m + 1] * Rn[m];
      for (int m = 2; m <= n; ++m) K1 += bn[m - 2] * Rn[m];
      if (n >= 1) K1 -= std::conj(bn[1]) * Rn[1];
      for (int m = 0; m <= n; ++m) K3 += bn[m + 2] * Rn[m];
    }
    (void)K2;
    const cplx J = J1 - std::conj(J2);
    const cplx K = K1 + std::conj(K3);
    finish_hessian(dzz, J, K, 1.0 / (s * s), out);
  }
}

// §6.2: a = Mh / c, S = S_n^m((x-c)/s) up to degree p+2.
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
