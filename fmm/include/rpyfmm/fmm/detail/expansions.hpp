// rpyfmm::fmm — multipole/local expansions: formation, evaluation with gradient and Hessian,
// rotations and translations (docs/theory/fmm.md, "Expansions" and "Translations between levels";
// Guan, dissertation, Theorems 2.2.2-2.2.5 and 2.3.1-2.3.2).
//
// All coefficients are *scaled*: for a box of side s and center c,
//   Mh_n^m = sum_j q_j c_n^m conj(R_n^m((y_j - c)/s))                 (P2M)
//   Lh_n^m = (1/s) sum_j q_j conj(S_n^m((y_j - c)/s)) / c_n^m          (P2L)
// Storage: 0 <= m <= n <= p, triangular (harmonics.hpp), `nd` densities one after the other.
#pragma once

#include <array>
#include <cstddef>
#include <vector>

#include "rpyfmm/fmm/detail/harmonics.hpp"
#include "rpyfmm/fmm/direct.hpp"

namespace rpyfmm::fmm::detail {

/// Output selection flags (per density), the values of rpyfmm::fmm::Output.
inline constexpr unsigned kPotential = potential, kGradient = gradient, kHessian = hessian;
/// The values of rpyfmm::fmm::curl_grad_div and rpyfmm::fmm::grad_div (laplace_fmm.hpp).
inline constexpr unsigned kCurlGradDiv = 8u, kGradDiv = 16u;

/// Accumulates charges q[d*ldq + j] (j < n, d < nd) at points xyz[3j..3j+2] into the scaled local
/// expansions Lh[d*ncoef(p) ...] of a box with center `c` and side `s` (P2L, X list); points must be
/// well separated from the box. `S` is scratch (ncoef(p)).
void p2l(const Harmonics& H, int p, double s, const double* c, const double* xyz, const double* q, std::size_t ldq,
         std::size_t nd, std::size_t n, cplx* Lh, cplx* S);

/// Re'(A_n, B_n) = sum_{m=0}^{mmax} omega_m Re(A_n^m B_n^m), omega_0 = 1, omega_m = 2: the sum over
/// -n <= m <= n of a product of expansions stored for m >= 0 (the negative orders are conjugates).
inline double re_prime(const cplx* A, const cplx* B, int mmax) noexcept {
  double acc = A[0].real() * B[0].real() - A[0].imag() * B[0].imag();
  double acc2 = 0.0;
  for (int m = 1; m <= mmax; ++m) acc2 += A[m].real() * B[m].real() - A[m].imag() * B[m].imag();
  return acc + 2.0 * acc2;
}
/// Adds the Hessian (xx, yy, zz, xy, xz, yz at out[4..9]) from d_zz, J = d_xz + i d_yz and
/// K = (d_xx - d_yy) + 2i d_xy, all times `scale`.
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

/// Lanes of l2p_block (targets evaluated together, SIMD lane = target).
inline constexpr int kL2PLanes = 8;
/// L2P for up to kL2PLanes targets at once: the regular table of every target is
/// built in structure-of-arrays form and each coefficient is broadcast over the lanes; the tables are
/// shared by the nd densities. u{x,y,z}: scaled target offsets (x - c)/s (nt <= kL2PLanes valid lanes);
/// b: nd x ncoef(p) (b = Lh c); result of density d, lane t added to out[d*ld + t*10 + column].
/// scratch: 2 * ncoef(p) * kL2PLanes doubles. A group of three densities flagged curl_grad_div
/// (laplace_fmm.hpp) is evaluated from its combined coefficients, kCombinedPerGroup * ncoef(p)
/// doubles per group in `combined` (curl_grad_div_coefficients), into the columns that
/// the fold (fold_combined_groups) counts once each: curl_x in (2, gy), curl_y in (0, gz), curl_z in (1, gx),
/// (grad div)_x in (0, hxx), _y in (1, hyy), _z in (2, hzz) (density of the group, column). A
/// group flagged grad_div has its three densities' potential and gradient evaluated as asked and
/// its grad div from kGradDivPerGroup * ncoef(p) doubles in `combined` (grad_div_coefficients), into
/// the same three columns; `combined` holds the groups' coefficients one after the other.
void l2p_block(int p, double s, const double* rec, const cplx* b, std::size_t nd, const unsigned* flags, int nt,
               const double* ux, const double* uy, const double* uz, double* out, std::size_t ld, double* scratch,
               const double* combined = nullptr) noexcept;
/// Doubles of combined coefficients per curl_grad_div group per ncoef(p): six sums, (alpha, beta) each.
inline constexpr std::size_t kCombinedPerGroup = 12;
/// The combined coefficients of a curl_grad_div group of scaled local coefficients b (3 x ncoef(p),
/// b = Lh c) in a box of side s: sum_i alpha_k,i Re R_i + beta_k,i Im R_i at the scaled offset is
/// the k-th of curl_x,y,z and (grad div)_x,y,z (docs/theory/fmm.md, section 2, "Combined outputs").
/// ab: kCombinedPerGroup * ncoef(p) doubles, overwritten (alpha_k at ab[2k nc], beta_k at ab[(2k+1) nc]).
void curl_grad_div_coefficients(int p, double s, const cplx* b, double* ab) noexcept;
/// Doubles of combined coefficients per grad_div group per ncoef(p): three sums, (alpha, beta) each.
inline constexpr std::size_t kGradDivPerGroup = 6;
/// The combined coefficients of a grad_div group, as curl_grad_div_coefficients: the k-th sum is
/// (grad div)_k, k = x, y, z. ab: kGradDivPerGroup * ncoef(p) doubles, overwritten.
void grad_div_coefficients(int p, double s, const cplx* b, double* ab) noexcept;
/// Doubles of combined coefficients per ncoef(p) of the group whose first density carries `flags`.
[[nodiscard]] constexpr std::size_t combined_per_group(unsigned flags) noexcept {
  return flags == kCurlGradDiv ? kCombinedPerGroup : kGradDivPerGroup;
}
/// P2M for up to kL2PLanes sources at once (same layout as l2p_block): u = (y - c)/s scaled offsets,
/// charges q[d*ldq + t]; adds to Mh[d*ncoef(p) + i]. cn = c_n^m table. scratch as l2p_block.
void p2m_block(int p, const double* rec, const double* cn, int np, const double* ux, const double* uy, const double* uz,
               const double* q, std::size_t ldq, std::size_t nd, cplx* Mh, double* scratch) noexcept;
/// b_n^m = Lh_n^m c_n^m.
void local_to_b(const Harmonics& H, int p, const cplx* Lh, cplx* b) noexcept;

/// Evaluates a scaled multipole at one point, adding to out as l2p_block (out[0] potential, out[1..3]
/// gradient, out[4..9] Hessian xx, yy, zz, xy, xz, yz, according to `flags`). `a` = Mh_n^m / c_n^m,
/// `S` = singular table at (x-c)/s up to degree p+2 (p+1 if no Hessian, p if only potential).
void m2p_eval(int p, double s, const cplx* a, const cplx* S, unsigned flags, double* out) noexcept;
/// a_n^m = Mh_n^m / c_n^m.
void multipole_to_a(const Harmonics& H, int p, const cplx* Mh, cplx* a) noexcept;

/// Rotation matrices A^n(Q), n = 0..p: sum_m M_m Y_n^m(v) = sum_m' (A^n M)_m' Y_n^m'(Q v).
/// Built by an exact product quadrature on the sphere (n+1 Gauss-Legendre nodes x 2n+2 angles).
class Rotation {
 public:
  Rotation() = default;
  Rotation(int p, const std::array<double, 9>& Q);  // Q row-major, proper orthogonal
  /// Rotation about y by angle t (Q = Ry(t)): A^n is real, and apply/apply_adjoint use the
  /// real kernels (Re and Im parts separate, 2 real multiply-adds per entry instead of 8).
  static Rotation about_y(int p, double t);
  [[nodiscard]] int order() const noexcept { return p_; }
  /// out = A in (multipole into the frame); only orders m' < mmax_out are produced (others = 0).
  void apply(const cplx* in, cplx* out, int mmax_out) const noexcept;
  /// out = A^H in (local out of the frame); `in` has nonzero orders only for m' < mmax_in.
  void apply_adjoint(const cplx* in, cplx* out, int mmax_in) const noexcept;
  /// The same for kLanes densities at once, split into real and imaginary parts with the density
  /// index fastest: x[idx(n,m) * kLanes + d] (the batched M2L, planewave_batch.cpp).
  static constexpr int kLanes = 4;
  void apply_lanes(const double* xr, const double* xi, double* yr, double* yi, int mmax_out) const noexcept;
  void apply_adjoint_lanes(const double* xr, const double* xi, double* yr, double* yi, int mmax_in) const noexcept;
  /// Entry A^n_{m' m}, -n <= m', m <= n.
  [[nodiscard]] cplx entry(int n, int mp, int m) const noexcept {
    return a_[off_[n] + (mp + n) * (2 * n + 1) + (m + n)];
  }

