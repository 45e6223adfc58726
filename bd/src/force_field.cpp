#include "rpyfmm/bd/force_field.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <sstream>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

ForceField::ForceField(std::vector<ParticleType> types) : types_(std::move(types)) {
  require(!types_.empty(), ErrorCode::invalid_argument, "ForceField", "at least one particle type is needed");
  for (std::size_t t = 0; t < types_.size(); ++t) {
    const std::string where = "particle type '" + types_[t].name + "'";
    require_positive(types_[t].radius, where, "radius");
    for (double f : types_[t].external_force)
      require(std::isfinite(f), ErrorCode::invalid_argument, where, "external_force must be finite");
    require(std::isfinite(types_[t].surface_potential), ErrorCode::invalid_argument, where,
            "surface_potential must be finite");
    for (std::size_t u = 0; u < t; ++u)
      require(types_[u].name != types_[t].name, ErrorCode::invalid_argument, where, "type name used twice");
  }
  pairs_.assign(types_.size() * types_.size(), PairTerm{});
}

std::uint32_t ForceField::type_index(const std::string& name) const {
  for (std::size_t t = 0; t < types_.size(); ++t)
    if (types_[t].name == name) return static_cast<std::uint32_t>(t);
  fail(ErrorCode::invalid_argument, "particle type", "unknown type '" + name + "'");
}

void ForceField::set_pair(std::uint32_t t1, std::uint32_t t2, const PairPotential& potential) {
  require(t1 < types_.size() && t2 < types_.size(), ErrorCode::invalid_argument, "ForceField::set_pair",
          "type index out of range");
  const auto& a = types_[t1];
  const auto& b = types_[t2];
  const PairTerm term = resolve_pair(potential, a.radius, b.radius, a.surface_potential, b.surface_potential);
  pairs_[t1 * types_.size() + t2] = term;
  PairTerm mirrored = term;
  std::swap(mirrored.ai, mirrored.aj);
  pairs_[t2 * types_.size() + t1] = mirrored;
}

std::uint32_t ForceField::add_bond_potential(const BondPotential& potential) {
  const std::string where = std::string("bond potential ") + to_string(potential.kind);
  require_positive(potential.k, where, "k");
  if (potential.kind == BondKind::fene) {
    require_positive(potential.length, where, "length (maximum extension R0)");
  } else {
    require(std::isfinite(potential.length) && potential.length >= 0.0, ErrorCode::invalid_argument, where,
            "length (rest length) must be finite and >= 0");
  }
  bond_potentials_.push_back(potential);
  return static_cast<std::uint32_t>(bond_potentials_.size() - 1);
}

void ForceField::add_bonds(std::span<const Bond> bonds) {
  for (const Bond& b : bonds) {
    require(b.type < bond_potentials_.size(), ErrorCode::invalid_argument, "ForceField::add_bonds",
            "bond (" + std::to_string(b.i) + ", " + std::to_string(b.j) + ") has unknown bond type " +
                std::to_string(b.type));
    require(b.i != b.j, ErrorCode::invalid_input, "ForceField::add_bonds",
            "bond joins particle " + std::to_string(b.i) + " to itself");
  }
  bonds_.insert(bonds_.end(), bonds.begin(), bonds.end());
  bond_index_valid_ = false;
}

ForceField ForceField::with_bonds(std::span<const Bond> bonds, std::span<const std::uint64_t> names) const {
  require(names.empty() || names.size() == bonds.size(), ErrorCode::invalid_argument, "ForceField::with_bonds",
          "names must be empty or one per bond");
  ForceField part = *this;
  part.bonds_.clear();
  part.add_bonds(bonds);
  part.bond_names_.assign(names.begin(), names.end());
  return part;
}

void ForceField::set_global_force(const std::array<double, 3>& force) {
  for (double f : force)
    require(std::isfinite(f), ErrorCode::invalid_argument, "ForceField::set_global_force", "force must be finite");
  global_force_ = force;
}

void ForceField::set_trap(double stiffness) {
  require(std::isfinite(stiffness) && stiffness >= 0.0, ErrorCode::invalid_argument, "ForceField::set_trap",
          "stiffness must be finite and >= 0");
  trap_ = stiffness;
}

void ForceField::add_callback(ForceCallback callback) {
  require(static_cast<bool>(callback), ErrorCode::invalid_argument, "ForceField::add_callback", "empty callback");
  callbacks_.push_back(std::move(callback));
}

