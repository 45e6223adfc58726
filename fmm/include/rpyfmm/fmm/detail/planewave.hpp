// rpyfmm::fmm — the plane-wave (exponential) representation used by the M2L
// (docs/theory/fmm.md, "Plane-wave M2L with merge-and-shift"; Cheng, Greengard & Rokhlin,
// J. Comput. Phys. 155 (1999) §3-§4; Guan, dissertation, Theorems 2.2.7-2.2.9).
//
// In one frame (propagation along +-z), for a unit-frame multipole Mt = Mh/s:
//   M2F  F_k(m)  = i^m sum_{n>=m} (+-lambda_k)^n Mt_n^m / c_n^m,        0 <= m < K_k
//   F2P  W_kj    = sum_{|m|<K_k} F_k(m) e^{i m a_kj},  a_kj = 2 pi j / M_k
//   shift V_kj   = W_kj exp(-+lambda_k d_z +- i lambda_k (d_x cos a_kj + d_y sin a_kj))
//   P2F  G_k(m)  = (1/M_k) sum_j V_kj e^{-i m a_kj}
// Real densities give W_{k,j+M_k/2} = conj(W_kj) (M_k even), so physical values are stored for the
// nodes j < M_k/2 only ("half nodes"): sum_physical() counts the stored values.
//   F2L  Lh_n^m  = sum_{k: K_k > m} w_k lambda_k^n i^m / c_n^m [(-1)^n G_k^up(m) + G_k^down(m)]
// Frames: z: identity; y: Q_Y (x,y,z) -> (z,x,y); x: Q_X (x,y,z) -> (-z,y,x).
#pragma once

#include <array>
#include <memory>
#include <vector>

#include "rpyfmm/fmm/detail/expansions.hpp"
#include "rpyfmm/fmm/detail/harmonics.hpp"

namespace rpyfmm::fmm::detail {

class PlaneWave {
 public:
  /// `nodes` (12 to 39 lambda nodes) selects the quadrature table; p the expansion order.
  PlaneWave(int p, int nodes);
  /// Process-wide cache (thread-safe).
  static const PlaneWave& cached(int p, int nodes);

  [[nodiscard]] int order() const noexcept { return p_; }
  [[nodiscard]] int nlams() const noexcept { return nlams_; }
  [[nodiscard]] int sum_fourier() const noexcept { return sumK_; }
  /// Stored physical values per direction: sum_k M_k / 2 (half nodes).
  [[nodiscard]] int sum_physical() const noexcept { return sumM_; }
  /// Node k's lambda_k, Fourier modes K_k, angle nodes M_k (even; M_k/2 of them stored) and storage offsets.
  [[nodiscard]] double lambda(int k) const noexcept { return lambda_[k]; }
  [[nodiscard]] int fourier_modes(int k) const noexcept { return K_[k]; }
  [[nodiscard]] int angle_nodes(int k) const noexcept { return M_[k]; }
  [[nodiscard]] int fourier_offset(int k) const noexcept { return koff_[k]; }
  [[nodiscard]] int physical_offset(int k) const noexcept { return moff_[k]; }
  /// max_k K_k: rotated multipoles are needed only for m < kmax, F2L yields only m < kmax.
  [[nodiscard]] int kmax() const noexcept { return kmax_; }

  /// Multipole into frame f (0 = z: identity, 1 = y, 2 = x), orders m < kmax produced.
  /// Q_X = Ry(pi/2); Q_Y = Ry(-pi/2) Rz(-pi/2), so both use real y-rotation kernels.
  void to_frame(int f, const cplx* M, cplx* Mf, cplx* work) const noexcept;
  /// Local out of frame f: L = A(Q_f)^H Lf, Lf having orders m < kmax only.
  void from_frame(int f, const cplx* Lf, cplx* L) const noexcept;
  /// Frame offset d' = Q_f d for an integer offset d.
  static std::array<int, 3> frame_offset(int f, std::array<int, 3> d) noexcept {
    if (f == 1) return {d[2], d[0], d[1]};
    if (f == 2) return {-d[2], d[1], d[0]};
    return d;
  }

