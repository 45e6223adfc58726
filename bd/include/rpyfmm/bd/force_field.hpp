// rpyfmm::bd — the forces of a BD run: per-type pair potentials (mixtures),
// bonds (bead-spring chains), constant external forces (gravity /
// sedimentation), a harmonic trap and user callbacks. compute() evaluates F_i particle by
// particle (full neighbour lists, sorted), so the result does not depend on
// the number of threads.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/bd/potentials.hpp"
#include "rpyfmm/bd/torque_field.hpp"

namespace rpyfmm::bd {

/// A kind of particle. Radius and external force apply to every particle of the type.
struct ParticleType {
  std::string name = "A";
  double radius = 1.0;                            ///< hydrodynamic radius a (> 0)
  std::array<double, 3> external_force{0, 0, 0};  ///< constant force, e.g. buoyant weight (m - m_f) g
  double surface_potential = 0.0;                 ///< Psi, used by DLVO pairs (Tran et al. (2015), Annex 2)
};

struct Bond {
  std::uint32_t i = 0, j = 0;
  std::uint32_t type = 0;  ///< index into the bond potentials
};

/// A user force: adds to `forces` (3N) given positions (3N, unwrapped) and the step.
/// Must be deterministic for reproducible runs.
using ForceCallback =
    std::function<void(std::span<const double> positions, std::uint64_t step, std::span<double> forces)>;

class ForceField {
 public:
  explicit ForceField(std::vector<ParticleType> types = {ParticleType{}});

  [[nodiscard]] const std::vector<ParticleType>& types() const { return types_; }
  /// Index of the type named `name`; throws naming it when unknown.
  [[nodiscard]] std::uint32_t type_index(const std::string& name) const;

  /// Pair potential between types t1 and t2 (symmetric). Replaces an earlier one.
  void set_pair(std::uint32_t t1, std::uint32_t t2, const PairPotential& potential);
  /// Adds a bond potential, returns its index for Bond::type.
  std::uint32_t add_bond_potential(const BondPotential& potential);
  /// Adds bonds (validated against the particle count in check()).
  void add_bonds(std::span<const Bond> bonds);
  /// A copy with `bonds` in place of this field's bonds (a part of a larger system: its bonds with
  /// their ends as indices into the part, rpyfmm/mpi/brownian_dynamics.hpp). `names` (empty, or one
  /// per bond): each bond's index in the whole system, named in errors instead of its index here.
  [[nodiscard]] ForceField with_bonds(std::span<const Bond> bonds, std::span<const std::uint64_t> names = {}) const;
  /// Constant force on every particle, added to the types' external forces.
  void set_global_force(const std::array<double, 3>& force);
  [[nodiscard]] const std::array<double, 3>& global_force() const { return global_force_; }
  /// Harmonic trap at the origin on every particle: F = -stiffness x, energy stiffness |x|^2 / 2
  /// (x unwrapped; 0 = none). Throws unless finite and >= 0.
  void set_trap(double stiffness);
  [[nodiscard]] double trap_stiffness() const { return trap_; }
  void add_callback(ForceCallback callback);
  [[nodiscard]] bool has_callbacks() const { return !callbacks_.empty(); }
  /// The callbacks, in the order compute() calls them (last, each adding to the forces of the
  /// other terms).
  [[nodiscard]] std::span<const ForceCallback> callbacks() const { return callbacks_; }
  /// A copy without the callbacks (the forces of a part of a larger system, compute_rows, whose
  /// callbacks the caller runs on the whole system: rpyfmm/mpi/brownian_dynamics.hpp).
  [[nodiscard]] ForceField without_callbacks() const;
  /// The torques on rotating particles (used by the integrator only with rotation on;
  /// docs/theory/bd.md Sec. 7). Replaces an earlier one; throws unless it has no types or one
  /// per particle type.
  void set_torque_field(TorqueField torques);
  [[nodiscard]] const TorqueField& torque_field() const { return torques_; }

  /// Largest pair cutoff (0 when no pair potential): the neighbour list's r_c.
  [[nodiscard]] double max_cutoff() const;
  [[nodiscard]] bool has_pairs() const { return max_cutoff() > 0.0; }
  /// The cut-off of every pair of types (types x types, 0 where the pair does not interact): the
  /// neighbour list's radius per pair (NeighbourList::set_pair_cutoffs).
  [[nodiscard]] std::vector<double> pair_cutoffs() const;
  [[nodiscard]] std::span<const Bond> bonds() const { return bonds_; }
  [[nodiscard]] std::span<const BondPotential> bond_potentials() const { return bond_potentials_; }
  /// Pair term between types (inactive when none set).
  [[nodiscard]] const PairTerm& pair(std::uint32_t t1, std::uint32_t t2) const {
    return pairs_[t1 * types_.size() + t2];
  }

  /// Checks particle types and bonds against N particles (throws naming the entry).
  void check(std::span<const std::uint32_t> particle_types) const;