double ForceField::max_cutoff() const {
  double rc = 0.0;
  for (const auto& p : pairs_)
    if (p.active) rc = std::max(rc, p.cutoff);
  return rc;
}

std::vector<double> ForceField::pair_cutoffs() const {
  std::vector<double> rc(pairs_.size(), 0.0);
  for (std::size_t k = 0; k < pairs_.size(); ++k)
    if (pairs_[k].active) rc[k] = pairs_[k].cutoff;
  return rc;
}

void ForceField::set_torque_field(TorqueField torques) {
  torques.check(types_.size());
  torques_ = std::move(torques);
}

void ForceField::check(std::span<const std::uint32_t> particle_types) const {
  for (std::size_t i = 0; i < particle_types.size(); ++i) {
    require(particle_types[i] < types_.size(), ErrorCode::invalid_input, "particles",
            "particle " + std::to_string(i) + " has type index " + std::to_string(particle_types[i]) + " but only " +
                std::to_string(types_.size()) + " types are defined");
  }
  for (const Bond& b : bonds_) {
    require(b.i < particle_types.size() && b.j < particle_types.size(), ErrorCode::invalid_input, "bonds",
            "bond (" + std::to_string(b.i) + ", " + std::to_string(b.j) +
                ") refers to a particle >= N = " + std::to_string(particle_types.size()));
  }
}

void ForceField::rebuild_bond_index(std::size_t n) const {
  bond_offsets_.assign(n + 1, 0);
  for (const Bond& b : bonds_) {
    ++bond_offsets_[b.i + 1];
    ++bond_offsets_[b.j + 1];
  }
  for (std::size_t i = 0; i < n; ++i) bond_offsets_[i + 1] += bond_offsets_[i];
  bond_entries_.assign(bond_offsets_[n], 0);
  std::vector<std::size_t> fill(bond_offsets_.begin(), bond_offsets_.end() - 1);
  for (std::size_t k = 0; k < bonds_.size(); ++k) {  // bond order: deterministic summation order
    bond_entries_[fill[bonds_[k].i]++] = static_cast<std::uint32_t>(k);
    bond_entries_[fill[bonds_[k].j]++] = static_cast<std::uint32_t>(k);
  }
  bond_index_n_ = n;
  bond_index_valid_ = true;
}

namespace {
std::string fmt_double(double v) {
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}

// Lowest bad particle index found by any thread (deterministic error messages).
void record_bad(std::atomic<std::size_t>& bad, std::size_t i) {
  std::size_t cur = bad.load(std::memory_order_relaxed);
  while (i < cur && !bad.compare_exchange_weak(cur, i, std::memory_order_relaxed)) {
  }
}
}  // namespace

void ForceField::fail_overlap(std::size_t i, std::span<const double> x, std::span<const std::uint32_t> ptype,
                              const NeighbourList& list, std::uint64_t step, std::span<const std::uint32_t> groups,
                              std::span<const std::uint64_t> ids) const {
  const auto name = [&](std::size_t k) { return std::to_string(ids.empty() ? k : ids[k]); };
  const std::size_t nt = types_.size();
  for (std::uint32_t j : list.neighbours(i)) {
    const PairTerm& p = pairs_[ptype[i] * nt + ptype[j]];
    if (!p.active || (!groups.empty() && groups[i] == groups[j])) continue;
    double d[3];
    list.separation(&x[3 * i], &x[3 * j], d);
    const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (r <= p.min_distance || r == 0.0) {
      fail(ErrorCode::invalid_input, "forces",
           "particles " + name(i) + " and " + name(j) + " overlap at step " + std::to_string(step) + ": distance " +
               fmt_double(r) + " <= " + fmt_double(p.min_distance) + " allowed by the hard '" + to_string(p.kind) +
               "' potential (sigma " + fmt_double(p.sigma) + ")");
    }
  }
}

void ForceField::fail_bond(std::size_t k, std::span<const double> x, const NeighbourList& list, std::uint64_t step,
                           std::span<const std::uint64_t> ids) const {
  const Bond& b = bonds_[k];
  const auto name = [&](std::size_t i) { return std::to_string(ids.empty() ? i : ids[i]); };
  double d[3];
  list.separation(&x[3 * b.i], &x[3 * b.j], d);
  const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  fail(ErrorCode::invalid_input, "forces",
       "bond " + std::to_string(k < bond_names_.size() ? bond_names_[k] : k) + " between particles " + name(b.i) +
           " and " + name(b.j) + " at step " + std::to_string(step) +
           (r == 0.0 ? " joins coincident particles"
                     : " is stretched to " + fmt_double(r) + " >= FENE maximum extension " +
                           fmt_double(bond_potentials_[b.type].length)));
}

