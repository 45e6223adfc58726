// Batched plane-wave conversions of the M2L for several densities (docs/theory/fmm.md, "Several
// densities"):
// the same M2F, F2P, P2F, F2L and frame rotations as planewave.cpp, with up to four densities
// held in the lanes of one vector (layout [entry * D + d]), so that each table entry is loaded
// once for all of them and the inner loops have no reductions. Used by the FMM driver for nd >= 2
// (FmmRpy's four Laplace densities); results equal the one-density path up to rounding.
#include <algorithm>

#include "planewave_kernels.hpp"
#include "rpyfmm/fmm/detail/planewave.hpp"

namespace rpyfmm::fmm::detail {

namespace {
constexpr int D = PlaneWave::kDensityLanes;

// i^m as (re, im).
[[gnu::always_inline]] inline void ipow_parts(int m, double& c, double& s) noexcept {
  constexpr double tc[4] = {1, 0, -1, 0}, ts[4] = {0, 1, 0, -1};
  c = tc[m & 3];
  s = ts[m & 3];
}

// Multiplies coefficient (n, m) of every lane by e^{i m phi0} for phi0 = quarter * pi/2 (quarter =
// +-1): the y-frame's Rz(-+pi/2) of phase_rotate, with the factors (+-i)^m exact.
[[gnu::always_inline]] inline void quarter_turn_lanes(int p, int quarter, double* re, double* im) noexcept {
  for (int m = 1; m <= p; ++m) {
    double c, s;
    ipow_parts(quarter * m, c, s);  // & 3 of a negative int is its value mod 4 (two's complement)
    for (int n = m; n <= p; ++n) {
      double* xr = re + std::size_t(idx(n, m)) * D;
      double* xi = im + std::size_t(idx(n, m)) * D;
#pragma omp simd
      for (int d = 0; d < D; ++d) {
        const double a = xr[d], b = xi[d];
        xr[d] = a * c - b * s;
        xi[d] = a * s + b * c;
      }
    }
  }
}

void ensure(std::vector<double>& v, std::size_t n) {
  if (v.size() < n) v.assign(n, 0.0);
}
}  // namespace

// Mt = inv_s Mh (unit-frame multipole) gathered into lanes; unused lanes are 0.
void PlaneWave::gather_multipole_lanes(const cplx* Mh, std::size_t ldm, int nd, double inv_s,
                                       LaneWork& w) const noexcept {
  const int nc = ncoef(p_);
  for (int i = 0; i < nc; ++i)
    for (int d = 0; d < D; ++d) {
      const cplx x = d < nd ? Mh[std::size_t(d) * ldm + i] * inv_s : cplx(0.0);
      w.ar[std::size_t(i) * D + d] = x.real();
      w.ai[std::size_t(i) * D + d] = x.imag();
    }
}

// Into frame f: z identity, x = Ry(pi/2), y = Ry(-pi/2) Rz(-pi/2). (mr, mi): the rotated lanes.
void PlaneWave::rotate_lanes_into_frame(int f, LaneWork& w, const double*& mr, const double*& mi) const noexcept {
  mr = w.ar.data();
  mi = w.ai.data();
  if (f == 2) {
    rot_x_.apply_lanes(w.ar.data(), w.ai.data(), w.br.data(), w.bi.data(), kmax_);
    mr = w.br.data();
    mi = w.bi.data();
  } else if (f == 1) {
    quarter_turn_lanes(p_, -1, w.ar.data(), w.ai.data());
    rot_yneg_.apply_lanes(w.ar.data(), w.ai.data(), w.br.data(), w.bi.data(), kmax_);
    mr = w.br.data();
    mi = w.bi.data();
  }
}

// M2F, both directions from the parity sums: F^up = i^m (E + O), F^down = i^m (-1)^m (E - O).
void PlaneWave::m2f_lanes(const double* mr, const double* mi, LaneWork& w) const noexcept {
  for (int k = 0; k < nlams_; ++k)
    for (int m = 0; m < K_[k]; ++m) {
      double er[D] = {}, ei[D] = {}, orr[D] = {}, oi[D] = {};
      for (int n = m; n <= p_; n += 2) {  // n - m even into E, n + 1 (odd) into O
        const double a = lam_over_c_[std::size_t(idx(n, m)) * nlp_ + k];
        const double* xr = mr + std::size_t(idx(n, m)) * D;
        const double* xi = mi + std::size_t(idx(n, m)) * D;
        const bool odd = n + 1 <= p_;
        const double b = odd ? lam_over_c_[std::size_t(idx(n + 1, m)) * nlp_ + k] : 0.0;
        const double* yr = odd ? mr + std::size_t(idx(n + 1, m)) * D : xr;
        const double* yi = odd ? mi + std::size_t(idx(n + 1, m)) * D : xi;
#pragma omp simd
        for (int d = 0; d < D; ++d) {
          er[d] += a * xr[d];
          ei[d] += a * xi[d];
          orr[d] += b * yr[d];
          oi[d] += b * yi[d];
        }
      }
      double c, s;
      ipow_parts(m, c, s);
      const double sd = (m & 1) ? -1.0 : 1.0;
      const std::size_t at = std::size_t(koff_[k] + m) * D;
#pragma omp simd
      for (int d = 0; d < D; ++d) {
        const double ur = er[d] + orr[d], ui = ei[d] + oi[d], dr = er[d] - orr[d], di = ei[d] - oi[d];
        w.fur[at + d] = c * ur - s * ui;
        w.fui[at + d] = c * ui + s * ur;
        w.fdr[at + d] = sd * (c * dr - s * di);
        w.fdi[at + d] = sd * (c * di + s * dr);
      }
    }
}

// F2P at the stored nodes, both directions.
void PlaneWave::f2p_lanes(const LaneWork& w, int nd, cplx* Wup, cplx* Wdown, std::size_t ldw) const noexcept {
  for (int k = 0; k < nlams_; ++k) {
    const int M = Mh_[k];
    for (int j = 0; j < M; ++j) {
      const std::size_t a0 = std::size_t(koff_[k]) * D;
      double ur[D], ui[D] = {}, dr[D], di[D] = {};
      for (int d = 0; d < D; ++d) {
        ur[d] = w.fur[a0 + d];
        dr[d] = w.fdr[a0 + d];
      }
      for (int m = 1; m < K_[k]; ++m) {
        const double c = 2.0 * cos_[toff_[k] + std::size_t(m) * M + j],
                     s = 2.0 * sin_[toff_[k] + std::size_t(m) * M + j];
        const std::size_t at = std::size_t(koff_[k] + m) * D;
        if (m & 1) {
#pragma omp simd
          for (int d = 0; d < D; ++d) {
            ui[d] += w.fur[at + d] * s + w.fui[at + d] * c;
            di[d] += w.fdr[at + d] * s + w.fdi[at + d] * c;
          }
        } else {
#pragma omp simd
          for (int d = 0; d < D; ++d) {
            ur[d] += w.fur[at + d] * c - w.fui[at + d] * s;
            dr[d] += w.fdr[at + d] * c - w.fdi[at + d] * s;
          }
        }
      }
      for (int d = 0; d < nd; ++d) {
        Wup[std::size_t(d) * ldw + moff_[k] + j] = cplx(ur[d], ui[d]);
        Wdown[std::size_t(d) * ldw + moff_[k] + j] = cplx(dr[d], di[d]);
      }
    }
  }
}

void PlaneWave::multipole_to_waves(int f, const cplx* Mh, std::size_t ldm, int nd, double inv_s, cplx* Wup, cplx* Wdown,
                                   std::size_t ldw, LaneWork& w) const noexcept {
  simd_dispatch([=, this, &w]() RPYFMM_SIMD_BODY {
    const std::size_t nlane = std::size_t(ncoef(p_)) * D, klane = std::size_t(sumK_) * D;
    for (auto* v : {&w.ar, &w.ai, &w.br, &w.bi}) ensure(*v, nlane);
    for (auto* v : {&w.fur, &w.fui, &w.fdr, &w.fdi}) ensure(*v, klane);
    gather_multipole_lanes(Mh, ldm, nd, inv_s, w);
    const double *mr, *mi;
    rotate_lanes_into_frame(f, w, mr, mi);
    m2f_lanes(mr, mi, w);
    f2p_lanes(w, nd, Wup, Wdown, ldw);
  });
}

// P2F from the stored nodes: G(m) = (2/M_k) sum_j e^{-i m a_j} (Re V_j, m even; i Im V_j, m odd).
// V == nullptr: no waves, G = 0.
void PlaneWave::p2f_lanes(const cplx* V, std::size_t ldv, int nd, double* gr, double* gi, LaneWork& w) const noexcept {
  const std::size_t klane = std::size_t(sumK_) * D;
  if (V == nullptr) {
    std::fill(gr, gr + klane, 0.0);
    std::fill(gi, gi + klane, 0.0);
    return;
  }
  for (int j = 0; j < sumM_; ++j)
    for (int d = 0; d < D; ++d) {
      const cplx v = d < nd ? V[std::size_t(d) * ldv + j] : cplx(0.0);
      w.vr[std::size_t(j) * D + d] = v.real();
      w.vi[std::size_t(j) * D + d] = v.imag();
    }
  for (int k = 0; k < nlams_; ++k) {
    const int M = Mh_[k];
    const double scale = 2.0 / M_[k];
    for (int m = 0; m < K_[k]; ++m) {
      const double* c = cos_.data() + toff_[k] + std::size_t(m) * M;
      const double* s = sin_.data() + toff_[k] + std::size_t(m) * M;
      const double* v = ((m & 1) ? w.vi.data() : w.vr.data()) + std::size_t(moff_[k]) * D;
      double vc[D] = {}, vs[D] = {};
      for (int j = 0; j < M; ++j)
#pragma omp simd
        for (int d = 0; d < D; ++d) {
          vc[d] += v[j * D + d] * c[j];
          vs[d] += v[j * D + d] * s[j];
        }
      const std::size_t at = std::size_t(koff_[k] + m) * D;
      for (int d = 0; d < D; ++d) {
        gr[at + d] = (m & 1) ? vs[d] * scale : vc[d] * scale;
        gi[at + d] = (m & 1) ? vc[d] * scale : -vs[d] * scale;
      }
    }
  }
}

// F2L: Lh_n^m = i^m sum_k w_k lambda_k^n / c_n^m [(-1)^n G^up + G^down], m < kmax, into (ar, ai).
void PlaneWave::f2l_lanes(LaneWork& w) const noexcept {
  const std::size_t nlane = std::size_t(ncoef(p_)) * D;
  std::fill(w.ar.begin(), w.ar.begin() + nlane, 0.0);
  std::fill(w.ai.begin(), w.ai.begin() + nlane, 0.0);
  for (int m = 0; m < kmax_; ++m) {
    double c, s;
    ipow_parts(m, c, s);
    for (int n = m; n <= p_; ++n) {
      const double sgn = (n & 1) ? -1.0 : 1.0;
      double re[D] = {}, im[D] = {};
      for (int k = 0; k < nlams_; ++k) {
        if (m >= K_[k]) continue;
        const double a = lam_weight_over_c_[std::size_t(idx(n, m)) * nlp_ + k];
        const std::size_t at = std::size_t(koff_[k] + m) * D;
#pragma omp simd
        for (int d = 0; d < D; ++d) {
          re[d] += a * (sgn * w.fur[at + d] + w.fdr[at + d]);
          im[d] += a * (sgn * w.fui[at + d] + w.fdi[at + d]);
        }
      }
      const std::size_t at = std::size_t(idx(n, m)) * D;
#pragma omp simd
      for (int d = 0; d < D; ++d) {
        w.ar[at + d] = c * re[d] - s * im[d];
        w.ai[at + d] = c * im[d] + s * re[d];
      }
    }
  }
}

// Out of frame f: L = A(Q_f)^H Lf. (lr, li): the rotated lanes.
void PlaneWave::rotate_lanes_out_of_frame(int f, LaneWork& w, const double*& lr, const double*& li) const noexcept {
  lr = w.ar.data();
  li = w.ai.data();
  if (f == 2) {
    rot_x_.apply_adjoint_lanes(w.ar.data(), w.ai.data(), w.br.data(), w.bi.data(), kmax_);
    lr = w.br.data();
    li = w.bi.data();
  } else if (f == 1) {
    rot_yneg_.apply_adjoint_lanes(w.ar.data(), w.ai.data(), w.br.data(), w.bi.data(), kmax_);
    quarter_turn_lanes(p_, 1, w.br.data(), w.bi.data());
    lr = w.br.data();
    li = w.bi.data();
  }
}

void PlaneWave::waves_to_local(int f, const cplx* Vup, const cplx* Vdown, std::size_t ldv, int nd, cplx* L,
                               std::size_t ldl, LaneWork& w) const noexcept {
  simd_dispatch([=, this, &w]() RPYFMM_SIMD_BODY {
    const int nc = ncoef(p_);
    const std::size_t nlane = std::size_t(nc) * D, klane = std::size_t(sumK_) * D, mlane = std::size_t(sumM_) * D;
    for (auto* v : {&w.ar, &w.ai, &w.br, &w.bi}) ensure(*v, nlane);
    for (auto* v : {&w.fur, &w.fui, &w.fdr, &w.fdi}) ensure(*v, klane);
    for (auto* v : {&w.vr, &w.vi}) ensure(*v, mlane);
    p2f_lanes(Vup, ldv, nd, w.fur.data(), w.fui.data(), w);
    p2f_lanes(Vdown, ldv, nd, w.fdr.data(), w.fdi.data(), w);
    f2l_lanes(w);
    const double *lr, *li;
    rotate_lanes_out_of_frame(f, w, lr, li);
    for (int d = 0; d < nd; ++d) {
      cplx* out = L + std::size_t(d) * ldl;
      for (int i = 0; i < nc; ++i) out[i] += cplx(lr[std::size_t(i) * D + d], li[std::size_t(i) * D + d]);
    }
  });
}

}  // namespace rpyfmm::fmm::detail
