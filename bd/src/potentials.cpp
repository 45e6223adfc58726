#include "rpyfmm/bd/potentials.hpp"

#include <cmath>
#include <numbers>

#include "device/pair_potentials.hpp"
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
      // Tran et al. (2015) eq. 11: pi eps a_i a_j / (a_i + a_j) (Psi_i^2 + Psi_j^2),
      // ratio 2 Psi_i Psi_j / (Psi_i^2 + Psi_j^2)
      t.el_prefactor = std::numbers::pi * p.permittivity * ai * aj / (ai + aj) * sum2;
      t.el_ratio = sum2 > 0.0 ? 2.0 * psi_i * psi_j / sum2 : 0.0;
      if (p.core == DlvoCore::born) {
        require(std::isfinite(p.born_sigma) && p.born_sigma >= 0.0, ErrorCode::invalid_argument, where,
                "born_sigma must be finite and >= 0");
        // Default sigma_B = 0.8 / kappa: the primary minimum stays wide enough for the time step of
        // Tran et al. (2015) (docs/theory/bd.md Sec. 4, DLVO with a Born core).
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

// The formulas are the device stages' (device/pair_potentials.hpp), compiled here with this
// file's flags: one implementation for the CPU engine and the device engines.

EnergyForce evaluate_pair(const PairTerm& t, double r) {
  return device::pair_energy_force(t, r);
}

EnergyForce born_repulsion(double prefactor, double ai, double aj, double r) {
  return device::born_energy_force(prefactor, ai, aj, r);
}

EnergyForce evaluate_bond(const BondPotential& b, double r) {
  return device::bond_energy_force(b, r);
}

}  // namespace rpyfmm::bd
