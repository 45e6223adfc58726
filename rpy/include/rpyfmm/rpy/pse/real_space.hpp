// rpyfmm — PSE real-space kernel: the closed forms F(r, xi), G(r, xi) of
// [PSE] Appendix A (eqs. A1-A4), in units of M0 = 1/(6 pi eta a):
//   M_r,ij = M0 [ F(r) (I - rhat rhat) + G(r) rhat rhat ],   M_r,ii = M0 F(0) I.
// Exposed for tests and benchmarks; the operator uses PseRealSpaceTable.
#pragma once

#include <cstddef>
#include <vector>

namespace rpyfmm::rpy::pse {

/// F and G of [PSE] App. A at distance r >= 0 (both branches r > 2a and r <= 2a;
/// series below r_s = 0.01/xi, clamped to [0.004 a, 0.2 a]; docs/theory/pse.md).
struct FG {
  double f;
  double g;
};
FG real_space_fg(double r, double xi, double a);

/// Self term F(0) = G(0) = erfc(2 a xi) - expm1(-4 a^2 xi^2) / (4 sqrt(pi) a xi)  ([PSE] eq. A4).
double real_space_self(double xi, double a);

/// Smallest r such that max(|F|, |G|) <= eps_r on [r, r + 4/xi] (docs/theory/pse.md).
double real_space_cutoff(double eps_r, double xi, double a);

/// Linear table of F, G in r on [0, r_cut] (docs/theory/pse.md): spacing halved
/// until the error at every midpoint is below eps_t.
class PseRealSpaceTable {
 public:
  PseRealSpaceTable() = default;
  PseRealSpaceTable(double xi, double a, double r_cut, double eps_t);
  /// (F, G) at r in [0, r_cut).
  [[nodiscard]] FG operator()(double r) const {
    double t = r * inv_dr_;
    auto j = static_cast<std::size_t>(t);
    t -= static_cast<double>(j);
    const double* e = &data_[4 * j];
    return {e[0] + t * (e[2] - e[0]), e[1] + t * (e[3] - e[1])};
  }
  [[nodiscard]] double dr() const { return dr_; }
  [[nodiscard]] std::size_t size() const { return data_.size() / 4; }
  /// Per cell j: (F_j, G_j, F_{j+1}, G_{j+1}).
  [[nodiscard]] const std::vector<double>& data() const { return data_; }

 private:
  double dr_ = 0.0;
  double inv_dr_ = 0.0;
  std::vector<double> data_;
};

}  // namespace rpyfmm::rpy::pse
