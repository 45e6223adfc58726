#include "engine_tables.hpp"

#include <cmath>
#include <string>

#include "../thermal_energy.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/free_draining.hpp"

namespace rpyfmm::bd::device {

namespace {

constexpr const char* kWhere = "bd device engine";

void check_options(const EngineOptions& o) {
  require_positive(o.dt, kWhere, "dt");
  require_thermal_energy(o.kT, 2.0 * o.kT * o.dt, kWhere, "2 kT dt");
  require_positive(o.max_displacement, kWhere, "max_displacement");
  require_positive(o.viscosity, kWhere, "viscosity");
  for (double f : o.global_force)
    require(std::isfinite(f), ErrorCode::invalid_argument, kWhere, "global_force must be finite");
}

/// Each particle's bonds in bond order (ForceField's bond index: the order of its sum).
void fill_bonds(const ForceField& forces, std::size_t n, EngineTables& t) {
  const auto bonds = forces.bonds();
  t.bond_begin.assign(n + 1, 0);
  for (const Bond& b : bonds) {
    ++t.bond_begin[b.i + 1];
    ++t.bond_begin[b.j + 1];
  }
  for (std::size_t i = 0; i < n; ++i) t.bond_begin[i + 1] += t.bond_begin[i];
  t.bonds.assign(t.bond_begin[n], BondEntry{});
  std::vector<std::uint32_t> fill(t.bond_begin.begin(), t.bond_begin.end() - 1);
  for (std::size_t k = 0; k < bonds.size(); ++k) {
    const Bond& b = bonds[k];
    const auto bond = static_cast<std::uint32_t>(k);
    t.bonds[fill[b.i]++] = BondEntry{b.j, b.type, bond};
    t.bonds[fill[b.j]++] = BondEntry{b.i, b.type, bond};
  }
  t.bond_potentials.assign(forces.bond_potentials().begin(), forces.bond_potentials().end());
}

void fill_forces(const ForceField& forces, const EngineOptions& o, EngineTables& t) {
  const auto& types = forces.types();
  t.ntypes = static_cast<std::uint32_t>(types.size());
  t.pairs.resize(types.size() * types.size());
  for (std::uint32_t a = 0; a < t.ntypes; ++a)
    for (std::uint32_t b = 0; b < t.ntypes; ++b) t.pairs[a * t.ntypes + b] = forces.pair(a, b);
  t.has_pairs = forces.has_pairs();
  t.external.resize(3 * types.size());
  for (std::size_t a = 0; a < types.size(); ++a)
    for (int c = 0; c < 3; ++c) t.external[3 * a + c] = types[a].external_force[c] + o.global_force[c];
  t.trap = forces.trap_stiffness();
}

/// Skin and per-pair radii: NeighbourList's rules (its constructor checks the skin and, in a
/// periodic box, r_L against half the box; set_pair_cutoffs's radii).
void fill_lists(const ForceField& forces, const rpy::Geometry& geometry, const EngineOptions& o, EngineTables& t) {
  const NeighbourList reference(geometry, forces.max_cutoff(), o.neighbours);
  t.cutoff = reference.cutoff();
  t.skin = reference.skin();
  t.fixed_interval = o.neighbours.fixed_interval;
  const std::vector<double> cutoffs = forces.pair_cutoffs();
  t.list_rl2.resize(cutoffs.size());
  for (std::size_t k = 0; k < cutoffs.size(); ++k) {
    const double rl = cutoffs[k] + t.skin;
    t.list_rl2[k] = cutoffs[k] > 0.0 ? rl * rl : 0.0;
  }
  t.image.periodic = geometry.is_periodic();
  for (int c = 0; c < 3; ++c) {
    t.image.box[c] = geometry.box()[c];
    t.image.inv_box[c] = geometry.is_periodic() ? 1.0 / geometry.box()[c] : 0.0;
  }
}

/// rpy::FreeDrainingMobility's mu = 1 / (6 pi eta a) and its square root, per type.
void fill_motion(const ForceField& forces, const EngineOptions& o, EngineTables& t) {
  for (const ParticleType& type : forces.types()) {
    const rpy::SphereMobility m = rpy::sphere_mobility(type.radius, o.viscosity);
    t.mobility.push_back(m.translation);
    t.sqrt_mobility.push_back(m.sqrt_translation);
    t.radius.push_back(type.radius);
  }
  t.dt = o.dt;
  t.noise = std::sqrt(2.0 * o.kT * o.dt);
  t.brownian = o.kT > 0.0;
  t.max_displacement2 = o.max_displacement * o.max_displacement;
  t.seed = o.seed;
}

}  // namespace

EngineTables make_motion_tables(const ForceField& forces, const EngineOptions& options) {
  check_options(options);
  EngineTables t;
  fill_motion(forces, options, t);
  return t;
}

EngineTables make_engine_tables(const ForceField& forces, std::span<const std::uint32_t> types,
                                const rpy::Geometry& geometry, const EngineOptions& options) {
  check_options(options);
  require(!types.empty(), ErrorCode::invalid_input, kWhere, "no particles (N = 0)");
  require(types.size() < 0xFFFFFFFFu, ErrorCode::invalid_input, kWhere, "too many particles");
  forces.check(types);
  EngineTables t;
  t.n = types.size();
  t.type.assign(types.begin(), types.end());
  fill_forces(forces, options, t);
  fill_bonds(forces, t.n, t);
  fill_lists(forces, geometry, options, t);
  fill_motion(forces, options, t);
  return t;
}

std::vector<double> particle_radii(const EngineTables& t) {
  std::vector<double> radii(t.n);
  for (std::size_t i = 0; i < t.n; ++i) radii[i] = t.radius[t.type[i]];
  return radii;
}

void check_positions(std::span<const double> positions, std::size_t n) {
  require(positions.size() == 3 * n, ErrorCode::invalid_input, kWhere,
          "positions has " + std::to_string(positions.size()) + " entries, expected 3N = " + std::to_string(3 * n));
  require_finite(positions, kWhere, "positions", 3);
}

}  // namespace rpyfmm::bd::device
