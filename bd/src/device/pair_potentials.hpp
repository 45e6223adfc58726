// rpyfmm::bd::device — the pair and bond potentials, one implementation for both engines: the
// energy V(r) and s = -V'(r)/r (force on i: s (x_i - x_j)), from the parameters resolve_pair
// gives (PairTerm) and the bond potentials (BondPotential). The CPU engine's evaluate_pair,
// born_repulsion and evaluate_bond (bd/src/potentials.cpp) call these functions; the device
// stages (particle_force.hpp) call them in a kernel and in the host launcher. On the device
// only the logarithms and exponentials (DLVO, FENE) differ, by about an ulp, from the host's
// libm (docs/gpu-bd.md, bounds).
//
//   lj36_18  4 eps [(s/r)^36 - (s/r)^18]     (Tran et al. (2015), Annex 1, eq. 8)
//   wca      4 eps [(s/r)^12 - (s/r)^6] + eps
//   soft     eps (1 - r/s)^2
//   dlvo     van der Waals + electrostatic (Tran et al. (2015), Annex 2, eqs. 10-11), plus the
//            Born core of Feke, Prabhu, Mann & Mann (1984) when set (docs/theory/bd.md Sec. 4)
//   harmonic k/2 (r - r0)^2;  fene -k R0^2/2 ln(1 - (r/R0)^2)
//
// Internal linkage (static): each translation unit compiles its own copy under its own
// floating-point flags (potentials.cpp as the CPU engine always has been, host_engine.cpp with
// -ffp-contract=off, bd/bd.cmake), so that on a target with FMA the linker cannot substitute
// one unit's copy for the other's.
#pragma once

#include <math.h>  // ::exp, ::log: CUDA builtins in device code too

#include "rpyfmm/bd/potentials.hpp"
#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::bd::device {

/// Born repulsion between spheres of radii ai, aj at centre distance r (potentials.hpp,
/// born_repulsion): the four poles b = +-(ai + aj), +-(ai - aj) of Feke et al. (1984).
RPYFMM_HOST_DEVICE static inline EnergyForce born_energy_force(double prefactor, double ai, double aj, double r) {
  const double s = ai + aj, d = ai - aj;
  const double e_sum = 6.0 * (ai * ai + 7.0 * ai * aj + aj * aj);
  const double e_diff = 6.0 * (ai * ai - 7.0 * ai * aj + aj * aj);
  const double pole_b[4] = {s, -s, -d, d};
  const double pole_e[4] = {e_sum, e_sum, e_diff, e_diff};
  const double pole_sign[4] = {1.0, 1.0, -1.0, -1.0};
  double sum = 0.0, dsum = 0.0;  // S(r) and S'(r)
  for (int p = 0; p < 4; ++p) {
    const double x = r - pole_b[p];
    const double x2 = x * x, x7 = x2 * x2 * x2 * x;
    const double num = r * r - 7.0 * pole_b[p] * r + pole_e[p];
    sum += pole_sign[p] * num / x7;
    dsum += pole_sign[p] * ((2.0 * r - 7.0 * pole_b[p]) / x7 - 7.0 * num / (x7 * x));
  }
  const double energy = prefactor * sum / r;
  const double dv = prefactor * (dsum / r - sum / (r * r));
  return {energy, -dv / r};
}

/// DLVO: van der Waals (eq. 10, s = a_i + a_j, d = a_i - a_j) and electrostatic (eq. 11,
/// h = r - a_i - a_j) terms, plus the Born core when t.born_prefactor > 0.
RPYFMM_HOST_DEVICE static inline EnergyForce dlvo_energy_force(const PairTerm& t, double r) {
  const double ai = t.ai, aj = t.aj;
  const double r2 = r * r;
  const double ps = r2 - (ai + aj) * (ai + aj);
  const double pd = r2 - (ai - aj) * (ai - aj);
  const double c = 2.0 * ai * aj;
  const double v_vdw = -t.hamaker / 6.0 * (c / ps + c / pd + ::log(ps / pd));
  const double dv_vdw =
      -t.hamaker / 6.0 * (-2.0 * c * r / (ps * ps) - 2.0 * c * r / (pd * pd) + 2.0 * r / ps - 2.0 * r / pd);
  const double h = r - ai - aj;
  const double e = ::exp(-t.kappa * h);
  const double one_m_e2 = 1.0 - e * e;
  const double v_el = t.el_prefactor * (t.el_ratio * ::log((1.0 + e) / (1.0 - e)) + ::log(one_m_e2));
  const double dv_el =
      t.el_prefactor * (t.el_ratio * (-2.0 * t.kappa * e / one_m_e2) + 2.0 * t.kappa * e * e / one_m_e2);
  const EnergyForce born = t.born_prefactor > 0.0 ? born_energy_force(t.born_prefactor, ai, aj, r) : EnergyForce{0, 0};
  return {v_vdw + v_el + born.energy, -(dv_vdw + dv_el) / r + born.s};
}

/// V and -V'/r of pair term t at 0 < r < t.cutoff (evaluate_pair).
RPYFMM_HOST_DEVICE static inline EnergyForce pair_energy_force(const PairTerm& t, double r) {
  switch (t.kind) {
    case PairKind::lj36_18: {
      const double x2 = (t.sigma / r) * (t.sigma / r);
      const double x6 = x2 * x2 * x2;
      const double x18 = x6 * x6 * x6;
      const double x36 = x18 * x18;
      return {4.0 * t.epsilon * (x36 - x18), 4.0 * t.epsilon * (36.0 * x36 - 18.0 * x18) / (r * r)};
    }
    case PairKind::wca: {
      const double x2 = (t.sigma / r) * (t.sigma / r);
      const double x6 = x2 * x2 * x2;
      const double x12 = x6 * x6;
      return {4.0 * t.epsilon * (x12 - x6) + t.epsilon, 4.0 * t.epsilon * (12.0 * x12 - 6.0 * x6) / (r * r)};
    }
    case PairKind::soft: {
      const double u = 1.0 - r / t.sigma;
      return {t.epsilon * u * u, 2.0 * t.epsilon * u / (t.sigma * r)};
    }
    case PairKind::dlvo:
      return dlvo_energy_force(t, r);
  }
  return {0.0, 0.0};
}

/// V and -V'/r of a bond at r > 0 (fene: r < R0; evaluate_bond).
RPYFMM_HOST_DEVICE static inline EnergyForce bond_energy_force(const BondPotential& b, double r) {
  if (b.kind == BondKind::harmonic) {
    const double d = r - b.length;
    return {0.5 * b.k * d * d, -b.k * d / r};
  }
  const double q = 1.0 - (r / b.length) * (r / b.length);
  return {-0.5 * b.k * b.length * b.length * ::log(q), -b.k / q};
}

}  // namespace rpyfmm::bd::device
