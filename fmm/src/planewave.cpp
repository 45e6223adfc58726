// Plane-wave M2L operators (docs/theory/fmm.md, "Plane-wave M2L with merge-and-shift"; Guan,
// dissertation, Theorems 2.2.7-2.2.9).
#include "rpyfmm/fmm/detail/planewave.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <numbers>
#include <stdexcept>

#include "planewave_kernels.hpp"
#include "planewave_tables.hpp"

namespace rpyfmm::fmm::detail {

PlaneWave::PlaneWave(int p, int nodes)
    : p_(p),
      rot_yneg_(Rotation::about_y(p, -0.5 * std::numbers::pi)),
      rot_x_(Rotation::about_y(p, 0.5 * std::numbers::pi)) {
  const auto table = planewave_table(nodes);
  if (table.empty()) throw std::invalid_argument("PlaneWave: no table of this many lambda nodes");
  nlams_ = int(table.size());
  if (nlams_ > kMaxNodes) throw std::invalid_argument("PlaneWave: table has too many lambda nodes");
  for (const auto& node : table) {
    lambda_.push_back(node.lambda);
    weight_.push_back(node.weight);
    K_.push_back(node.nfourier);
    // Half-node storage: for real densities W(a + pi) = conj(W(a)), and so do
    // the translation factors, so with M_k even only the nodes j < M_k/2 are stored, shifted and
    // transformed. The published odd M_k (and the one-node last lambda) are rounded up to even,
    // which keeps every table within its tolerance (docs/theory/fmm.md, "Half the angle nodes";
    // test FmmBlocks.PlaneWaveM2LAllOffsetsAllTables).
    const int Mk = node.nphysical + (node.nphysical & 1);
    M_.push_back(Mk);
    Mh_.push_back(Mk / 2);
    moff_.push_back(sumM_);
    sumM_ += Mk / 2;
    koff_.push_back(sumK_);
    sumK_ += node.nfourier;
    kmax_ = std::max(kmax_, node.nfourier);
  }
  const Harmonics& H = Harmonics::cached(p);
  const int nc = ncoef(p);
  // lambda_k^n / c_n^m, node index fastest (padded to kLanes, zero where K_k <= m), so that M2F and
  // F2L run over the nodes k with unit stride for each (n, m).
  nlp_ = (nlams_ + kLanes - 1) / kLanes * kLanes;
  lam_over_c_.assign(std::size_t(nc) * nlp_, 0.0);
  lam_weight_over_c_.assign(std::size_t(nc) * nlp_, 0.0);
  for (int k = 0; k < nlams_; ++k) {
    // lambda^n / c_n^m through logs would lose digits; the direct product stays below ~1e80.
    double lp = 1.0;
    for (int n = 0; n <= p; ++n) {
      for (int m = 0; m <= n && m < K_[k]; ++m) {
        const std::size_t at = std::size_t(idx(n, m)) * nlp_ + k;
        lam_over_c_[at] = lp * H.inv_c(n, m);
        lam_weight_over_c_[at] = lam_over_c_[at] * weight_[k];
      }
      lp *= lambda_[k];
    }
  }
  // Twiddles e^{i m a_kj} of the stored nodes j < M_k/2 as separate cos / sin tables, m-major
  // within node k, so that F2P and P2F run over the angle index j with unit stride (vectorized).
  for (int k = 0; k < nlams_; ++k) {
    if (Mh_[k] > kMaxPhysical) throw std::invalid_argument("PlaneWave: table has too many angle nodes");
    toff_.push_back(int(cos_.size()));
    for (int m = 0; m < K_[k]; ++m)
      for (int j = 0; j < Mh_[k]; ++j) {
        const double a = 2.0 * std::numbers::pi * j / M_[k];
        cos_.push_back(std::cos(m * a));
        sin_.push_back(std::sin(m * a));
      }
  }
  shift_.resize(std::size_t(343) * sumM_);
  for (int dz = -3; dz <= 3; ++dz)
    for (int dy = -3; dy <= 3; ++dy)
      for (int dx = -3; dx <= 3; ++dx) {
        cplx* out = shift_.data() + std::size_t(((dz + 3) * 7 + (dy + 3)) * 7 + (dx + 3)) * sumM_;
        for (int k = 0; k < nlams_; ++k)
          for (int j = 0; j < Mh_[k]; ++j) {
            const double a = 2.0 * std::numbers::pi * j / M_[k];
            const double lam = lambda_[k];
            out[moff_[k] + j] = std::exp(-lam * dz) * std::exp(cplx(0.0, lam * (dx * std::cos(a) + dy * std::sin(a))));
          }
      }
}

const PlaneWave& PlaneWave::cached(int p, int nodes) {
  static std::mutex mutex;
  static std::map<std::pair<int, int>, std::unique_ptr<PlaneWave>> cache;
  std::lock_guard lock(mutex);
  auto& slot = cache[{p, nodes}];
  if (!slot) slot = std::make_unique<PlaneWave>(p, nodes);
  return *slot;
}

void PlaneWave::to_frame(int f, const cplx* M, cplx* Mf, cplx* work) const noexcept {
  const int nc = ncoef(p_);
  if (f == 0) {
    for (int i = 0; i < nc; ++i) Mf[i] = M[i];
  } else if (f == 2) {
    rot_x_.apply(M, Mf, kmax_);
  } else {
    for (int i = 0; i < nc; ++i) work[i] = M[i];
    phase_rotate(p_, -0.5 * std::numbers::pi, work);
    rot_yneg_.apply(work, Mf, kmax_);
  }
}

void PlaneWave::from_frame(int f, const cplx* Lf, cplx* L) const noexcept {
  const int nc = ncoef(p_);
  if (f == 0) {
    for (int i = 0; i < nc; ++i) L[i] = Lf[i];
  } else if (f == 2) {
    rot_x_.apply_adjoint(Lf, L, kmax_);
  } else {
    rot_yneg_.apply_adjoint(Lf, L, kmax_);
    phase_rotate(p_, 0.5 * std::numbers::pi, L);
  }
}

namespace {
inline cplx ipow(int m) noexcept {  // i^m
  switch (m & 3) {
    case 0:
      return {1, 0};
    case 1:
      return {0, 1};
    case 2:
      return {-1, 0};
    default:
      return {0, -1};
  }
}
// (sum_j a_j x_j, sum_j a_j y_j), inlined so that it takes the caller's vector ISA.
[[gnu::always_inline]] inline void dot2(const double* a, const double* x, const double* y, int n, double& ax,
                                        double& ay) noexcept {
  double sx = 0.0, sy = 0.0;
#pragma omp simd reduction(+ : sx, sy)
  for (int j = 0; j < n; ++j) {
    sx += a[j] * x[j];
    sy += a[j] * y[j];
  }
  ax = sx;
  ay = sy;
}
}  // namespace

void PlaneWave::m2f(const cplx* Mt, cplx* Fup, cplx* Fdown) const noexcept {
  simd_dispatch([=, this]() RPYFMM_SIMD_BODY {
    // For each m, the parity sums E_k = sum_{n-m even} lambda_k^n Mt_n^m / c_n^m and O_k (odd) for all
    // nodes k at once; F^up = i^m (E + O), F^down = i^m (-1)^m (E - O).
    alignas(64) double er[kMaxNodes], ei[kMaxNodes], orr[kMaxNodes], oi[kMaxNodes];
    const int L = nlp_;
    for (int m = 0; m < kmax_; ++m) {
      for (int k = 0; k < L; ++k) er[k] = ei[k] = orr[k] = oi[k] = 0.0;
      for (int n = m; n <= p_; ++n) {
        const double* a = lam_over_c_.data() + std::size_t(idx(n, m)) * L;
        const double mr = Mt[idx(n, m)].real(), mi = Mt[idx(n, m)].imag();
        double* re = ((n - m) & 1) ? orr : er;
        double* im = ((n - m) & 1) ? oi : ei;
#pragma omp simd
        for (int k = 0; k < L; ++k) {
          re[k] += a[k] * mr;
          im[k] += a[k] * mi;
        }
      }
      const cplx im = ipow(m), imd = (m & 1) ? -im : im;
      for (int k = 0; k < nlams_; ++k) {
        if (m >= K_[k]) continue;
        Fup[koff_[k] + m] = im * cplx(er[k] + orr[k], ei[k] + oi[k]);
        Fdown[koff_[k] + m] = imd * cplx(er[k] - orr[k], ei[k] - oi[k]);
      }
    }
  });
}

void PlaneWave::f2p(const cplx* F, cplx* W) const noexcept {
  simd_dispatch([=, this]() RPYFMM_SIMD_BODY {
    double re[kMaxPhysical], im[kMaxPhysical];
    for (int k = 0; k < nlams_; ++k) {
      const cplx* f = F + koff_[k];
      const int M = Mh_[k];  // stored nodes j < M_k / 2; W_{j + M_k/2} = conj(W_j)
      for (int j = 0; j < M; ++j) {
        re[j] = f[0].real();
        im[j] = 0.0;
      }
      // W_kj = F(0) + 2 sum_{m>0} [Re or Im of F(m) e^{i m a_kj}] (real charges: F(-m) = conj F(m) up
      // to the parity of m, so even m contribute to the real and odd m to the imaginary part).
      for (int m = 1; m < K_[k]; ++m) {
        const double fr = 2.0 * f[m].real(), fi = 2.0 * f[m].imag();
        const double* c = cos_.data() + toff_[k] + std::size_t(m) * M;
        const double* s = sin_.data() + toff_[k] + std::size_t(m) * M;
        if (m & 1) {
#pragma omp simd
          for (int j = 0; j < M; ++j) im[j] += fr * s[j] + fi * c[j];
        } else {
#pragma omp simd
          for (int j = 0; j < M; ++j) re[j] += fr * c[j] - fi * s[j];
        }
      }
      for (int j = 0; j < M; ++j) W[moff_[k] + j] = cplx(re[j], im[j]);
    }
  });
}

void PlaneWave::p2f(const cplx* V, cplx* G) const noexcept {
  simd_dispatch([=, this]() RPYFMM_SIMD_BODY {
    double vr[kMaxPhysical], vi[kMaxPhysical];
    for (int k = 0; k < nlams_; ++k) {
      const int M = Mh_[k];
      const double scale = 2.0 / M_[k];
      for (int j = 0; j < M; ++j) {
        vr[j] = V[moff_[k] + j].real();
        vi[j] = V[moff_[k] + j].imag();
      }
      // G(m) = (1/M_k) sum_{j < M_k} V_j e^{-i m a_j}; with V_{j + M_k/2} = conj(V_j) and
      // e^{-i m (a + pi)} = (-1)^m e^{-i m a} the pair (j, j + M_k/2) gives 2 Re V_j e^{-i m a_j}
      // for even m and 2i Im V_j e^{-i m a_j} for odd m: real x complex sums.
      for (int m = 0; m < K_[k]; ++m) {
        const double* c = cos_.data() + toff_[k] + std::size_t(m) * M;
        const double* s = sin_.data() + toff_[k] + std::size_t(m) * M;
        double vc, vs;
        dot2((m & 1) ? vi : vr, c, s, M, vc, vs);
        G[koff_[k] + m] = (m & 1) ? cplx(vs * scale, vc * scale) : cplx(vc * scale, -vs * scale);
      }
    }
  });
}

void PlaneWave::f2l(const cplx* Gup, const cplx* Gdown, cplx* Lh) const noexcept {
  simd_dispatch([=, this]() RPYFMM_SIMD_BODY {
    // Lh_n^m = i^m sum_k w_k lambda_k^n / c_n^m [(-1)^n G_k^up(m) + G_k^down(m)], one dot product
    // over the nodes k per (n, m); the table is zero where K_k <= m, so those nodes drop out.
    alignas(64) double er[kMaxNodes], ei[kMaxNodes], orr[kMaxNodes], oi[kMaxNodes];
    const int L = nlp_, nc = ncoef(p_);
    for (int i = 0; i < nc; ++i) Lh[i] = 0.0;
    for (int m = 0; m < kmax_; ++m) {
      for (int k = 0; k < L; ++k) er[k] = ei[k] = orr[k] = oi[k] = 0.0;
      for (int k = 0; k < nlams_; ++k) {
        if (m >= K_[k]) continue;
        const cplx gu = Gup[koff_[k] + m], gd = Gdown[koff_[k] + m];
        er[k] = gu.real() + gd.real();  // even n
        ei[k] = gu.imag() + gd.imag();
        orr[k] = gd.real() - gu.real();  // odd n
        oi[k] = gd.imag() - gu.imag();
      }
      const cplx im = ipow(m);
      for (int n = m; n <= p_; ++n) {
        const double* a = lam_weight_over_c_.data() + std::size_t(idx(n, m)) * L;
        double re, imag;
        dot2(a, (n & 1) ? orr : er, (n & 1) ? oi : ei, L, re, imag);
        Lh[idx(n, m)] = im * cplx(re, imag);
      }
    }
  });
}

const std::array<std::array<MergeGroup, 3>, 216>& merge_groups() {
  static const auto table = [] {
    std::array<std::array<MergeGroup, 3>, 216> t{};
    for (int az = -2; az <= 3; ++az)
      for (int ay = -2; ay <= 3; ++ay)
        for (int ax = -2; ax <= 3; ++ax) {
          auto& g = t[merge_position(ax, ay, az)];
          for (auto& e : g) e = {0, 0};
          const int a[3] = {ax, ay, az};
          // Rule 1: separated from all 8 children along one axis (precedence z, y, x).
          const int frame_axis[3] = {2, 1, 0};  // frame f propagates along axis frame_axis[f]
          bool all8 = false;
          for (int f = 0; f < 3 && !all8; ++f) {
            const int ai = a[frame_axis[f]];
            if (ai == -2 || ai == 3) {
              g[f] = {static_cast<signed char>(ai == -2 ? 1 : -1), 0xFF};
              all8 = true;
            }
          }
          if (all8) continue;
          // Rule 2: classify each V-pair by the first axis along which the boxes are separated (CGR 1999 §4).
          for (int oct = 0; oct < 8; ++oct) {
            const int c[3] = {oct & 1, (oct >> 1) & 1, (oct >> 2) & 1};
            const int d[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
            if (std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])}) < 2) continue;
            int f, sign;
            if (std::abs(d[2]) >= 2) {
              f = 0;
              sign = d[2] > 0 ? 1 : -1;
            } else if (std::abs(d[1]) >= 2) {
              f = 1;
              sign = d[1] > 0 ? 1 : -1;
            } else {
              f = 2;
              sign = d[0] > 0 ? 1 : -1;
            }
            g[f].sign = static_cast<signed char>(sign);
            g[f].mask = static_cast<unsigned char>(g[f].mask | (1u << oct));
          }
        }
    return t;
  }();
  return table;
}

}  // namespace rpyfmm::fmm::detail