 private:
  int p_ = -1;
  bool real_ = false;
  std::vector<std::size_t> off_;
  std::vector<cplx> a_;
  // Real kernels (about_y): per degree n, (n+1)^2 entries at roff_[n]:
  // plus_[m'][m] = A_{m'm} + A_{m',-m} (m >= 1; A_{m'0} at m = 0), minus_[m'][m] = A_{m'm} - A_{m',-m};
  // tplus_/tminus_ the same for A^T (adjoint): tplus_[m][m'] = A_{m'm} + A_{-m',m}, ...
  std::vector<std::size_t> roff_;
  std::vector<double> plus_, minus_, tplus_, tminus_;
};

/// Multiplies coefficient m by e^{i m phi0} (a rotation about z).
void phase_rotate(int p, double phi0, cplx* coef) noexcept;

/// Point-and-shoot translations between a box and its children (Greengard & Rokhlin, Acta Numerica 6 (1997) §5): M2M
/// (child -> parent) and L2L (parent -> child). Precomputes the two y-rotations of the child-parent directions and the
/// z-shift factors for one order p.
class ChildTranslations {
 public:
  explicit ChildTranslations(int p);
  [[nodiscard]] int order() const noexcept { return p_; }
  /// Adds to Mh_parent the multipole of child `octant` (bit0 = +x, bit1 = +y, bit2 = +z half).
  /// `work` must hold 2 ncoef(p) entries. Child side s, parent side 2s (scaled coefficients).
  void m2m(int octant, const cplx* Mh_child, cplx* Mh_parent, cplx* work) const noexcept;
  /// Adds to Lh_child the L2L of the parent's local.
  void l2l(int octant, const cplx* Lh_parent, cplx* Lh_child, cplx* work) const noexcept;

  /// Scaled z-shifts, exposed for tests: new center = old + d zhat; s0 old side, s1 new side.
  void m2m_z(const cplx* in, cplx* out, double d, double s0, double s1) const noexcept;
  void l2l_z(const cplx* in, cplx* out, double d, double s0, double s1) const noexcept;

 private:
  int p_;
  Rotation up_, down_;         // Ry(t0), Ry(pi - t0), cos t0 = 1/sqrt(3)
  std::vector<double> m2m_c_;  // sqrt(C(j-k,l) C(j+k,l)) at [idx(j,k)*(p+1) + l]
  std::vector<double> l2l_c_;  // sqrt(C(n-k,n-j) C(n+k,n-j)) at [idx(j,k)*(p+1) + (n-j)]
};

/// Gauss-Legendre nodes and weights on [-1, 1].
void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w);

}  // namespace rpyfmm::fmm::detail