double ForceField::add_pair_forces(std::size_t i, std::span<const double> x, std::span<const std::uint32_t> ptype,
                                   const NeighbourList& list, std::span<const std::uint32_t> groups, double f[3],
                                   double* fw, std::atomic<std::size_t>& bad_pair) const {
  const std::size_t nt = types_.size();
  const bool grouped = !groups.empty();
  double e = 0.0;
  for (std::uint32_t j : list.neighbours(i)) {
    const PairTerm& p = pairs_[ptype[i] * nt + ptype[j]];
    if (!p.active) continue;
    double* to = f;
    if (grouped && groups[i] == groups[j]) {
      if (fw == nullptr) continue;
      to = fw;
    }
    double d[3];
    list.separation(&x[3 * i], &x[3 * j], d);
    const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    if (r2 >= p.cutoff * p.cutoff) continue;
    if (r2 <= p.min_distance * p.min_distance || r2 == 0.0) {
      record_bad(bad_pair, i);
      continue;
    }
    const EnergyForce ef = evaluate_pair(p, std::sqrt(r2));
    e += 0.5 * ef.energy;  // each pair is visited from both sides
    for (int c = 0; c < 3; ++c) to[c] += ef.s * d[c];
  }
  return e;
}

double ForceField::particle_row(std::size_t i, std::span<const double> x, std::span<const std::uint32_t> ptype,
                                const NeighbourList& list, std::span<const std::uint32_t> groups, double f[3],
                                double* fw, RowFailures& bad) const {
  const ParticleType& ti = types_[ptype[i]];
  for (int c = 0; c < 3; ++c) f[c] = ti.external_force[c] + global_force_[c];
  double e = 0.0;
  if (max_cutoff() > 0.0) e += add_pair_forces(i, x, ptype, list, groups, f, fw, bad.pair);
  for (std::size_t k = bond_offsets_[i]; k < bond_offsets_[i + 1]; ++k) {
    const Bond& b = bonds_[bond_entries_[k]];
    const BondPotential& bp = bond_potentials_[b.type];
    const std::uint32_t j = b.i == i ? b.j : b.i;
    double d[3];
    list.separation(&x[3 * i], &x[3 * j], d);
    const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (r == 0.0 || (bp.kind == BondKind::fene && r >= bp.length)) {
      record_bad(bad.bond, bond_entries_[k]);
      continue;
    }
    const EnergyForce ef = evaluate_bond(bp, r);
    e += 0.5 * ef.energy;
    for (int c = 0; c < 3; ++c) f[c] += ef.s * d[c];
  }
  if (trap_ > 0.0) {
    for (int c = 0; c < 3; ++c) {
      f[c] -= trap_ * x[3 * i + c];
      e += 0.5 * trap_ * x[3 * i + c] * x[3 * i + c];
    }
  }
  return e;
}

double ForceField::compute(std::span<const double> x, std::span<const std::uint32_t> ptype, const NeighbourList& list,
                           std::uint64_t step, std::span<double> forces, std::span<const std::uint32_t> groups,
                           std::span<double> within) const {
  const std::size_t n = ptype.size();
  require(x.size() == 3 * n && forces.size() == 3 * n, ErrorCode::invalid_input, "ForceField::compute",
          "positions, types and forces disagree on N");
  require(groups.empty() || groups.size() == n, ErrorCode::invalid_input, "ForceField::compute",
          "groups has " + std::to_string(groups.size()) + " entries for " + std::to_string(n) + " particles");
  require(within.empty() || (within.size() == 3 * n && !groups.empty()), ErrorCode::invalid_input,
          "ForceField::compute", "within needs groups and 3N entries");
  const bool split = !within.empty();
  check_list(list, n, "ForceField::compute");
  if (!bond_index_valid_ || bond_index_n_ != n) rebuild_bond_index(n);
  RowFailures bad;
  // Each particle's share of the energy, summed afterwards in particle order: an OpenMP reduction
  // would add the threads' partial sums in an order that depends on the schedule, so the energy
  // (the log's potential_energy) would change in its last bits with the thread count and the run.
  std::vector<double> particle_energy(n);
#pragma omp parallel for schedule(dynamic, 256) if (n >= 1024)
  for (std::size_t i = 0; i < n; ++i) {
    double f[3];
    double fw[3] = {0.0, 0.0, 0.0};
    particle_energy[i] = particle_row(i, x, ptype, list, groups, f, split ? fw : nullptr, bad);
    for (int c = 0; c < 3; ++c) forces[3 * i + c] = f[c];
    if (split)
      for (int c = 0; c < 3; ++c) within[3 * i + c] = fw[c];
  }
  double energy = 0.0;
  for (const double e : particle_energy) energy += e;
  // With `within`, every pair was checked for overlaps: the search looks at all of them.
  if (bad.pair.load() != RowFailures::kNone)
    fail_overlap(bad.pair.load(), x, ptype, list, step, split ? std::span<const std::uint32_t>() : groups);
  if (bad.bond.load() != RowFailures::kNone) fail_bond(bad.bond.load(), x, list, step);
  for (const auto& cb : callbacks_) cb(x, step, forces);
  return energy;
}

