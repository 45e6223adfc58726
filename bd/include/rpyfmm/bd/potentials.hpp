// rpyfmm::bd — pair and bond potentials: the formulas, one function each.
//
// Every function returns the energy V(r) and the scalar s = -V'(r) / r, so that
// the force on i from j is F_i = s (x_i - x_j). Energies are in the caller's
// units (commonly kT = 1).
#pragma once

#include <cmath>
#include <string>

namespace rpyfmm::bd {

enum class PairKind {
  lj36_18,  ///< generalized Lennard-Jones 4 eps [(s/r)^36 - (s/r)^18], r < r_c (Tran et al. (2015), Annex 1, eq. 8);
            ///< hard
  wca,      ///< Weeks-Chandler-Andersen: LJ 12-6 shifted by +eps, cut at 2^(1/6) s; hard
  soft,     ///< soft repulsion eps (1 - r/s)^2 for r < s (finite at overlap; for relaxing overlaps)
  dlvo,     ///< DLVO van der Waals + electrostatic (Tran et al. (2015), Annex 2, eqs. 9-11); hard (needs h > 0)
};

/// Short-range repulsion added to a DLVO pair (docs/theory/bd.md Sec. 4, DLVO with a Born core).
enum class DlvoCore {
  none,  ///< the Annex's eqs. 9-11 only: the van der Waals term diverges to -inf at contact
  born,  ///< Born repulsion between two spheres (Feke, Prabhu, Mann & Mann 1984)
};

const char* to_string(PairKind kind);
PairKind pair_kind_from_string(const std::string& name);  // throws naming the value
const char* to_string(DlvoCore core);
DlvoCore dlvo_core_from_string(const std::string& name);  // throws naming the value

/// True for potentials that diverge at overlap (used for the overlap check).
inline bool is_hard(PairKind kind) {
  return kind != PairKind::soft;
}

/// Parameters of one pair interaction between two particle types.
struct PairPotential {
  PairKind kind = PairKind::wca;
  /// Energy scale eps (lj36_18: Tran et al. (2015) use eps = 14 kT; wca, soft). Not used by dlvo.
  double epsilon = 1.0;
  /// Length scale s; 0 = contact distance a_i + a_j (Tran et al. (2015): s = d_A, the diameter).
  double sigma = 0.0;
  /// Cutoff r_c; 0 = default: lj36_18 1.5 s, wca 2^(1/6) s, soft s, dlvo a_i + a_j + 10/kappa.
  double cutoff = 0.0;
  /// Hard potentials reject pairs closer than this fraction of s (dlvo: of a_i + a_j)
  /// as overlapping particles, instead of blowing up. In (0, 1].
  double min_distance_fraction = 0.8;
  // DLVO (Tran et al. (2015), Annex 2): Hamaker constant A_ij, solvent permittivity eps_r eps_0,
  // inverse Debye length kappa. Surface potentials Psi come from the particle types.
  double hamaker = 0.0;
  double permittivity = 0.0;
  double kappa = 0.0;
  /// Short-range repulsion of a DLVO pair, and the Born collision diameter sigma_B
  /// (0 = default 0.8 / kappa, docs/theory/bd.md Sec. 4).
  DlvoCore core = DlvoCore::none;
  double born_sigma = 0.0;
};

/// One pair's resolved parameters (radii and defaults applied) for fast evaluation.
struct PairTerm {
  PairKind kind = PairKind::wca;
  bool active = false;
  double epsilon = 0.0, sigma = 0.0, cutoff = 0.0, min_distance = 0.0;
  double ai = 0.0, aj = 0.0;
  // DLVO prefactors
  double hamaker = 0.0, kappa = 0.0, el_prefactor = 0.0, el_ratio = 0.0;
  double born_prefactor = 0.0;  ///< A sigma_B^6 / 37800 (0: no Born core)
};

/// Resolves defaults for types with radii ai, aj and surface potentials psi_i, psi_j.
/// Throws naming the bad parameter.
PairTerm resolve_pair(const PairPotential& p, double ai, double aj, double psi_i, double psi_j);

struct EnergyForce {
  double energy;
  double s;  ///< -V'(r)/r
};

/// V and -V'/r at distance r (0 < r < cutoff; beyond it the caller skips the pair).
EnergyForce evaluate_pair(const PairTerm& t, double r);

/// Born repulsion between spheres of radii ai, aj at centre distance r > ai + aj, for a
/// Hamaker constant A and collision diameter sigma_B, with prefactor = A sigma_B^6 / 37800
/// (Feke, Prabhu, Mann & Mann 1984, J. Phys. Chem. 88, 5735): V and -V'/r.
EnergyForce born_repulsion(double prefactor, double ai, double aj, double r);

enum class BondKind {
  harmonic,  ///< k/2 (r - r0)^2
  fene,      ///< -k R0^2/2 ln(1 - (r/R0)^2), r < R0 (Warner 1972; Kremer & Grest 1990)
};
const char* to_string(BondKind kind);
BondKind bond_kind_from_string(const std::string& name);

struct BondPotential {
  BondKind kind = BondKind::harmonic;
  double k = 1.0;       ///< stiffness (> 0)
  double length = 1.0;  ///< harmonic: rest length r0 (>= 0); fene: maximum extension R0 (> 0)
};

/// V and -V'/r of a bond at distance r; fene requires r < R0 (caller checks).
EnergyForce evaluate_bond(const BondPotential& b, double r);

}  // namespace rpyfmm::bd
