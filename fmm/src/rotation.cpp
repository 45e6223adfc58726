// Rotation matrices of spherical-harmonic expansions (docs/theory/fmm.md, "Translations between
// levels"; Greengard & Rokhlin, Acta Numerica 6 (1997) §5):
//   A^n_{m'm}(Q) = (2n+1)/(4 pi) int_S2 Y_n^m(u) conj(Y_n^m'(Q u)) dOmega(u),
// evaluated by the exact product rule (n+1 Gauss-Legendre nodes in cos(theta), 2n+2 angles),
// as one small complex GEMM per degree.
#include <Eigen/Dense>
#include <cmath>
#include <numbers>

#include "planewave_kernels.hpp"
#include "rpyfmm/fmm/detail/expansions.hpp"

namespace rpyfmm::fmm::detail {

namespace {
// Lane layout -> one complex vector per lane -> op -> lane layout (rotations without real kernels).
template <class Op>
void generic_lanes(const double* xr, const double* xi, double* yr, double* yi, int p, Op op) {
  constexpr int D = Rotation::kLanes;
  const int nc = ncoef(p);
  std::vector<cplx> in(nc), out(nc);
  for (int d = 0; d < D; ++d) {
    for (int i = 0; i < nc; ++i) in[i] = cplx(xr[std::size_t(i) * D + d], xi[std::size_t(i) * D + d]);
    op(in.data(), out.data());
    for (int i = 0; i < nc; ++i) {
      yr[std::size_t(i) * D + d] = out[i].real();
      yi[std::size_t(i) * D + d] = out[i].imag();
    }
  }
}
}  // namespace

void gauss_legendre(int n, std::vector<double>& x, std::vector<double>& w) {
  x.assign(n, 0.0);
  w.assign(n, 0.0);
  for (int i = 0; i < n; ++i) {
    double t = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    double dp = 1.0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = t;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2 * k - 1) * t * p1 - (k - 1) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      if (n == 1) p0 = 1.0;
      dp = n * (t * p1 - p0) / (t * t - 1.0);
      const double dt = p1 / dp;
      t -= dt;
      if (std::abs(dt) < 1e-16) break;
    }
    double p0 = 1.0, p1 = t;
    for (int k = 2; k <= n; ++k) {
      const double p2 = ((2 * k - 1) * t * p1 - (k - 1) * p0) / k;
      p0 = p1;
      p1 = p2;
    }
    dp = n * (t * p1 - p0) / (t * t - 1.0);
    x[i] = t;
    w[i] = 2.0 / ((1.0 - t * t) * dp * dp);
  }
}

Rotation::Rotation(int p, const std::array<double, 9>& Q) : p_(p) {
  off_.resize(p + 2);
  off_[0] = 0;
  for (int n = 0; n <= p; ++n) off_[n + 1] = off_[n] + std::size_t(2 * n + 1) * (2 * n + 1);
  a_.assign(off_[p + 1], cplx(0.0));
  const Harmonics& H = Harmonics::cached(p);
#pragma omp parallel for schedule(dynamic)
  for (int n = 0; n <= p; ++n) {
    const int nt = n + 1, nphi = 2 * n + 2, npts = nt * nphi, dim = 2 * n + 1;
    std::vector<double> gx, gw;
    gauss_legendre(nt, gx, gw);
    Eigen::MatrixXcd Yu(npts, dim), Yv(npts, dim);
    Eigen::VectorXd wts(npts);
    std::vector<cplx> R(ncoef(n));
    auto fill = [&](Eigen::MatrixXcd& Y, int row, double x, double y, double z) {
      H.regular(n, x, y, z, R.data());
      for (int m = 0; m <= n; ++m) {
        const cplx v = H.c(n, m) * R[idx(n, m)];
        Y(row, n + m) = v;
        if (m > 0) Y(row, n - m) = std::conj(v);
      }
    };
    for (int it = 0; it < nt; ++it) {
      const double ct = gx[it], st = std::sqrt(std::max(0.0, 1.0 - ct * ct));
      for (int ip = 0; ip < nphi; ++ip) {
        const double ph = 2.0 * std::numbers::pi * ip / nphi;
        const int row = it * nphi + ip;
        const double u[3] = {st * std::cos(ph), st * std::sin(ph), ct};
        const double v[3] = {Q[0] * u[0] + Q[1] * u[1] + Q[2] * u[2], Q[3] * u[0] + Q[4] * u[1] + Q[5] * u[2],
                             Q[6] * u[0] + Q[7] * u[1] + Q[8] * u[2]};
        fill(Yu, row, u[0], u[1], u[2]);
        fill(Yv, row, v[0], v[1], v[2]);
        wts[row] = gw[it] * (2.0 * std::numbers::pi / nphi) * (2 * n + 1) / (4.0 * std::numbers::pi);
      }
    }
    const Eigen::MatrixXcd A = Yv.adjoint() * (wts.asDiagonal() * Yu);  // rows m', cols m
    for (int i = 0; i < dim; ++i)
      for (int j = 0; j < dim; ++j) a_[off_[n] + std::size_t(i) * dim + j] = A(i, j);
  }
}

