// M2M and L2L between a box and its children by point-and-shoot (docs/theory/fmm.md, "Translations
// between levels"; Guan, dissertation, Theorems 2.2.4-2.2.5):
// rotate so that the shift is along +z, shift along z, rotate back.
#include <cmath>
#include <numbers>

#include "rpyfmm/fmm/detail/expansions.hpp"

namespace rpyfmm::fmm::detail {

namespace {
// Child octant -> direction signs of the child center relative to the parent center.
inline void octant_signs(int octant, int& sx, int& sy, int& sz) {
  sx = (octant & 1) ? 1 : -1;
  sy = (octant & 2) ? 1 : -1;
  sz = (octant & 4) ? 1 : -1;
}
}  // namespace

ChildTranslations::ChildTranslations(int p)
    : p_(p),
      up_(Rotation::about_y(p, std::acos(1.0 / std::sqrt(3.0)))),
      down_(Rotation::about_y(p, std::numbers::pi - std::acos(1.0 / std::sqrt(3.0)))) {
  const Harmonics& H = Harmonics::cached(p);
  m2m_c_.assign(std::size_t(ncoef(p)) * (p + 1), 0.0);
  l2l_c_.assign(std::size_t(ncoef(p)) * (p + 1), 0.0);
  for (int j = 0; j <= p; ++j)
    for (int k = 0; k <= j; ++k) {
      for (int l = 0; l <= j - k; ++l)
        m2m_c_[std::size_t(idx(j, k)) * (p + 1) + l] = H.sqrt_binomial(j - k, l) * H.sqrt_binomial(j + k, l);
      for (int n = j; n <= p; ++n)
        l2l_c_[std::size_t(idx(j, k)) * (p + 1) + (n - j)] =
            H.sqrt_binomial(n - k, n - j) * H.sqrt_binomial(n + k, n - j);
    }
}

// Mh'_j^k = sum_l Mh_{j-l}^k (s0/s1)^(j-l) (-d/s1)^l sqrt(C(j-k,l) C(j+k,l))   (scaled)
void ChildTranslations::m2m_z(const cplx* in, cplx* out, double d, double s0, double s1) const noexcept {
  const int p = p_;
  std::vector<double> ra(p + 1), rb(p + 1);
  ra[0] = rb[0] = 1.0;
  for (int i = 1; i <= p; ++i) {
    ra[i] = ra[i - 1] * (s0 / s1);
    rb[i] = rb[i - 1] * (-d / s1);
  }
  for (int j = 0; j <= p; ++j)
    for (int k = 0; k <= j; ++k) {
      const double* cf = m2m_c_.data() + std::size_t(idx(j, k)) * (p + 1);
      cplx acc = 0.0;
      for (int l = 0; l <= j - k; ++l) acc += in[idx(j - l, k)] * (ra[j - l] * rb[l] * cf[l]);
      out[idx(j, k)] = acc;
    }
}

// Lh'_j^k = sum_{n>=j} Lh_n^k (s1/s0)^j (d/s0)^(n-j) sqrt(C(n-k,n-j) C(n+k,n-j))   (scaled)
void ChildTranslations::l2l_z(const cplx* in, cplx* out, double d, double s0, double s1) const noexcept {
  const int p = p_;
  std::vector<double> ra(p + 1), rb(p + 1);
  ra[0] = rb[0] = 1.0;
  for (int i = 1; i <= p; ++i) {
    ra[i] = ra[i - 1] * (s1 / s0);
    rb[i] = rb[i - 1] * (d / s0);
  }
  for (int j = 0; j <= p; ++j)
    for (int k = 0; k <= j; ++k) {
      const double* cf = l2l_c_.data() + std::size_t(idx(j, k)) * (p + 1);
      cplx acc = 0.0;
      for (int n = j; n <= p; ++n) acc += in[idx(n, k)] * (rb[n - j] * cf[n - j]);
      out[idx(j, k)] = acc * ra[j];
    }
}

// Child at offset (s/2)(sx,sy,sz) from the parent center (child side s, parent side 2s).
// M2M moves the center from child to parent: direction u = -(sx,sy,sz)/sqrt(3), |d| = sqrt(3) s/2.
// Frame Q_u = Ry(t) Rz(f) with u = (sin t cos f, sin t sin f, cos t), so A(Q_u) = A(Ry(t)) diag(e^{imf}).
void ChildTranslations::m2m(int octant, const cplx* Mh_child, cplx* Mh_parent, cplx* work) const noexcept {
  int sx, sy, sz;
  octant_signs(octant, sx, sy, sz);
  const int nc = ncoef(p_);
  cplx* a = work;
  cplx* b = work + nc;
  const double f = std::atan2(double(-sy), double(-sx));
  const Rotation& R = (-sz > 0) ? up_ : down_;
  for (int i = 0; i < nc; ++i) a[i] = Mh_child[i];
  phase_rotate(p_, f, a);
  R.apply(a, b, p_ + 1);
  // In units of the child side s = 1: |d| = sqrt(3)/2, s0 = 1, s1 = 2.
  m2m_z(b, a, std::sqrt(3.0) / 2.0, 1.0, 2.0);
  R.apply_adjoint(a, b, p_ + 1);
  phase_rotate(p_, -f, b);
  for (int i = 0; i < nc; ++i) Mh_parent[i] += b[i];
}

void ChildTranslations::l2l(int octant, const cplx* Lh_parent, cplx* Lh_child, cplx* work) const noexcept {
  int sx, sy, sz;
  octant_signs(octant, sx, sy, sz);
  const int nc = ncoef(p_);
  cplx* a = work;
  cplx* b = work + nc;
  const double f = std::atan2(double(sy), double(sx));
  const Rotation& R = (sz > 0) ? up_ : down_;
  for (int i = 0; i < nc; ++i) a[i] = Lh_parent[i];
  phase_rotate(p_, f, a);
  R.apply(a, b, p_ + 1);
  // Parent side 2 (old), child side 1 (new), |d| = sqrt(3)/2.
  l2l_z(b, a, std::sqrt(3.0) / 2.0, 2.0, 1.0);
  R.apply_adjoint(a, b, p_ + 1);
  phase_rotate(p_, -f, b);
  for (int i = 0; i < nc; ++i) Lh_child[i] += b[i];
}

}  // namespace rpyfmm::fmm::detail
