// rpyfmm — PSE real-space kernel of the rotational blocks (equal radii a; docs/theory/pse.md,
// "Rotation"). For a pair at d = x_i - x_j, r = |d|, e = d / r, the real-space part adds
//     U_i += (c / eta) (T_j x e),    W_i += (c / eta) (F_j x e) + (1 / eta) (h I + k e e^T) T_j,
// the same structure as the free-space grand mobility (rpy_rotation_kernel.hpp). Each coefficient
// is the free-space RPY coefficient (Wajnryb et al. 2013, exact in every overlap regime) minus the
// wave-space part in real space, the radial transform of the Hasimoto-split Fourier factor
//     c_w(r) = (1 / 4 pi^2) int sinc(ka) s(ka) H(k) k j1(kr) dk,
//     h_w(r) = (1 / 8 pi^2) int s(ka)^2 H(k) k^2 (j0(kr) - j1(kr) / kr) dk,
//     k_w(r) = (1 / 8 pi^2) int s(ka)^2 H(k) k^2 j2(kr) dk,
// with s(x) = 3 j1(x) / x (the sphere's rotational shape factor) and H(k, xi) of [PSE] eq. 11.
// H decays like a Gaussian, so the integrals are smooth and are evaluated by Gauss-Legendre
// quadrature; the differences decay like exp(-xi^2 r^2) and are cut at the translational r_cut.
// Exposed for tests; the operator uses PseRotationTable.
#pragma once

#include <cstddef>
#include <vector>

namespace rpyfmm::rpy::pse {

/// Coefficients of one pair times eta (see above), or of the self block (c = k = 0).
struct RotationCoefficients {
  double c;
  double h;
  double k;
};

/// The wave-space part (c_w, h_w, k_w) by quadrature on fixed nodes chosen for r <= r_max:
/// panels of 16 Gauss-Legendre points, narrow enough for the oscillation of j(kr) and of the shape
/// factors, up to the k where H < 1e-19.
class RotationWaveKernel {
 public:
  RotationWaveKernel(double xi, double a, double r_max);
  [[nodiscard]] RotationCoefficients operator()(double r) const;
  /// out[j] = (*this)(j * step) for j < count, with the sines and cosines of k r by the
  /// angle-addition recurrence from exact values every 64 steps (relative drift ~1e-14).
  void tabulate(double step, std::size_t count, RotationCoefficients* out) const;
  [[nodiscard]] std::size_t nodes() const { return k_.size(); }

 private:
  std::vector<double> k_;        // quadrature nodes
  std::vector<double> w_cross_;  // weight * sinc * s * H * k / (4 pi^2)
  std::vector<double> w_rot_;    // weight * s^2 * H * k^2 / (8 pi^2)
};

/// The real-space coefficients at r >= 0: free-space RPY minus RotationWaveKernel (self: r = 0).
/// Builds a quadrature for this one r: for tests; the operator tabulates (PseRotationTable).
RotationCoefficients rotation_real_space(double r, double xi, double a);

/// Linear table of the real-space coefficients on [0, r_cut], in units of 1 / (6 pi a^2) for c and
/// 1 / (6 pi a^3) for h and k (the translational M0 = 1 / (6 pi a) with the scaling of torques
/// by a): the spacing halves until every midpoint is within eps_t in those units.
class PseRotationTable {
 public:
  PseRotationTable() = default;
  PseRotationTable(double xi, double a, double r_cut, double eps_t);
  /// (c, h, k) times eta at r in [0, r_cut).
  [[nodiscard]] RotationCoefficients operator()(double r) const {
    double t = r * inv_dr_;
    auto j = static_cast<std::size_t>(t);
    t -= static_cast<double>(j);
    const double* e = &data_[3 * j];
    return {unit_c_ * (e[0] + t * (e[3] - e[0])), unit_hk_ * (e[1] + t * (e[4] - e[1])),
            unit_hk_ * (e[2] + t * (e[5] - e[2]))};
  }
  /// h at r = 0 (the self block) times eta.
  [[nodiscard]] double self() const { return unit_hk_ * data_[1]; }
  [[nodiscard]] double dr() const { return dr_; }
  [[nodiscard]] std::size_t size() const { return data_.size() / 3 - 1; }
  /// The nodes' (c, h, k), dimensionless, three per node (size() + 1 nodes), 1 / dr() and the
  /// units of c and of h, k: for row kernels that interpolate several pairs at once.
  [[nodiscard]] const double* data() const { return data_.data(); }
  [[nodiscard]] double inv_dr() const { return inv_dr_; }
  [[nodiscard]] double unit_c() const { return unit_c_; }
  [[nodiscard]] double unit_hk() const { return unit_hk_; }

 private:
  double dr_ = 0.0;
  double inv_dr_ = 0.0;
  double unit_c_ = 0.0;
  double unit_hk_ = 0.0;
  std::vector<double> data_;  // (c, h, k) at the nodes 0 ... size(), dimensionless
};

}  // namespace rpyfmm::rpy::pse