Rotation Rotation::about_y(int p, double t) {
  // Real matrix: only rows m' >= 0 are computed (two real GEMMs per degree instead of one complex
  // GEMM over all rows); a real A satisfies A_{-m',-m} = A_{m'm} (from Y^{-m} = conj(Y^m)).
  const double ct0 = std::cos(t), st0 = std::sin(t);
  const std::array<double, 9> Q = {ct0, 0.0, -st0, 0.0, 1.0, 0.0, st0, 0.0, ct0};
  Rotation r;
  r.p_ = p;
  r.off_.resize(p + 2);
  r.off_[0] = 0;
  for (int n = 0; n <= p; ++n) r.off_[n + 1] = r.off_[n] + std::size_t(2 * n + 1) * (2 * n + 1);
  r.a_.assign(r.off_[p + 1], cplx(0.0));
  const Harmonics& H = Harmonics::cached(p);
#pragma omp parallel for schedule(dynamic)
  for (int n = p; n >= 0; --n) {
    // The reflection y -> -y commutes with Ry and conjugates both harmonics, so the angles phi and
    // -phi contribute equally to the real part: sum over phi_j in [0, pi] with doubled weights.
    const int nt = n + 1, nphi = 2 * n + 2, nhalf = n + 2, npts = nt * nhalf, dim = 2 * n + 1;
    std::vector<double> gx, gw;
    gauss_legendre(nt, gx, gw);
    Eigen::MatrixXd Ur(npts, dim), Ui(npts, dim), Vr(npts, n + 1), Vi(npts, n + 1);
    std::vector<cplx> R(ncoef(n)), ring(n + 1);
    for (int it = 0; it < nt; ++it) {
      const double c = gx[it], sn = std::sqrt(std::max(0.0, 1.0 - c * c));
      H.regular(n, sn, 0.0, c, R.data());  // Y_n^m on the ring at phi = 0; e^{i m phi} added below
      for (int m = 0; m <= n; ++m) ring[m] = H.c(n, m) * R[idx(n, m)];
      for (int ip = 0; ip < nhalf; ++ip) {
        const double ph = 2.0 * std::numbers::pi * ip / nphi;
        const int row = it * nhalf + ip;
        const double u[3] = {sn * std::cos(ph), sn * std::sin(ph), c};
        const double mult = (ip == 0 || ip == n + 1) ? 1.0 : 2.0;
        const double w = mult * gw[it] * (2.0 * std::numbers::pi / nphi) * (2 * n + 1) / (4.0 * std::numbers::pi);
        for (int m = 0; m <= n; ++m) {
          const cplx y = w * ring[m] * cplx(std::cos(m * ph), std::sin(m * ph));  // weight folded into Y(u)
          Ur(row, n + m) = y.real();
          Ui(row, n + m) = y.imag();
          Ur(row, n - m) = y.real();
          Ui(row, n - m) = -y.imag();
        }
        H.regular(n, Q[0] * u[0] + Q[1] * u[1] + Q[2] * u[2], Q[3] * u[0] + Q[4] * u[1] + Q[5] * u[2],
                  Q[6] * u[0] + Q[7] * u[1] + Q[8] * u[2], R.data());
        for (int m = 0; m <= n; ++m) {
          const cplx y = H.c(n, m) * R[idx(n, m)];
          Vr(row, m) = y.real();
          Vi(row, m) = y.imag();
        }
      }
    }
    const Eigen::MatrixXd A = Vr.transpose() * Ur + Vi.transpose() * Ui;  // Re(conj(V)^T U): rows m' >= 0
    for (int mp = 0; mp <= n; ++mp)
      for (int m = -n; m <= n; ++m) {
        const double v = A(mp, m + n);
        r.a_[r.off_[n] + std::size_t(mp + n) * dim + (m + n)] = v;
        r.a_[r.off_[n] + std::size_t(-mp + n) * dim + (-m + n)] = v;
      }
  }
  r.real_ = true;
  r.roff_.resize(p + 2);
  r.roff_[0] = 0;
  for (int n = 0; n <= p; ++n) r.roff_[n + 1] = r.roff_[n] + std::size_t(n + 1) * (n + 1);
  const std::size_t total = r.roff_[p + 1];
  r.plus_.assign(total, 0.0);
  r.minus_.assign(total, 0.0);
  r.tplus_.assign(total, 0.0);
  r.tminus_.assign(total, 0.0);
  for (int n = 0; n <= p; ++n) {
    const std::size_t o = r.roff_[n];
    for (int a = 0; a <= n; ++a)
      for (int b = 0; b <= n; ++b) {
        // forward: row m' = a, column m = b
        const double f0 = r.entry(n, a, b).real(), f1 = r.entry(n, a, -b).real();
        r.plus_[o + a * (n + 1) + b] = b == 0 ? f0 : f0 + f1;
        r.minus_[o + a * (n + 1) + b] = b == 0 ? 0.0 : f0 - f1;
        // adjoint: row m = a, column m' = b: A_{b a} and A_{-b, a}
        const double g0 = r.entry(n, b, a).real(), g1 = r.entry(n, -b, a).real();
        r.tplus_[o + a * (n + 1) + b] = b == 0 ? g0 : g0 + g1;
        r.tminus_[o + a * (n + 1) + b] = b == 0 ? 0.0 : g0 - g1;
      }
  }
  return r;
}

