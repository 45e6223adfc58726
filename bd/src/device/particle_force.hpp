// rpyfmm::bd::device — the force on one particle and its share of the potential energy, in the
// order of ForceField::compute (bd/src/force_field.cpp): its type's external force (plus the
// global force), then the pair forces over its sorted Verlet row (pairs beyond their cut-off
// skipped, Tran et al. (2015), Algorithm 1, lines 11-13), then its bonds in bond order, then the
// harmonic trap. Each pair and bond is visited from both sides, so each side counts half its
// energy. The same operations in the same order as the CPU engine: the same bits where neither
// side contracts multiply-adds (docs/gpu-bd.md).
#pragma once

#include <math.h>  // ::sqrt

#include <cstdint>

#include "atomics.hpp"
#include "minimum_image.hpp"
#include "pair_potentials.hpp"
#include "rpyfmm/bd/potentials.hpp"
#include "rpyfmm/core/host_device.hpp"

namespace rpyfmm::bd::device {

/// One of a particle's bonds: the particle at its other end, its potential, the bond's index.
struct BondEntry {
  std::uint32_t partner = 0;
  std::uint32_t potential = 0;
  std::uint32_t bond = 0;
};

/// Everything the force on a particle reads besides the positions (device or host memory).
struct ForceTables {
  std::uint32_t ntypes = 1;
  const std::uint32_t* type = nullptr;        ///< per particle
  const PairTerm* pairs = nullptr;            ///< ntypes x ntypes (ForceField::pair)
  bool has_pairs = false;                     ///< some pair term active (cut-off > 0)
  const double* external = nullptr;           ///< 3 per type: external + global force
  double trap = 0.0;                          ///< harmonic trap stiffness (0: none)
  const std::uint32_t* bond_begin = nullptr;  ///< per particle + 1: its first BondEntry
  const BondEntry* bonds = nullptr;           ///< in bond order per particle
  const BondPotential* bond_potentials = nullptr;
  MinimumImage image;
};

/// The Verlet rows (verlet_rows.hpp): row i is indices[offsets[i], offsets[i + 1]).
struct RowsView {
  const std::uint64_t* offsets = nullptr;
  const std::uint32_t* indices = nullptr;
};

/// Where a particle's force goes, and the lowest particle with an overlapping hard pair / the
/// lowest broken bond (store_min slots).
struct ForceOutput {
  double* force = nullptr;   ///< 3 per particle
  double* energy = nullptr;  ///< per particle: its share
  std::uint64_t* bad_pair = nullptr;
  std::uint64_t* bad_bond = nullptr;
};

/// Adds the pair forces on particle i to f; returns half their energy. A hard pair closer than
/// its minimum distance (or coincident) is recorded in bad_pair and skipped.
RPYFMM_HOST_DEVICE inline double add_pair_forces(std::uint32_t i, const double* x, const ForceTables& t,
                                                 const RowsView& rows, double f[3], std::uint64_t* bad_pair) {
  const std::uint64_t row_types = static_cast<std::uint64_t>(t.type[i]) * t.ntypes;
  const double* xi = x + 3 * static_cast<std::uint64_t>(i);
  double e = 0.0;
  for (std::uint64_t k = rows.offsets[i]; k < rows.offsets[i + 1]; ++k) {
    const std::uint32_t j = rows.indices[k];
    const PairTerm& p = t.pairs[row_types + t.type[j]];
    if (!p.active) continue;
    double d[3];
    t.image.separation(xi, x + 3 * static_cast<std::uint64_t>(j), d);
    const double r2 = squared_norm(d);
    if (r2 >= p.cutoff * p.cutoff) continue;
    if (r2 <= p.min_distance * p.min_distance || r2 == 0.0) {
      store_min(bad_pair, i);
      continue;
    }
    const EnergyForce ef = pair_energy_force(p, ::sqrt(r2));
    e += 0.5 * ef.energy;  // each pair is visited from both sides
    for (int c = 0; c < 3; ++c) f[c] += ef.s * d[c];
  }
  return e;
}

/// Adds the bond forces on particle i to f and half their energy to e, bond by bond (the CPU
/// engine's order of additions). A bond joining coincident particles, or a FENE bond at or past
/// R0, is recorded in bad_bond and skipped.
RPYFMM_HOST_DEVICE inline void add_bond_forces(std::uint32_t i, const double* x, const ForceTables& t, double f[3],
                                               double& e, std::uint64_t* bad_bond) {
  for (std::uint32_t k = t.bond_begin[i]; k < t.bond_begin[i + 1]; ++k) {
    const BondEntry b = t.bonds[k];
    const BondPotential& bp = t.bond_potentials[b.potential];
    double d[3];
    t.image.separation(x + 3 * static_cast<std::uint64_t>(i), x + 3 * static_cast<std::uint64_t>(b.partner), d);
    const double r = ::sqrt(squared_norm(d));
    if (r == 0.0 || (bp.kind == BondKind::fene && r >= bp.length)) {
      store_min(bad_bond, b.bond);
      continue;
    }
    const EnergyForce ef = bond_energy_force(bp, r);
    e += 0.5 * ef.energy;
    for (int c = 0; c < 3; ++c) f[c] += ef.s * d[c];
  }
}

/// The force on particle i and its share of the energy, into `out`.
RPYFMM_HOST_DEVICE inline void particle_force(std::uint32_t i, const double* x, const ForceTables& t,
                                              const RowsView& rows, const ForceOutput& out) {
  const double* ext = t.external + 3 * static_cast<std::uint64_t>(t.type[i]);
  double f[3] = {ext[0], ext[1], ext[2]};
  double e = 0.0;
  if (t.has_pairs) e += add_pair_forces(i, x, t, rows, f, out.bad_pair);
  add_bond_forces(i, x, t, f, e, out.bad_bond);
  const double* xi = x + 3 * static_cast<std::uint64_t>(i);
  if (t.trap > 0.0) {
    for (int c = 0; c < 3; ++c) {
      f[c] -= t.trap * xi[c];
      e += 0.5 * t.trap * xi[c] * xi[c];
    }
  }
  for (int c = 0; c < 3; ++c) out.force[3 * static_cast<std::uint64_t>(i) + c] = f[c];
  out.energy[i] = e;
}

}  // namespace rpyfmm::bd::device
