// Plane-wave M2L operators (PLANEWAVE.md §3.4, §4, §5.3).
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

PlaneWave::PlaneWave(int p, int digits)
    : p_(p),
      rot_yneg_(Rotation::about_y(p, -0.5 * std::numbers::pi)),
      rot_x_(Rotation::about_y(p, 0.5 * std::numbers::pi)) {
  const auto table = planewave_table(digits);
  if (table.empty()) throw std::invalid_argument("PlaneWave: no table for this precision");
  nlams_ = int(table.size());
  for (const auto& node : table) {
    lambda_.push_back(node.lambda);
    weight_.push_back(node.weight);
    K_.push_back(node.nfourier);
    M_.push_back(node.nphysical);
    koff_.push_back(sumK_);
    moff_.push_back(sumM_);
    sumK_ += node.nfourier;
    sumM_ += node.nphysical;
    kmax_ = std::max(kmax_, node.nfourier);
  }
  const Harmonics& H = Harmonics::cached(p);
  const int nc = ncoef(p);
  lam_over_c_.assign(std::size_t(nlams_) * nc, 0.0);
  for (int k = 0; k < nlams_; ++k) {
    // lambda^n / c_n^m through logs would lose digits; the direct product stays below ~1e80.
    double lp = 1.0;
    for (int n = 0; n <= p; ++n) {
      for (int m = 0; m <= n; ++m) lam_over_c_[std::size_t(k) * nc + idx(n, m)] = lp * H.inv_c(n, m);
      lp *= lambda_[k];
    }
  }
  // Twiddles e^{i m a_kj} as separate cos / sin tables, m-major within node k, so that F2P and
  // P2F run over the angle index j with unit stride (vectorized).
  for (int k = 0; k < nlams_; ++k) {
    if (M_[k] > kMaxPhysical) throw std::invalid_argument("PlaneWave: table has too many angle nodes");
    toff_.push_back(int(cos_.size()));
    for (int m = 0; m < K_[k]; ++m)
      for (int j = 0; j < M_[k]; ++j) {
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
          for (int j = 0; j < M_[k]; ++j) {
            const double a = 2.0 * std::numbers::pi * j / M_[k];
            const double lam = lambda_[k];
            out[moff_[k] + j] = std::exp(-lam * dz) * std::exp(cplx(0.0, lam * (dx * std::cos(a) + dy * std::sin(a))));
          }
      }
}

const PlaneWave& PlaneWave::cached(int p, int digits) {
  static std::mutex mutex;
  static std::map<std::pair<int, int>, std::unique_ptr<PlaneWave>> cache;
  std::lock_guard lock(mutex);
  auto& slot = cache[{p, digits}];
  if (!slot) slot = std::make_unique<PlaneWave>(p, digits);
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
}  // namespace

void PlaneWave::m2f(const cplx* Mt, cplx* Fup, cplx* Fdown) const noexcept {
  const int nc = ncoef(p_);
  for (int k = 0; k < nlams_; ++k) {
    const double* lc = lam_over_c_.data() + std::size_t(k) * nc;
    for (int m = 0; m < K_[k]; ++m) {
      cplx E = 0.0, O = 0.0;
      for (int n = m; n <= p_; n += 2) E += lc[idx(n, m)] * Mt[idx(n, m)];
      for (int n = m + 1; n <= p_; n += 2) O += lc[idx(n, m)] * Mt[idx(n, m)];
      const cplx im = ipow(m);
      Fup[koff_[k] + m] = im * (E + O);
      Fdown[koff_[k] + m] = (m & 1) ? -im * (E - O) : im * (E - O);
    }
  }
}

RPYFMM_PW_CLONES void PlaneWave::f2p(const cplx* F, cplx* W) const noexcept {
  double re[kMaxPhysical], im[kMaxPhysical];
  for (int k = 0; k < nlams_; ++k) {
    const cplx* f = F + koff_[k];
    const int M = M_[k];
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
}

RPYFMM_PW_CLONES void PlaneWave::p2f(const cplx* V, cplx* G) const noexcept {
  double vr[kMaxPhysical], vi[kMaxPhysical];
  for (int k = 0; k < nlams_; ++k) {
    const int M = M_[k];
    const double inv = 1.0 / M;
    for (int j = 0; j < M; ++j) {
      vr[j] = V[moff_[k] + j].real();
      vi[j] = V[moff_[k] + j].imag();
    }
    for (int m = 0; m < K_[k]; ++m) {  // (1/M) sum_j V_j e^{-i m a_kj}
      const double* c = cos_.data() + toff_[k] + std::size_t(m) * M;
      const double* s = sin_.data() + toff_[k] + std::size_t(m) * M;
      double gr = 0.0, gi = 0.0;
#pragma omp simd reduction(+ : gr, gi)
      for (int j = 0; j < M; ++j) {
        gr += vr[j] * c[j] + vi[j] * s[j];
        gi += vi[j] * c[j] - vr[j] * s[j];
      }
      G[koff_[k] + m] = cplx(gr * inv, gi * inv);
    }
  }
}

void PlaneWave::f2l(const cplx* Gup, const cplx* Gdown, cplx* Lh) const noexcept {
  const int nc = ncoef(p_);
  for (int i = 0; i < nc; ++i) Lh[i] = 0.0;
  for (int k = 0; k < nlams_; ++k) {
    const double* lc = lam_over_c_.data() + std::size_t(k) * nc;
    const double w = weight_[k];
    for (int m = 0; m < K_[k]; ++m) {
      const cplx gu = Gup[koff_[k] + m] * w, gd = Gdown[koff_[k] + m] * w;
      const cplx sum_even = gu + gd, sum_odd = gd - gu;  // (-1)^n Gup + Gdown
      const cplx im = ipow(m);
      for (int n = m; n <= p_; ++n) Lh[idx(n, m)] += lc[idx(n, m)] * ((n & 1) ? sum_odd : sum_even) * im;
    }
  }
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
          // Rule 2: classify each V-pair by §4.1.
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