  /// F (3N) at `positions` with `list` up to date (its cutoff >= max_cutoff()).
  /// Throws rpyfmm::Error naming the particles when a hard pair overlaps
  /// (r < min_distance_fraction * sigma), a FENE bond is stretched beyond R0,
  /// or bonded particles coincide. Returns the total potential energy.
  /// `groups` (empty, or N group indices): pairs of particles in the same group are skipped
  /// (the beads of one rigid body, whose internal forces cancel anyway), or, with `within` (3N),
  /// their forces go to `within` instead (the SAC scheme's forces inside a complex, sac.hpp; their
  /// energy counts in the result): one pass over the neighbour list for both.
  double compute(std::span<const double> positions, std::span<const std::uint32_t> particle_types,
                 const NeighbourList& list, std::uint64_t step, std::span<double> forces,
                 std::span<const std::uint32_t> groups = {}, std::span<double> within = {}) const;
  /// compute() for some particles of a part of a larger system (a rank's own particles among its
  /// own and halo particles, rpyfmm/mpi/brownian_dynamics.hpp): forces (3 per row) and energies (one
  /// per row: the particle's share, half of each pair's energy and its trap energy, the terms that
  /// compute() sums) of the particles `rows` (indices < N), each summed in compute()'s order, so
  /// bit for bit compute()'s values where the part holds every neighbour of the row's particle in
  /// the whole system's order. ids (N): each particle's index in the whole system, named in errors
  /// instead of its index here. Bonds index the part (with_bonds), bit for bit compute()'s where they
  /// keep the whole system's bond order; callbacks take the whole system and are refused
  /// (not_supported). `groups` (empty, or N) and `within` (empty, or 3 per row) as compute()'s.
  void compute_rows(std::span<const double> positions, std::span<const std::uint32_t> particle_types,
                    const NeighbourList& list, std::uint64_t step, std::span<const std::uint32_t> rows,
                    std::span<const std::uint64_t> ids, std::span<double> forces, std::span<double> energies,
                    std::span<const std::uint32_t> groups = {}, std::span<double> within = {}) const;

 private:
  void rebuild_bond_index(std::size_t n) const;
  /// The lowest particle with a hard-core overlap and the lowest bad bond found by any thread.
  struct RowFailures {
    static constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
    std::atomic<std::size_t> pair{kNone}, bond{kNone};
  };
  /// Particle i's force into f (external, pair, bond and trap terms; pairs inside its group into fw
  /// or skipped, as add_pair_forces) and its share of the energy (returned); failures into bad.
  double particle_row(std::size_t i, std::span<const double> x, std::span<const std::uint32_t> ptype,
                      const NeighbourList& list, std::span<const std::uint32_t> groups, double f[3], double* fw,
                      RowFailures& bad) const;
  /// Throws unless the list is built for n particles and the pair cut-offs (with pairs).
  void check_list(const NeighbourList& list, std::size_t n, const char* where) const;
  /// Adds to f the pair forces on particle i, from the pairs across groups (every pair when
  /// `groups` is empty); those inside i's group go to fw, or are skipped when fw is null. Records i
  /// in bad_pair on a hard-core overlap. Returns half the pairs' energy (each pair is visited from
  /// both sides).
  double add_pair_forces(std::size_t i, std::span<const double> x, std::span<const std::uint32_t> ptype,
                         const NeighbourList& list, std::span<const std::uint32_t> groups, double f[3], double* fw,
                         std::atomic<std::size_t>& bad_pair) const;
  /// Throws invalid_input naming the first neighbour of particle i within its hard core, among the
  /// pairs `groups` leaves in (none found at the precision of r: returns); particles named by ids
  /// where given.
  void fail_overlap(std::size_t i, std::span<const double> x, std::span<const std::uint32_t> ptype,
                    const NeighbourList& list, std::uint64_t step, std::span<const std::uint32_t> groups,
                    std::span<const std::uint64_t> ids = {}) const;
  /// Throws invalid_input naming bond k (coincident ends, or a FENE bond at its maximum extension).
  [[noreturn]] void fail_bond(std::size_t k, std::span<const double> x, const NeighbourList& list, std::uint64_t step,
                              std::span<const std::uint64_t> ids = {}) const;

  std::vector<ParticleType> types_;
  std::vector<PairTerm> pairs_;  // types x types
  std::vector<BondPotential> bond_potentials_;
  std::vector<Bond> bonds_;
  std::vector<std::uint64_t> bond_names_;  // empty, or each bond's index in a larger system (with_bonds)
  std::array<double, 3> global_force_{0, 0, 0};
  double trap_ = 0.0;
  std::vector<ForceCallback> callbacks_;
  TorqueField torques_;
  // Per-particle bond index (CSR), built lazily for N particles.
  mutable std::size_t bond_index_n_ = 0;
  mutable bool bond_index_valid_ = false;
  mutable std::vector<std::size_t> bond_offsets_;
  mutable std::vector<std::uint32_t> bond_entries_;  // bond indices
};

}  // namespace rpyfmm::bd
