// rpyfmm::fmm — the plane-wave (exponential) representation used by the M2L
// (PLANEWAVE.md §3-§4; Cheng, Greengard & Rokhlin, JCP 155 (1999) §3-§4;
// dissertation 004, Theorems 2.2.7-2.2.9).
//
// In one frame (propagation along +-z), for a unit-frame multipole Mt = Mh/s:
//   M2F  F_k(m)  = i^m sum_{n>=m} (+-lambda_k)^n Mt_n^m / c_n^m,        0 <= m < K_k   (§3.4)
//   F2P  W_kj    = sum_{|m|<K_k} F_k(m) e^{i m a_kj},  a_kj = 2 pi j / M_k
//   shift V_kj   = W_kj exp(-+lambda_k d_z +- i lambda_k (d_x cos a_kj + d_y sin a_kj))
//   P2F  G_k(m)  = (1/M_k) sum_j V_kj e^{-i m a_kj}
//   F2L  Lh_n^m  = sum_{k: K_k > m} w_k lambda_k^n i^m / c_n^m [(-1)^n G_k^up(m) + G_k^down(m)]
// Frames (§4.2): z: identity; y: Q_Y (x,y,z) -> (z,x,y); x: Q_X (x,y,z) -> (-z,y,x).
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "rpyfmm/fmm/detail/expansions.hpp"
#include "rpyfmm/fmm/detail/harmonics.hpp"

namespace rpyfmm::fmm::detail {

class PlaneWave {
 public:
  /// `digits` in {3, 6, 9, 12} selects the quadrature table; p the expansion order.
  PlaneWave(int p, int digits);
  /// Process-wide cache (thread-safe).
  static const PlaneWave& cached(int p, int digits);

  [[nodiscard]] int order() const noexcept { return p_; }
  [[nodiscard]] int nlams() const noexcept { return nlams_; }
  [[nodiscard]] int sum_fourier() const noexcept { return sumK_; }
  [[nodiscard]] int sum_physical() const noexcept { return sumM_; }
  /// max_k K_k: rotated multipoles are needed only for m < kmax, F2L yields only m < kmax (§3.3).
  [[nodiscard]] int kmax() const noexcept { return kmax_; }

  /// Multipole into frame f (0 = z: identity, 1 = y, 2 = x, §4.2), orders m < kmax produced.
  /// Q_X = Ry(pi/2); Q_Y = Ry(-pi/2) Rz(-pi/2), so both use real y-rotation kernels (§4.3).
  void to_frame(int f, const cplx* M, cplx* Mf, cplx* work) const noexcept;
  /// Local out of frame f: L = A(Q_f)^H Lf, Lf having orders m < kmax only.
  void from_frame(int f, const cplx* Lf, cplx* L) const noexcept;
  /// Frame offset d' = Q_f d for an integer offset d (§4.2).
  static std::array<int, 3> frame_offset(int f, std::array<int, 3> d) noexcept {
    if (f == 1) return {d[2], d[0], d[1]};
    if (f == 2) return {-d[2], d[1], d[0]};
    return d;
  }

  /// M2F for both directions at once (parity split, §3.4). Fup, Fdown: sum_fourier() entries.
  void m2f(const cplx* Mt, cplx* Fup, cplx* Fdown) const noexcept;
  /// F2P: physical values W (sum_physical() entries) from Fourier coefficients F.
  void f2p(const cplx* F, cplx* W) const noexcept;
  /// P2F: Fourier coefficients G (sum_fourier()) from physical values V.
  void p2f(const cplx* V, cplx* G) const noexcept;
  /// F2L: scaled frame local (orders m < kmax, others set to 0) from the up and down waves.
  void f2l(const cplx* Gup, const cplx* Gdown, cplx* Lh) const noexcept;
  /// Translation factor Sh(d')_kj = exp(-lambda_k d'_z + i lambda_k (d'_x cos a_kj + d'_y sin a_kj)),
  /// components in [-3, 3] (the down factor is Sh(-d')).
  [[nodiscard]] const cplx* shift(int dx, int dy, int dz) const noexcept {
    return shift_.data() + std::size_t(((dz + 3) * 7 + (dy + 3)) * 7 + (dx + 3)) * sumM_;
  }

 private:
  int p_, nlams_, sumK_ = 0, sumM_ = 0, kmax_ = 0;
  std::vector<double> lambda_, weight_;
  std::vector<int> K_, M_, koff_, moff_;
  std::vector<double> lam_over_c_;          // [k * ncoef(p) + idx(n,m)] = lambda_k^n / c_n^m
  static constexpr int kMaxPhysical = 256;  // most angle nodes of one lambda_k (tables: 144)
  std::vector<int> toff_;                   // node k's twiddles start at toff_[k]
  std::vector<double> cos_, sin_;           // [toff_k + m * M_k + j] = cos / sin (m a_kj), m < K_k
  std::vector<cplx> shift_;                 // 343 tables of sumM
  Rotation rot_yneg_, rot_x_;               // Ry(-pi/2), Ry(pi/2)
};

/// Merge-and-shift group table (§5.3). For a source box at integer offset a in {-2..3}^3 (child units,
/// relative to the parent's lower-left child), and a frame f, the wave sign (+1 up, -1 down, 0 none)
/// and the mask of the 8 children (bit = octant: bit0 +x, bit1 +y, bit2 +z) it is sent to.
struct MergeGroup {
  signed char sign;
  unsigned char mask;
};
const std::array<std::array<MergeGroup, 3>, 216>& merge_groups();
inline int merge_position(int ax, int ay, int az) noexcept {
  return ((az + 2) * 6 + (ay + 2)) * 6 + (ax + 2);
}

}  // namespace rpyfmm::fmm::detail