ForceField ForceField::without_callbacks() const {
  ForceField copy = *this;
  copy.callbacks_.clear();
  return copy;
}

void ForceField::compute_rows(std::span<const double> x, std::span<const std::uint32_t> ptype,
                              const NeighbourList& list, std::uint64_t step, std::span<const std::uint32_t> rows,
                              std::span<const std::uint64_t> ids, std::span<double> forces, std::span<double> energies,
                              std::span<const std::uint32_t> groups, std::span<double> within) const {
  const std::size_t n = ptype.size(), m = rows.size();
  require(x.size() == 3 * n && ids.size() == n, ErrorCode::invalid_input, "ForceField::compute_rows",
          "positions, types and ids disagree on N");
  require(forces.size() == 3 * m && energies.size() == m, ErrorCode::invalid_input, "ForceField::compute_rows",
          "forces and energies must have 3 and 1 entries per row");
  require(groups.empty() || groups.size() == n, ErrorCode::invalid_input, "ForceField::compute_rows",
          "groups has " + std::to_string(groups.size()) + " entries for " + std::to_string(n) + " particles");
  require(within.empty() || (within.size() == 3 * m && !groups.empty()), ErrorCode::invalid_input,
          "ForceField::compute_rows", "within needs groups and 3 entries per row");
  const bool split = !within.empty();
  require(callbacks_.empty(), ErrorCode::not_supported, "ForceField::compute_rows",
          "force callbacks take the whole system, not a part of it");
  for (const Bond& b : bonds_)
    require(b.i < n && b.j < n, ErrorCode::invalid_input, "ForceField::compute_rows",
            "a bond refers to a particle beyond the part's N = " + std::to_string(n));
  require(std::all_of(rows.begin(), rows.end(), [n](std::uint32_t i) { return i < n; }), ErrorCode::invalid_input,
          "ForceField::compute_rows", "a row index is beyond N");
  check_list(list, n, "ForceField::compute_rows");
  if (!bond_index_valid_ || bond_index_n_ != n) rebuild_bond_index(n);
  RowFailures bad;
#pragma omp parallel for schedule(dynamic, 256) if (m >= 1024)
  for (std::size_t k = 0; k < m; ++k) {
    double fw[3] = {0.0, 0.0, 0.0};
    energies[k] = particle_row(rows[k], x, ptype, list, groups, &forces[3 * k], split ? fw : nullptr, bad);
    if (split)
      for (int c = 0; c < 3; ++c) within[3 * k + c] = fw[c];
  }
  // As compute(): with `within` every pair was checked for overlaps.
  if (bad.pair.load() != RowFailures::kNone)
    fail_overlap(bad.pair.load(), x, ptype, list, step, split ? std::span<const std::uint32_t>() : groups, ids);
  if (bad.bond.load() != RowFailures::kNone) fail_bond(bad.bond.load(), x, list, step, ids);
}

void ForceField::check_list(const NeighbourList& list, std::size_t n, const char* where) const {
  const double rc = max_cutoff();
  require(rc == 0.0 || (list.size() == n && list.cutoff() >= rc), ErrorCode::invalid_input, where,
          "neighbour list is not built for these particles and cutoffs");
}

}  // namespace rpyfmm::bd