void Rotation::apply(const cplx* in, cplx* out, int mmax_out) const noexcept {
  if (real_) {
    for (int n = 0; n <= p_; ++n) {
      const cplx* x = in + idx(n, 0);
      cplx* y = out + idx(n, 0);
      const int top = std::min(n, mmax_out - 1);
      const double* P = plus_.data() + roff_[n];
      const double* Mi = minus_.data() + roff_[n];
      for (int mp = 0; mp <= top; ++mp) {
        const double* pr = P + mp * (n + 1);
        const double* mr = Mi + mp * (n + 1);
        double re = 0.0, im = 0.0;
        for (int m = 0; m <= n; ++m) {
          re += pr[m] * x[m].real();
          im += mr[m] * x[m].imag();
        }
        y[mp] = cplx(re, im);
      }
      for (int mp = std::max(top + 1, 0); mp <= n; ++mp) y[mp] = 0.0;
    }
    return;
  }
  for (int n = 0; n <= p_; ++n) {
    const int dim = 2 * n + 1;
    const cplx* A = a_.data() + off_[n];
    const cplx* x = in + idx(n, 0);
    cplx* y = out + idx(n, 0);
    const int top = std::min(n, mmax_out - 1);
    for (int mp = 0; mp <= top; ++mp) {
      const cplx* row = A + std::size_t(mp + n) * dim + n;  // row[m] = A_{m' m}
      cplx acc = row[0] * x[0];
      for (int m = 1; m <= n; ++m) acc += row[m] * x[m] + row[-m] * std::conj(x[m]);
      y[mp] = acc;
    }
    for (int mp = std::max(top + 1, 0); mp <= n; ++mp) y[mp] = 0.0;
  }
}

