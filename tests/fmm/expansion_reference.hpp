// Test-only reference forms of P2M and L2P: one point at a time, straight from the definitions of
// the scaled expansions (rpyfmm/fmm/detail/expansions.hpp; docs/theory/fmm.md), against which the
// vectorized p2m_block / l2p_block of the library and the translations are checked.
#pragma once

#include <complex>
#include <cstddef>

#include "rpyfmm/fmm/detail/expansions.hpp"

namespace fmmtest {

using rpyfmm::fmm::detail::cplx;
using rpyfmm::fmm::detail::Harmonics;

/// Accumulates charges q[d*ldq + j] (j < n, d < nd) at points xyz[3j..3j+2] into the scaled
/// multipoles Mh[d*ncoef(p) ...] of a box with center `c` and side `s`:
/// Mh_n^m += q_j c_n^m conj(R_n^m((y_j - c)/s)). `R` is scratch (ncoef(p)).
inline void p2m_reference(const Harmonics& H, int p, double s, const double* c, const double* xyz, const double* q,
                          std::size_t ldq, std::size_t nd, std::size_t n, cplx* Mh, cplx* R) {
  const double inv_s = 1.0 / s;
  const double* cn = H.c_table();
  const int nc = rpyfmm::fmm::detail::ncoef(p);
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

/// Evaluates a scaled local expansion at one point: out[0] potential, out[1..3] gradient,
/// out[4..9] Hessian (xx, yy, zz, xy, xz, yz), added to out according to `flags`.
/// `b` = Lh_n^m c_n^m (local_to_b), `R` = regular harmonics at (x - c)/s up to degree p.
inline void l2p_reference(int p, double s, const cplx* b, const cplx* R, unsigned flags, double* out) {
  using rpyfmm::fmm::detail::finish_hessian;
  using rpyfmm::fmm::detail::idx;
  using rpyfmm::fmm::detail::re_prime;
  if (flags & rpyfmm::fmm::detail::kPotential) {
    double phi = 0.0;
    for (int n = 0; n <= p; ++n) phi += re_prime(b + idx(n, 0), R + idx(n, 0), n);
    out[0] += phi;
  }
  if (flags & rpyfmm::fmm::detail::kGradient) {
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
  if (flags & rpyfmm::fmm::detail::kHessian) {
    double dzz = 0.0;
    cplx J1 = 0.0, J2 = 0.0, K1 = 0.0, K3 = 0.0;
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
    const cplx J = J1 - std::conj(J2);
    const cplx K = K1 + std::conj(K3);
    finish_hessian(dzz, J, K, 1.0 / (s * s), out);
  }
}

}  // namespace fmmtest