  /// M2F for both directions at once (parity split). Fup, Fdown: sum_fourier() entries.
  void m2f(const cplx* Mt, cplx* Fup, cplx* Fdown) const noexcept;
  /// F2P: physical values W at the stored nodes (sum_physical() entries) from Fourier coefficients F.
  void f2p(const cplx* F, cplx* W) const noexcept;
  /// P2F: Fourier coefficients G (sum_fourier()) from physical values V at the stored nodes
  /// (the others being their conjugates).
  void p2f(const cplx* V, cplx* G) const noexcept;
  /// F2L: scaled frame local (orders m < kmax, others set to 0) from the up and down waves.
  void f2l(const cplx* Gup, const cplx* Gdown, cplx* Lh) const noexcept;
  /// Scratch of the batched conversions below (one per thread).
  struct LaneWork {
    std::vector<double> ar, ai, br, bi, fur, fui, fdr, fdi, vr, vi;
  };
  static constexpr int kDensityLanes = Rotation::kLanes;
  /// Batched source side of the M2L for nd <= kDensityLanes densities (planewave_batch.cpp): for
  /// each d, Mt = inv_s Mh_d into frame f, M2F, F2P up and down, as to_frame + m2f + f2p would,
  /// with the density index innermost so that every table entry serves all nd at once.
  /// Mh_d at Mh + d ldm; waves at Wup + d ldw and Wdown + d ldw (sum_physical() entries each).
  void multipole_to_waves(int f, const cplx* Mh, std::size_t ldm, int nd, double inv_s, cplx* Wup, cplx* Wdown,
                          std::size_t ldw, LaneWork& work) const noexcept;
  /// Batched target side: P2F of the up and down waves (nullptr = none), F2L, out of frame f, and
  /// L_d += the result (L_d at L + d ldl), as p2f + f2l + from_frame would.
  void waves_to_local(int f, const cplx* Vup, const cplx* Vdown, std::size_t ldv, int nd, cplx* L, std::size_t ldl,
                      LaneWork& work) const noexcept;
  /// Translation factor Sh(d')_kj = exp(-lambda_k d'_z + i lambda_k (d'_x cos a_kj + d'_y sin a_kj)),
  /// components in [-3, 3] (the down factor is Sh(-d')).
  [[nodiscard]] const cplx* shift(int dx, int dy, int dz) const noexcept {
    return shift_.data() + std::size_t(((dz + 3) * 7 + (dy + 3)) * 7 + (dx + 3)) * sumM_;
  }

 private:
  // Stages of multipole_to_waves and waves_to_local (planewave_batch.cpp), inlined into each
  // instruction-set version of those two. Lanes: [entry * kDensityLanes + d].
  [[gnu::always_inline]] inline void gather_multipole_lanes(const cplx* Mh, std::size_t ldm, int nd, double inv_s,
                                                            LaneWork& w) const noexcept;
  [[gnu::always_inline]] inline void rotate_lanes_into_frame(int f, LaneWork& w, const double*& mr,
                                                             const double*& mi) const noexcept;
  [[gnu::always_inline]] inline void m2f_lanes(const double* mr, const double* mi, LaneWork& w) const noexcept;
  [[gnu::always_inline]] inline void f2p_lanes(const LaneWork& w, int nd, cplx* Wup, cplx* Wdown,
                                               std::size_t ldw) const noexcept;
  [[gnu::always_inline]] inline void p2f_lanes(const cplx* V, std::size_t ldv, int nd, double* gr, double* gi,
                                               LaneWork& w) const noexcept;
  [[gnu::always_inline]] inline void f2l_lanes(LaneWork& w) const noexcept;
  [[gnu::always_inline]] inline void rotate_lanes_out_of_frame(int f, LaneWork& w, const double*& lr,
                                                               const double*& li) const noexcept;

  int p_, nlams_, sumK_ = 0, sumM_ = 0, kmax_ = 0;
  std::vector<double> lambda_, weight_;
  std::vector<int> K_, M_, Mh_, koff_, moff_;  // M_k even, Mh_k = M_k / 2 stored
  static constexpr int kLanes = 8;             // node tables padded to a multiple of this
  static constexpr int kMaxNodes = 64;         // most lambda nodes of a table (tables: 37), padded
  int nlp_ = 0;                                // nlams padded to kLanes
  std::vector<double> lam_over_c_;             // [idx(n,m) * nlp + k] = lambda_k^n / c_n^m (0 if K_k <= m)
  std::vector<double> lam_weight_over_c_;      // the same times w_k
  static constexpr int kMaxPhysical = 256;     // most stored angle nodes of one lambda_k (tables: 72)
  std::vector<int> toff_;                      // node k's twiddles start at toff_[k]
  std::vector<double> cos_, sin_;              // [toff_k + m * Mh_k + j] = cos / sin (m a_kj), m < K_k
  std::vector<cplx> shift_;                    // 343 tables of sumM (stored nodes)
  Rotation rot_yneg_, rot_x_;                  // Ry(-pi/2), Ry(pi/2)
};

/// Merge-and-shift group table. For a source box at integer offset a in {-2..3}^3 (child units,
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