void Rotation::apply_adjoint(const cplx* in, cplx* out, int mmax_in) const noexcept {
  if (real_) {
    for (int n = 0; n <= p_; ++n) {
      const cplx* x = in + idx(n, 0);
      cplx* y = out + idx(n, 0);
      const int top = std::min(n, mmax_in - 1);
      const double* P = tplus_.data() + roff_[n];
      const double* Mi = tminus_.data() + roff_[n];
      for (int m = 0; m <= n; ++m) {
        const double* pr = P + m * (n + 1);
        const double* mr = Mi + m * (n + 1);
        double re = 0.0, im = 0.0;
        for (int mp = 0; mp <= top; ++mp) {
          re += pr[mp] * x[mp].real();
          im += mr[mp] * x[mp].imag();
        }
        y[m] = cplx(re, im);
      }
    }
    return;
  }
  for (int n = 0; n <= p_; ++n) {
    const int dim = 2 * n + 1;
    const cplx* A = a_.data() + off_[n];
    const cplx* x = in + idx(n, 0);
    cplx* y = out + idx(n, 0);
    const int top = std::min(n, mmax_in - 1);
    for (int m = 0; m <= n; ++m) {
      // (A^H x)_m = sum_{m'} conj(A_{m' m}) x_{m'}, x_{-m'} = conj(x_{m'}).
      cplx acc = std::conj(A[std::size_t(n) * dim + (m + n)]) * x[0];
      for (int mp = 1; mp <= top; ++mp)
        acc += std::conj(A[std::size_t(mp + n) * dim + (m + n)]) * x[mp] +
               std::conj(A[std::size_t(n - mp) * dim + (m + n)]) * std::conj(x[mp]);
      y[m] = acc;
    }
  }
}

// Lane versions: the real kernels with the density index innermost (one vector of kLanes). A
// general (non-y) rotation has no real kernel; it goes through apply() lane by lane.
namespace {
// Per degree n: y_r = sum_{c < cols(n, r)} P[r (n+1) + c] x_c for the real parts (Mi for the
// imaginary parts), rows r <= n, all lanes at once.
template <class Cols>
[[gnu::always_inline]] inline void real_kernel_lanes(int p, const std::size_t* roff, const double* plus,
                                                     const double* minus, const double* xr, const double* xi,
                                                     double* yr, double* yi, Cols cols) noexcept {
  constexpr int D = Rotation::kLanes;
  for (int n = 0; n <= p; ++n) {
    const double* x_re = xr + std::size_t(idx(n, 0)) * D;
    const double* x_im = xi + std::size_t(idx(n, 0)) * D;
    for (int r = 0; r <= n; ++r) {
      const double* pr = plus + roff[n] + std::size_t(r) * (n + 1);
      const double* mr = minus + roff[n] + std::size_t(r) * (n + 1);
      double re[D] = {}, im[D] = {};
      const int nc = cols(n, r);
      for (int c = 0; c < nc; ++c)
#pragma omp simd
        for (int d = 0; d < D; ++d) {
          re[d] += pr[c] * x_re[c * D + d];
          im[d] += mr[c] * x_im[c * D + d];
        }
      for (int d = 0; d < D; ++d) {
        yr[std::size_t(idx(n, r)) * D + d] = re[d];
        yi[std::size_t(idx(n, r)) * D + d] = im[d];
      }
    }
  }
}
}  // namespace

void Rotation::apply_lanes(const double* xr, const double* xi, double* yr, double* yi, int mmax_out) const noexcept {
  simd_dispatch([=, this]() RPYFMM_SIMD_BODY {
    if (!real_) {
      generic_lanes(xr, xi, yr, yi, p_, [&](const cplx* in, cplx* out) { apply(in, out, mmax_out); });
      return;
    }
    // Row m' < mmax_out sums over all m <= n; the other rows are 0.
    real_kernel_lanes(p_, roff_.data(), plus_.data(), minus_.data(), xr, xi, yr, yi,
                      [&](int n, int mp) { return mp < mmax_out ? n + 1 : 0; });
  });
}

void Rotation::apply_adjoint_lanes(const double* xr, const double* xi, double* yr, double* yi,
                                   int mmax_in) const noexcept {
  simd_dispatch([=, this]() RPYFMM_SIMD_BODY {
    if (!real_) {
      generic_lanes(xr, xi, yr, yi, p_, [&](const cplx* in, cplx* out) { apply_adjoint(in, out, mmax_in); });
      return;
    }
    // Row m sums over the input orders m' <= min(n, mmax_in - 1).
    real_kernel_lanes(p_, roff_.data(), tplus_.data(), tminus_.data(), xr, xi, yr, yi,
                      [&](int n, int) { return std::min(n, mmax_in - 1) + 1; });
  });
}

void phase_rotate(int p, double phi0, cplx* coef) noexcept {
  const cplx e(std::cos(phi0), std::sin(phi0));
  cplx em = 1.0;
  for (int m = 1; m <= p; ++m) {
    em *= e;
    for (int n = m; n <= p; ++n) coef[idx(n, m)] *= em;
  }
}

}  // namespace rpyfmm::fmm::detail
