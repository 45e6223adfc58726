// rpyfmm — PSE real-space kernel F(r, xi), G(r, xi): [PSE] Appendix A
// (eqs. A1-A4) in the form of docs/theory/pse.md, with its small-r series, envelope cutoff and
// linear table.
#include "rpyfmm/rpy/pse/real_space.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "rpyfmm/core/validate.hpp"
#include "table_refinement.hpp"

namespace rpyfmm::rpy::pse {

namespace {

constexpr double kSqrtPi = 1.7724538509055160273;

/// Closed forms of [PSE] App. A (eqs. A1-A3), r > 0; f0, g0 switch at r = 2a.
/// T = long double near r = 0, where the terms cancel (docs/theory/pse.md).
template <class T>
FG closed_form(T r, T xi, T a) {
  const T xi2 = xi * xi;
  const T xi3 = xi2 * xi;
  const T xi4 = xi2 * xi2;
  const T r2 = r * r;
  const T r3 = r2 * r;
  const T rm = r - T(2.0) * a;
  const T rp = r + T(2.0) * a;
  const T E0 = std::exp(-xi2 * r2);
  const T Em = std::exp(-xi2 * rm * rm);
  const T Ep = std::exp(-xi2 * rp * rp);
  const T C0 = std::erfc(xi * r);
  const T Cm = std::erfc(xi * rm);
  const T Cp = std::erfc(xi * rp);
  const T pm = T(4.0) * a * a + T(4.0) * a * r + T(9.0) * r2;
  const T pp = T(4.0) * a * a - T(4.0) * a * r + T(9.0) * r2;
  const T ds = T(1.772453850905516027298167483341145183L) * a * xi3;  // sqrt(pi) a xi^3
  const T d4 = a * xi4;                                               // a xi^4

  const T f1 = (T(18.0) * xi2 * r2 + T(3.0)) / (T(64.0) * ds * r2);
  const T f2 = (T(2.0) * xi2 * (T(2.0) * a - r) * pm - T(2.0) * a - T(3.0) * r) / (T(128.0) * ds * r3);
  const T f3 = (-T(2.0) * xi2 * (T(2.0) * a + r) * pp + T(2.0) * a - T(3.0) * r) / (T(128.0) * ds * r3);
  const T f4 = (T(3.0) - T(36.0) * xi4 * r2 * r2) / (T(128.0) * d4 * r3);
  const T f5 = (T(4.0) * xi4 * rm * rm * pm - T(3.0)) / (T(256.0) * d4 * r3);
  const T f6 = (T(4.0) * xi4 * rp * rp * pp - T(3.0)) / (T(256.0) * d4 * r3);

  const T g1 = (T(6.0) * xi2 * r2 - T(3.0)) / (T(32.0) * ds * r2);
  const T g2 = (-T(2.0) * xi2 * rm * rm * (T(2.0) * a + T(3.0) * r) + T(2.0) * a + T(3.0) * r) / (T(64.0) * ds * r3);
  const T g3 = (T(2.0) * xi2 * rp * rp * (T(2.0) * a - T(3.0) * r) - T(2.0) * a + T(3.0) * r) / (T(64.0) * ds * r3);
  const T g4 = -T(3.0) * (T(4.0) * xi4 * r2 * r2 + T(1.0)) / (T(64.0) * d4 * r3);
  const T g5 =
      (T(3.0) - T(4.0) * xi4 * (T(2.0) * a - r) * (T(2.0) * a - r) * (T(2.0) * a - r) * (T(2.0) * a + T(3.0) * r)) /
      (T(128.0) * d4 * r3);
  const T g6 = (T(3.0) - T(4.0) * xi4 * (T(2.0) * a - T(3.0) * r) * rp * rp * rp) / (T(128.0) * d4 * r3);

  T f0 = 0;
  T g0 = 0;
  if (r <= T(2.0) * a) {  // overlap correction: exactly (overlapping RPY) - (far RPY)
    f0 = -rm * rm * pm / (T(32.0) * a * r3);
    g0 = (T(2.0) * a - r) * (T(2.0) * a - r) * (T(2.0) * a - r) * (T(2.0) * a + T(3.0) * r) / (T(16.0) * a * r3);
  }
  return {static_cast<double>(f0 + f1 * E0 + f2 * Em + f3 * Ep + f4 * C0 + f5 * Cm + f6 * Cp),
          static_cast<double>(g0 + g1 * E0 + g2 * Em + g3 * Ep + g4 * C0 + g5 * Cm + g6 * Cp)};
}

}  // namespace

double real_space_self(double xi, double a) {
  // [PSE] eq. A4, with -expm1 for accuracy at small xi a.
  return std::erfc(2.0 * a * xi) - std::expm1(-4.0 * a * a * xi * xi) / (4.0 * kSqrtPi * a * xi);
}

FG real_space_fg(double r, double xi, double a) {
  // The closed form cancels catastrophically as r -> 0 (absolute error ~3 u / (128 a xi^4 r^3)
  // for unit round-off u, docs/theory/pse.md). Below r_s the series (remainder O(r^4)); up to
  // 0.5 a the closed form in long double (u ~ 1e-19); beyond, double. Errors <~ 1e-11.
  const double rs = std::clamp(0.001 / xi, 0.0004 * a, 0.02 * a);
  if (r < rs) {
    const double F0 = real_space_self(xi, a);
    const double E = std::exp(-4.0 * a * a * xi * xi);
    const double cF = 2.0 / (5.0 * kSqrtPi * a) * (0.75 * xi * (1.0 - E) + 2.0 * a * a * xi * xi * xi * E);
    return {F0 - 9.0 * r / (32.0 * a) + cF * r * r, F0 - 3.0 * r / (16.0 * a) + 0.5 * cF * r * r};
  }
  if (r < 0.5 * a) return closed_form<long double>(r, xi, a);
  return closed_form<double>(r, xi, a);
}

double real_space_cutoff(double eps_r, double xi, double a) {
  require_positive(eps_r, "pse::real_space_cutoff", "eps_r");
  require_positive(xi, "pse::real_space_cutoff", "xi");
  require_positive(a, "pse::real_space_cutoff", "radius");
  // r_c = smallest r with max(|F|, |G|) <= eps_r on [r, r + 4/xi] (docs/theory/pse.md):
  // sample from r0 outward in steps of 0.01/xi and return the sample after the
  // last one that exceeds eps_r (far beyond 2a + sqrt(ln(1/eps_r))/xi all are below).
  const double step = 0.01 / xi;
  const double r0 = 0.5 * std::sqrt(std::log(1.0 / eps_r)) / xi;
  const double r_end = std::max(r0, 2.0 * a) + (std::sqrt(std::log(1.0 / eps_r)) + 6.0) / xi;
  // About 100 (2 xi a + 6) samples: a huge xi (xi a = 1e300) would need more than the loop can
  // count, its step vanishing next to r, so it is refused here instead of looping without end.
  constexpr double kMaxSamples = 1e7;
  require((r_end - r0) / step <= kMaxSamples, ErrorCode::invalid_argument, "pse::real_space_cutoff",
          "xi = " + format_number(xi) + " (xi a = " + format_number(xi * a) +
              ") is too large: the real-space cutoff would need more than 1e7 samples (xi a of order 1 is meant; "
              "the automatic choice scans [0.2, 8])");
  double last_bad = -1.0;
  for (double r = r0; r <= r_end; r += step) {
    const FG v = real_space_fg(r, xi, a);
    if (std::max(std::abs(v.f), std::abs(v.g)) > eps_r) last_bad = r;
  }
  return last_bad < 0.0 ? r0 : last_bad + step;
}

PseRealSpaceTable::PseRealSpaceTable(double xi, double a, double r_cut, double eps_t) {
  const char* where = "PseRealSpaceTable";
  require_positive(xi, where, "xi");
  require_positive(a, where, "radius");
  require_positive(r_cut, where, "r_cut");
  require_positive(eps_t, where, "table tolerance");
  // Linear interpolation error <= dr^2 max|F''| / 8 with max|F''| <~ 0.7 / a^2
  // (docs/theory/pse.md); start there and halve dr until every midpoint is within eps_t.
  const double dr0 = std::min(std::sqrt(8.0 * eps_t / 0.7) * a, r_cut / 16.0);
  const detail::RefinedTable t = detail::refine_linear_table(
      dr0, r_cut, eps_t, 2, std::size_t{1} << 24, where, "2^24", [&](double dr, std::size_t n) {
        std::vector<double> v(2 * (2 * n + 1));
        for (std::size_t j = 0; j <= 2 * n; ++j) {
          const FG fg = real_space_fg(static_cast<double>(j) * (0.5 * dr), xi, a);
          v[2 * j] = fg.f;
          v[2 * j + 1] = fg.g;
        }
        return v;
      });
  dr_ = t.dr;
  inv_dr_ = 1.0 / t.dr;
  // Per cell j its two nodes (f_j, g_j, f_j+1, g_j+1): one load per lookup.
  const std::size_t cells = t.nodes - 1;
  data_.resize(4 * cells);
  for (std::size_t j = 0; j < cells; ++j) std::copy_n(&t.values[2 * j], 4, &data_[4 * j]);
}

}  // namespace rpyfmm::rpy::pse
