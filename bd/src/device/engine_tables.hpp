// rpyfmm::bd::device — the host copies of everything a device step reads besides the positions,
// taken from the CPU engine's objects (ForceField, NeighbourList's skin rule) so that both
// engines run on the same parameters: the resolved pair terms, the per-pair list radii of
// NeighbourList::set_pair_cutoffs, the external forces, the free-draining mobilities of
// rpy::FreeDrainingMobility and each particle's bonds in the order ForceField::compute sums them.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "cell_grid.hpp"
#include "particle_force.hpp"
#include "rpyfmm/bd/device/device_engine.hpp"
#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::bd::device {

struct EngineTables {
  std::size_t n = 0;
  std::uint32_t ntypes = 1;
  std::vector<std::uint32_t> type;  // per particle
  // forces
  std::vector<PairTerm> pairs;  // ntypes x ntypes
  bool has_pairs = false;
  std::vector<double> external;  // 3 per type
  double trap = 0.0;
  std::vector<std::uint32_t> bond_begin;  // n + 1
  std::vector<BondEntry> bonds;
  std::vector<BondPotential> bond_potentials;
  // neighbour lists
  double cutoff = 0.0;           // r_c, the largest pair cut-off (0: no lists)
  double skin = 0.0;             // r_L - r_c
  std::vector<double> list_rl2;  // ntypes x ntypes: (r_c(t1, t2) + skin)^2, 0 where no pair
  int fixed_interval = 0;        // NeighbourOptions::fixed_interval
  MinimumImage image;
  // motion
  std::vector<double> mobility, sqrt_mobility, radius;  // per type
  double dt = 0.0, noise = 0.0, max_displacement2 = 1.0;
  bool brownian = false;
  std::uint64_t seed = 0;

  [[nodiscard]] double list_radius() const { return cutoff + skin; }
  /// (skin/2)^2: the rebuild test's threshold.
  [[nodiscard]] double rebuild_limit2() const { return 0.25 * skin * skin; }
  /// True when the CPU engine builds its rows from all pairs rather than from the cells of grid
  /// g: fewer than 64 particles, or a periodic grid with fewer than 3 cells a side.
  [[nodiscard]] bool rows_from_all_pairs(const CellGrid& g) const { return n < 64 || (g.periodic && !g.wrap); }
};

/// The tables for particles of `types` under `forces` and `options`. Throws rpyfmm::Error naming
/// the bad option, type or bond (the CPU engine's checks: ForceField::check, NeighbourList).
EngineTables make_engine_tables(const ForceField& forces, std::span<const std::uint32_t> types,
                                const rpy::Geometry& geometry, const EngineOptions& options);

/// The free-draining motion of particles of `forces`' types under `options` alone (mobility,
/// sqrt_mobility, radius per type and the step's constants; no particle, force or list tables), after
/// the checks of make_engine_tables on the options. For steps on a part of a system
/// (rpyfmm/mpi/brownian_dynamics.hpp).
EngineTables make_motion_tables(const ForceField& forces, const EngineOptions& options);

/// Each particle's radius (its type's), as Integrator hands them to its mobility.
std::vector<double> particle_radii(const EngineTables& t);

/// Throws unless positions holds 3n finite values.
void check_positions(std::span<const double> positions, std::size_t n);

}  // namespace rpyfmm::bd::device
