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

const char* to_string(DlvoCore core) {
  return core == DlvoCore::born ? "born" : "none";
}

DlvoCore dlvo_core_from_string(const std::string& name) {
  for (auto c : {DlvoCore::none, DlvoCore::born})
    if (name == to_string(c)) return c;
  fail(ErrorCode::invalid_argument, "pair potential dlvo", "unknown core '" + name + "' (expected none or born)");
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
      if (p.core == DlvoCore::born) {
        require(std::isfinite(p.born_sigma) && p.born_sigma >= 0.0, ErrorCode::invalid_argument, where,
                "born_sigma must be finite and >= 0");
        // Default sigma_B = 0.8 / kappa: the primary minimum stays wide enough for the GPU BD
        // paper's time step (docs/theory/bd.md Sec. 4, DLVO with a Born core).
        const double sigma_b = p.born_sigma > 0.0 ? p.born_sigma : 0.8 / p.kappa;
        const double s3 = sigma_b * sigma_b * sigma_b;
        t.born_prefactor = p.hamaker * s3 * s3 / 37800.0;
      }
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
      const EnergyForce born = t.born_prefactor > 0.0 ? born_repulsion(t.born_prefactor, ai, aj, r) : EnergyForce{0, 0};
      return {v_vdw + v_el + born.energy, -(dv_vdw + dv_el) / r + born.s};
    }
  }
  return {0.0, 0.0};
}

EnergyForce born_repulsion(double prefactor, double ai, double aj, double r) {
  // Feke et al. (1984): V = K/r sum_k c_k (r^2 - 7 b_k r + e_k) / (r - b_k)^7 over the four
  // poles b = +-(a_i + a_j) (sign +1, e = 6 (a_i^2 + 7 a_i a_j + a_j^2)) and b = +-(a_i - a_j)
  // (sign -1, e = 6 (a_i^2 - 7 a_i a_j + a_j^2)); near contact V -> K 30 a_i a_j / ((a_i + a_j) h^7).
  const double s = ai + aj, d = ai - aj;
  const double e_sum = 6.0 * (ai * ai + 7.0 * ai * aj + aj * aj);
  const double e_diff = 6.0 * (ai * ai - 7.0 * ai * aj + aj * aj);
  const struct {
    double b, e, sign;
  } poles[4] = {{s, e_sum, 1.0}, {-s, e_sum, 1.0}, {-d, e_diff, -1.0}, {d, e_diff, -1.0}};
  double sum = 0.0, dsum = 0.0;  // S(r) and S'(r)
  for (const auto& p : poles) {
    const double x = r - p.b;
    const double x2 = x * x, x7 = x2 * x2 * x2 * x;
    const double num = r * r - 7.0 * p.b * r + p.e;
    sum += p.sign * num / x7;
    dsum += p.sign * ((2.0 * r - 7.0 * p.b) / x7 - 7.0 * num / (x7 * x));
  }
  const double energy = prefactor * sum / r;
  const double dv = prefactor * (dsum / r - sum / (r * r));
  return {energy, -dv / r};
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
