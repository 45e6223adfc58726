#include "rpyfmm/bd/potentials.hpp"

#include <cmath>
#include <numbers>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

const char* to_string(PairKind kind) {
  switch (kind) {
    case PairKind::lj36_18:
      return "lj36_18";
    case PairKind::wca:
      return "wca";
    case PairKind::soft:
      return "soft";
    case PairKind::dlvo:
      return "dlvo";
  }
  return "unknown";
}

PairKind pair_kind_from_string(const std::string& name) {
  for (auto k : {PairKind::lj36_18, PairKind::wca, PairKind::soft, PairKind::dlvo})
    if (name == to_string(k)) return k;
  fail(ErrorCode::invalid_argument, "pair potential",
       "unknown kind '" + name + "' (expected lj36_18, wca, soft or dlvo)");
}

const char* to_string(BondKind kind) {
  return kind == BondKind::harmonic ? "harmonic" : "fene";
}

BondKind bond_kind_from_string(const std::string& name) {
  if (name == "harmonic") return BondKind::harmonic;
  if (name == "fene") return BondKind::fene;
  fail(ErrorCode::invalid_argument, "bond", "unknown kind '" + name + "' (expected harmonic or fene)");
}

PairTerm resolve_pair(const PairPotential& p, double ai, double aj, double psi_i, double psi_j) {
  const std::string where = std::string("pair potential ") + to_string(p.kind);
  require(std::isfinite(p.sigma) && p.sigma >= 0.0, ErrorCode::invalid_argument, where, "sigma must be >= 0");
  require(std::isfinite(p.cutoff) && p.cutoff >= 0.0, ErrorCode::invalid_argument, where, "cutoff must be >= 0");
  require_in_range(p.min_distance_fraction, 1e-6, 1.0, where, "min_distance_fraction");
  PairTerm t;
  t.kind = p.kind;
  t.active = true;
  t.ai = ai;
  t.aj = aj;
  t.sigma = p.sigma > 0.0 ? p.sigma : ai + aj;
  t.epsilon = p.epsilon;
  switch (p.kind) {
    case PairKind::lj36_18:
      require_positive(p.epsilon, where, "epsilon");
      t.cutoff = p.cutoff > 0.0 ? p.cutoff : 1.5 * t.sigma;
      break;
    case PairKind::wca:
      require_positive(p.epsilon, where, "epsilon");
      t.cutoff = std::pow(2.0, 1.0 / 6.0) * t.sigma;  // WCA is defined by this cutoff
      break;
    case PairKind::soft:
      require_positive(p.epsilon, where, "epsilon");
      t.cutoff = t.sigma;
      break;
    case PairKind::dlvo: {
      require_positive(p.kappa, where, "kappa");
      require(std::isfinite(p.hamaker) && p.hamaker >= 0.0, ErrorCode::invalid_argument, where,
              "hamaker must be finite and >= 0");
      require(std::isfinite(p.permittivity) && p.permittivity >= 0.0, ErrorCode::invalid_argument, where,
              "permittivity must be finite and >= 0");
      t.sigma = ai + aj;
      t.cutoff = p.cutoff > 0.0 ? p.cutoff : ai + aj + 10.0 / p.kappa;
      t.hamaker = p.hamaker;
      t.kappa = p.kappa;
      const double sum2 = psi_i * psi_i + psi_j * psi_j;
      // GPU BD paper eq. 11: pi eps a_i a_j / (a_i + a_j) (Psi_i^2 + Psi_j^2),
      // ratio 2 Psi_i Psi_j / (Psi_i^2 + Psi_j^2)
      t.el_prefactor = std::numbers::pi * p.permittivity * ai * aj / (ai + aj) * sum2;
      t.el_ratio = sum2 > 0.0 ? 2.0 * psi_i * psi_j / sum2 : 0.0;
      break;
    }
  }
  t.min_distance = p.min_distance_fraction * t.sigma;
  if (!is_hard(p.kind)) t.min_distance = 0.0;
  require(t.cutoff > t.min_distance, ErrorCode::invalid_argument, where, "cutoff must exceed the minimum distance");
  return t;
}

EnergyForce evaluate_pair(const PairTerm& t, double r) {
  switch (t.kind) {
    case PairKind::lj36_18: {  // GPU BD paper (Eurographics 2015) eq. 8
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
    case PairKind::dlvo: {
      // van der Waals, GPU BD paper eq. 10, with s = a_i + a_j, d = a_i - a_j.
      const double ai = t.ai, aj = t.aj;
      const double r2 = r * r;
      const double ps = r2 - (ai + aj) * (ai + aj);
      const double pd = r2 - (ai - aj) * (ai - aj);
      const double c = 2.0 * ai * aj;
      const double v_vdw = -t.hamaker / 6.0 * (c / ps + c / pd + std::log(ps / pd));
      const double dv_vdw =
          -t.hamaker / 6.0 * (-2.0 * c * r / (ps * ps) - 2.0 * c * r / (pd * pd) + 2.0 * r / ps - 2.0 * r / pd);
      // electrostatic, GPU BD paper eq. 11, h = r - a_i - a_j, e = exp(-kappa h).
      const double h = r - ai - aj;
      const double e = std::exp(-t.kappa * h);
      const double one_m_e2 = 1.0 - e * e;
      const double v_el = t.el_prefactor * (t.el_ratio * std::log((1.0 + e) / (1.0 - e)) + std::log(one_m_e2));
      const double dv_el =
          t.el_prefactor * (t.el_ratio * (-2.0 * t.kappa * e / one_m_e2) + 2.0 * t.kappa * e * e / one_m_e2);
      return {v_vdw + v_el, -(dv_vdw + dv_el) / r};
    }
  }
  return {0.0, 0.0};
}

EnergyForce evaluate_bond(const BondPotential& b, double r) {
  if (b.kind == BondKind::harmonic) {
    const double d = r - b.length;
    return {0.5 * b.k * d * d, -b.k * d / r};
  }
  const double q = 1.0 - (r / b.length) * (r / b.length);
  return {-0.5 * b.k * b.length * b.length * std::log(q), -b.k / q};
}

}  // namespace rpyfmm::bd
