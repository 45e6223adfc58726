// Measures the window-truncation error of the PSE wave-space part, the constant behind
// PseOptions' choice of the window half-width m (docs/theory/pse.md): for several xi a and
// tolerances, the product M_w F with the support P chosen by the parameters and with P - 1 ...
// P + 3, on the same grid, against the same grid with a 26-point window, relative to |M F|;
// next to it the model 1.5 erfc(m_eff / sqrt 2) of docs/theory/pse.md, m_eff = P h / (2 sigma).
//
// usage: window_truncation [N]   (default 2000 random points at volume fraction 0.1, a = 1)
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>
#include <vector>

#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/random.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

int main(int argc, char** argv) {
  const std::size_t n = argc > 1 ? static_cast<std::size_t>(std::atoll(argv[1])) : 2000;
  if (n < 2) {
    std::fprintf(stderr, "window_truncation: N must be an integer >= 2\n");
    return 2;
  }
  const double L = std::cbrt(static_cast<double>(n) * 4.0 / 3.0 * std::numbers::pi / 0.1);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> uniform(0.0, L);
  std::vector<double> x(3 * n), f(3 * n), u(3 * n), converged(3 * n), v(3 * n);
  for (double& q : x) q = uniform(rng);
  fill_normal(f, 1, 0);
  std::printf("xi_a,tolerance,grid,P,chosen,m_eff,trunc_error_over_tol,model_1.5erfc_over_tol,measured_over_erfc\n");
  for (double xi : {0.3, 0.45, 0.8, 1.5}) {
    for (double tol : {1e-2, 1e-3, 1e-5}) {
      PseOptions o;
      o.tolerance = tol;
      o.xi = xi;
      PseRpy base(Geometry::periodic(L), 1.0, o);
      base.set_positions(x, 1.0);
      const PseParameters p = base.parameters();
      base.apply(f, u);
      double norm = 0.0;
      for (double q : u) norm += q * q;
      PseOptions oc = o;
      oc.window_eta = p.window_eta;
      oc.grid = p.grid;
      oc.support = std::min(p.grid[0], 26);
      PseRpy reference(Geometry::periodic(L), 1.0, oc);
      reference.set_positions(x, 1.0);
      reference.apply_wave(f, converged);
      for (int P = p.support[0] - 1; P <= p.support[0] + 3; ++P) {
        PseOptions ot = oc;
        ot.support = P;
        PseRpy t(Geometry::periodic(L), 1.0, ot);
        t.set_positions(x, 1.0);
        t.apply_wave(f, v);
        double err = 0.0;
        for (std::size_t i = 0; i < v.size(); ++i) err += (v[i] - converged[i]) * (v[i] - converged[i]);
        err = std::sqrt(err / norm);
        const double m_eff = P * p.spacing[0] / (2.0 * p.sigma);
        const double erfc = std::erfc(m_eff / std::numbers::sqrt2);
        std::printf("%.2f,%.0e,%d,%d,%d,%.3f,%.4g,%.4g,%.3g\n", xi, tol, p.grid[0], P, P == p.support[0] ? 1 : 0, m_eff,
                    err / tol, 1.5 * erfc / tol, err / erfc);
      }
    }
  }
}
