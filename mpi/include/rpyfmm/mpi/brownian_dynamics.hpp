// rpyfmm — Brownian dynamics on particles distributed over the ranks of an MPI communicator
// (docs/mpi.md, "Brownian dynamics across ranks"): the Euler-Maruyama step of rpyfmm::bd::Integrator,
//
//     dx = M F dt + sqrt(2 kT dt) M^{1/2} z,
//
// z_i keyed by (seed, step, global index i) as the serial engine keys it, with the free-draining
// mobility M = 1 / (6 pi eta a_i) (Tran et al. (2015), eq. 3) or the RPY mobility of all ranks'
// particles: in free space by DistributedDirectRpy or DistributedFmmRpy with its Lanczos square root
// across ranks, in a periodic box by DistributedPseRpy (Positively Split Ewald: Fiore, Balboa
// Usabiaga, Donev & Swan, J. Chem. Phys. 146, 124116 (2017)) with its split sampler, drift and
// noise in one pass as bd::Integrator takes them from PseRpy.
//
// Each rank owns a share of the particles, contiguous along the Morton curve (SfcPartition), and
// keeps a halo: the other ranks' particles within the list radius r_L = r_c + skin of a cover of
// its owned particles by tight boxes, and the bond partners of its owned particles, found when the
// lists are built and refreshed (positions only) every step. Its own and halo particles, in
// increasing global index, form the part of the system on which it builds the Verlet lists of
// bd::NeighbourList and re-indexes the bonds, so every owned particle's force is summed over the
// same neighbours and bonds in the same order as in the serial engine (bd::ForceField::compute_rows). The
// lists, the halo and the partition are rebuilt together by the dynamic test of Tran et al. (2015),
// Algorithm 1, taken over all ranks: once any particle has moved more than skin/2 since the last
// build. At a rebuild the particles migrate along the Morton curve when the ranks' costs (their
// particles plus their neighbour-list entries) are imbalanced beyond a threshold.
//
// So with free draining the positions (and with rotation the orientations) after every step are,
// bit for bit, those of bd::Integrator with rpy::FreeDrainingMobility on the whole set, on any
// number of ranks and for any partition (same binary). With hydrodynamic interactions they are the serial engine's with
// the same operator to round-off (direct: products summed in another order; pse: the serial PseRpy with double
// wave-space grids, its sums in another order) or to the FMM's tolerance (fmm). The
// potential energy is the sum over the ranks of their particles' shares, equal to the serial
// engine's to round-off (a sum in another order).
//
// With rotation (IntegratorOptions::rotation; docs/theory/bd.md Sec. 7) every particle also carries
// a unit quaternion, which travels with it at repartitions. The torques of the force field's
// TorqueField (constant per type, dipoles in a uniform field) depend on the particle's own type and
// orientation alone, so the halo carries none. The step takes the grand mobility [U; W] = M [F; T]
// and the 6N Brownian sample [w_t; w_r], z_r keyed by (seed, step, bd::kRotationNoiseStream, global
// index) as the serial engine keys it: with free draining omega = T / (8 pi eta a^3) and w_r =
// z_r / sqrt(8 pi eta a^3) per particle by rpy::FreeDrainingMobility, so the orientations, like the
// positions, are bd::Integrator's bit for bit; with direct or fmm by the operator's four-argument
// apply and rpyfmm::mpi::sqrt_apply_rotation; with pse by DistributedPseRpy's grand product and its
// split sampler with rotation, the wave noise keyed by the particles' global indices (the serial
// key). Each particle turns by the exponential map, q <- exp(phi) q with phi = W dt + sqrt(2 kT dt)
// w_r, max_displacement bounding |phi| too.
//
// With inertial (Langevin) types (IntegratorOptions::inertia; docs/theory/bd.md, the Langevin
// section) their particles move by the Gronbech-Jensen-Farago step of bd::langevin_step (Gronbech-Jensen
// & Farago, Mol. Phys. 111, 983 (2013)) from the same forces F_n, its noise keyed by (seed, step,
// bd::kLangevinNoiseStream, global index) and the initial Maxwell velocities by the global index as the
// serial engine keys them; each particle's half-step velocity travels with it at repartitions. The
// other particles take the free-draining step alongside, so positions and velocities are
// bd::Integrator's bit for bit on any number of ranks. As in the serial engine, inertia needs the
// mobility none and no rotation; the kinetic temperature is summed over the ranks.
//
// With the SAC scheme (IntegratorOptions::sac; Algorithm 2 of Tran et al. (2015), Sec. 4.2, and
// docs/theory/bd.md Sec. 9) the inertial particles carry the adsorbers within R_A as the serial
// engine's bd::Complexes finds them: the halo also reaches max R_A + skin (rebuilt by the dynamic
// test), a carrier's owner sums its complex's forces from outside the complex, fetched from the
// adsorbed particles' owners, and an adsorbed particle adds its carrier's displacement, fetched
// from the carrier's owner (mpi/src/bd_complexes.cpp). Positions, velocities and complexes are
// bd::Integrator's bit for bit on any number of ranks.
//
// With split displacements (IntegratorOptions::keep_split_displacements) the step keeps M F dt and
// sqrt(2 kT dt) M^{1/2} z of the owned particles as the serial engine splits them (pse then takes
// the serial engine's unfused path, PSE's split sampler keyed in global index order). Force
// callbacks see the whole system, gathered on every rank in global index order every step, and
// give the owned particles the serial engine's forces bit for bit.
//
// Checkpoints hold the whole state in global index order (bd::Checkpoint, gathered on one rank;
// with rotation version 3: orientations, those at step 0 and the summed rotation vectors; with
// inertial particles version 4: the half-step velocities), so a run
// written on P ranks restarts on any other number (restart_distributed_bd).
//
// Every public call is collective and fails collectively (communicator.hpp): a bad input or a
// blow-up on one rank makes every rank throw the same rpyfmm::Error, state kept at the last good
// step.
#pragma once

#include <mpi.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/bd/sac.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/partition.hpp"
#include "rpyfmm/rpy/geometry.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace rpyfmm::mpi {

/// Options of a distributed run. Every rank must pass the same.
struct DistributedBdOptions {
  /// dt, kT, seed, max_displacement, rotation, inertia, keep_split_displacements and sac as for
  /// bd::Integrator (rotation and split displacements with the methods none, direct, fmm and pse;
  /// inertial types with none, without rotation and without split displacements, as the serial
  /// engine; the SAC scheme with inertial types and without bonds, as the serial engine).
  bd::IntegratorOptions integrator{};
  /// The skin (0: 0.3 r_c) and the rebuild strategy (fixed_interval), as bd::NeighbourList's.
  bd::NeighbourOptions neighbours{};
  /// The mobility: none (free draining, 1 / (6 pi eta a)), or the RPY mobility of all ranks'
  /// particles: in open geometry by direct (DistributedDirectRpy) or fmm (DistributedFmmRpy), with
  /// the Brownian displacement by rpyfmm::mpi::sqrt_apply with integrator.sqrt (Lanczos or
  /// Chebyshev, with or without the block preconditioner of the whole set; automatic:
  /// Lanczos without it; rpyfmm/mpi/sqrt.hpp); in a periodic box by pse (DistributedPseRpy), drift
  /// and noise in one pass, u = M F + sqrt(2 kT / dt) M^{1/2} z with PSE's split sampler, as
  /// bd::Integrator takes them from PseRpy (integrator.sqrt.method automatic or split).
  rpy::MobilityMethod method = rpy::MobilityMethod::none;
  /// The fmm method's operator options (tolerance, leaf capacity, ...).
  DistributedFmmRpyOptions fmm{.tolerance = 1e-3};
  /// The pse method's operator options (tolerance, xi, grid, ...). Its wave-space grids are double
  /// precision whatever wave_precision says (DistributedPseRpy).
  rpy::pse::PseOptions pse{};
  /// Solvent viscosity eta (> 0).
  double viscosity = 1.0;
  /// A rebuild moves the particles along the space-filling curve when the largest rank's cost
  /// exceeds this multiple of the mean (>= 1; 1: at every rebuild; infinity: never after the first
  /// partition).
  double repartition_imbalance = 1.25;
  /// The curve of the partitions (SfcPartition; docs/mpi.md, "Space-filling-curve partition"). The
  /// positions do not depend on it in free draining (bit for bit); with hydrodynamic interactions
  /// the operators' sums do, at round-off, as on a partition by measured costs.
  SfcCurve curve = SfcCurve::morton;
  /// What a rank's cost is, in the imbalance test and as the weights of the new partition.
  enum class Cost {
    /// Its particles plus their neighbour-list entries (the pair work): the same on every run.
    model,
    /// The seconds of its own force and update work since the last rebuild (no communication
    /// counted), spread over its particles in proportion to the model's weights: follows what the
    /// machine does (cores of different speed, other load on some). Partitions then differ from run
    /// to run. Free-draining positions do not depend on the partition (bit for bit); with
    /// hydrodynamic interactions the operators' sums do, at round-off.
    measured_time,
  };
  /// The cost of repartition_imbalance's test and the partition's weights (default: the model).
  Cost repartition_cost = Cost::model;
};

/// This rank's particles.
struct BdShare {
  std::vector<double> positions;              ///< 3n, finite, unwrapped
  std::vector<std::uint32_t> types;           ///< n indices into the force field's types
  std::vector<std::uint64_t> ids;             ///< n global indices (empty: the ranks' shares in rank order)
  std::vector<double> reference_positions{};  ///< 3n positions at step 0 (empty: the positions)
  /// With rotation: 4n quaternions w x y z (empty: the identity), checked and normalized as
  /// bd::Integrator checks them (quaternion::checked); those at step 0 (empty: the orientations);
  /// the rotation vectors summed since step 0 (3n; empty: zeros). Without rotation all empty.
  std::vector<double> orientations{};
  std::vector<double> reference_orientations{};
  std::vector<double> rotation_vectors{};
  /// With inertial particles: 3n half-step velocities v_{n-1/2} (0 for Brownian particles; empty:
  /// the Maxwell distribution at kT keyed by the global index, bd::maxwell_velocities). Without
  /// inertial particles on any rank: empty. Ranks with particles give them on all or on none.
  std::vector<double> velocities{};
};

/// What the run did on this rank, and its share of the work.
struct DistributedBdStats {
  std::uint64_t steps = 0;
  std::uint64_t rebuilds = 0;      ///< list, halo and (maybe) partition rebuilds, the same on every rank
  std::uint64_t repartitions = 0;  ///< rebuilds that moved particles between ranks
  std::size_t halo_size = 0;       ///< this rank's halo particles since the last rebuild
  double imbalance = 1.0;          ///< max / mean cost (repartition_cost) over the ranks at the last rebuild
  /// This rank's seconds: "rebuild" (test, partition, halo search and exchange, lists), "halo" (the
  /// halo's positions every step), "forces", "update" (step, guard and the collective checks).
  StageTimes seconds;
};

namespace detail {
class BondIndex;  // mpi/src/bd_bonds.hpp
}  // namespace detail

class DistributedBd {
 public:
  /// Collective. Throws rpyfmm::Error on every rank for options the serial engine refuses or this
  /// one does not support, for a wrong size, a non-finite coordinate or an unknown type on any
  /// rank, for ids that are not a permutation of 0 ... N - 1, for bonds to a particle >= N, and when
  /// no rank has a particle. Bonds (the force field's, the same on every rank) index the global
  /// particles; a bond's partner on another rank travels with the halo. The force field's callbacks
  /// (bd::ForceField::add_callback, the same number on every rank) take the whole system: every
  /// step each rank gathers all particles' positions and forces in global index order (one
  /// MPI_Allgatherv of 7 doubles per particle, O(N) memory and traffic per rank) and calls them
  /// on it as the serial engine does; pair potentials, bonds, external forces and the trap need
  /// no gather (prefer them where they express the force).
  DistributedBd(MPI_Comm comm, bd::ForceField forces, rpy::Geometry geometry, DistributedBdOptions options,
                BdShare share, std::uint64_t first_step = 0);
  ~DistributedBd();
  DistributedBd(DistributedBd&&) noexcept;
  DistributedBd& operator=(DistributedBd&&) noexcept;

  /// Collective: one step. On a blow-up (a particle moving more than max_displacement × its radius,
  /// or NaN) or a hard-core overlap every rank throws the same Error, naming the particle by its
  /// global index, and the state stays at the last good step.
  void step();
  /// Collective: `count` steps.
  void run(std::uint64_t count);

  [[nodiscard]] const Communicator& communicator() const { return comm_; }
  [[nodiscard]] const DistributedBdOptions& options() const { return options_; }
  /// This rank's particles (they change at repartitions): positions (3n, unwrapped), types, global
  /// indices and positions at step 0, in increasing global index.
  [[nodiscard]] std::size_t local_size() const { return ids_.size(); }
  [[nodiscard]] std::span<const double> positions() const { return x_; }
  /// The forces on this rank's particles at the start of the last step (3n; 0 before the first and
  /// after a repartition until the next step; with the SAC scheme they travel with the particles,
  /// and are those the step used, as bd::Integrator::last_forces() gives them).
  [[nodiscard]] std::span<const double> last_forces() const { return f_; }
  /// With integrator.keep_split_displacements (empty without): the deterministic part M F dt and
  /// the Brownian part sqrt(2 kT dt) M^{1/2} z of the last step's displacement of this rank's
  /// particles (3n each, in increasing global index; 0 before the first step and after a
  /// repartition until the next step), as bd::Integrator::deterministic_displacement and
  /// brownian_displacement give them: their sum is the step's displacement, bit for bit
  /// (x_next = x + (drift + noise)). With pse the Brownian part is PSE's split sampler on z as
  /// PseRpy::apply_sqrt takes it (no fused pass, as the serial engine with split displacements).
  [[nodiscard]] std::span<const double> deterministic_displacement() const { return dx_det_; }
  [[nodiscard]] std::span<const double> brownian_displacement() const { return dx_brown_; }
  [[nodiscard]] std::span<const std::uint32_t> types() const { return types_; }
  [[nodiscard]] std::span<const std::uint64_t> ids() const { return ids_; }
  [[nodiscard]] std::span<const double> reference_positions() const { return reference_; }
  /// With rotation (empty without): this rank's orientations (4n unit quaternions w x y z), the
  /// torques at the start of the last step (3n; 0 before the first and after a repartition until
  /// the next step), the rotation vectors of the last step (3n, lab frame; the same) and their sums
  /// since step 0 (3n), in increasing global index.
  [[nodiscard]] std::span<const double> orientations() const { return q_; }
  [[nodiscard]] std::span<const double> last_torques() const { return torque_; }
  [[nodiscard]] std::span<const double> last_rotations() const { return phi_; }
  [[nodiscard]] std::span<const double> rotation_vectors() const { return rotation_sum_; }
  /// Collective, with rotation: the rotational MSD (mean |sum of the rotation vectors|^2) and the
  /// orientation correlation (mean u(t) . u(0), u the body z axis) over every rank's particles, the
  /// serial run's log columns (bd::rotation_moment_sums) to round-off (a sum in another order).
  [[nodiscard]] std::array<double, 2> rotation_moments() const;
  /// With inertial particles (empty without): this rank's half-step velocities (3n, 0 for
  /// Brownian particles), in increasing global index.
  [[nodiscard]] std::span<const double> velocities() const { return v_; }
  /// Whether any rank has an inertial particle.
  [[nodiscard]] bool inertial() const { return inertial_; }
  /// Collective: the kinetic temperature of the half-step velocities, the mean of m |v|^2 / 3 over
  /// every rank's inertial particles (bd::LangevinGroup::kinetic_temperature, the serial log's
  /// column) to round-off (a sum in another order); 0 without inertial particles.
  [[nodiscard]] double kinetic_temperature() const;
  /// With the SAC scheme (empty without): each owned particle's complex at the current positions,
  /// in increasing global index, as bd::Complexes::owner() gives it for the whole system: the global
  /// index of its carrier (a carrier with adsorbed particles: its own), or bd::Complexes::kFree.
  [[nodiscard]] std::span<const std::uint32_t> complex_ids() const { return complex_ids_; }
  /// Collective, with the SAC scheme: the complexes (carriers with adsorbed particles) and the
  /// adsorbed particles over every rank at the current positions (bd::Complexes::count() and
  /// adsorbed_total() of the serial engine); {0, 0} without.
  [[nodiscard]] std::array<std::uint64_t, 2> complex_counts() const;
  [[nodiscard]] std::uint64_t global_size() const { return global_n_; }
  [[nodiscard]] std::uint64_t step_count() const { return step_; }
  /// The potential energy at the start of the last step, summed over the ranks (0 before a step).
  [[nodiscard]] double potential_energy() const { return energy_; }
  [[nodiscard]] const DistributedBdStats& stats() const { return stats_; }

  /// Collective: the whole state on `root` in global index order (positions, types, positions at
  /// step 0, step, seed, dt; with rotation the orientations, those at step 0 and the summed rotation
  /// vectors, bd::Checkpoint's version 3; with inertial particles the half-step velocities, version
  /// 4); an empty checkpoint on the other ranks.
  [[nodiscard]] bd::Checkpoint checkpoint(int root = 0) const;

  struct Halo;           // mpi/src/bd_halo.hpp
  struct Hydrodynamics;  // mpi/src/bd_hydrodynamics.hpp

 private:
  /// The lists, the halo and, when the costs are imbalanced (or at the first), the partition.
  void rebuild();
  /// Moves the particles to their owners along the Morton curve, balancing `weights` (per owned particle).
  void repartition(std::span<const double> weights);
  /// f_ and particle_energy_ of the owned particles; energy_ over all ranks.
  void compute_forces();
  /// The Euler-Maruyama step with the blow-up guard, and the next step's rebuild test.
  void advance();
  /// The step's new positions (3 per owned particle) and the lowest global index the guard refuses
  /// (kNoParticle: none): free draining by the device stage, or dx = u dt + sqrt(2 kT dt) w from
  /// the products of the hydrodynamic interactions.
  std::uint64_t displace_free_draining(std::vector<double>& next);
  std::uint64_t displace_with_hydrodynamics(std::vector<double>& next);
  /// With inertial particles: the Langevin step of the owned inertial particles (bd::langevin_step
  /// from F_n, noise keyed by the global index) replacing their entries of `next`, the new
  /// velocities in `v_next` (3 per owned particle), and the lowest global index the guard refuses;
  /// with the SAC scheme also their displacements into dx_.
  std::uint64_t displace_inertial(std::vector<double>& next, std::vector<double>& v_next);
  /// With inertial particles: v_ from the share's velocities (`order`: the share's particles by
  /// global index) or, when none are given, the Maxwell draw keyed by the global index.
  void start_velocities(std::span<const double> given, std::span<const std::size_t> order);
  /// With rotation: phi = omega dt + sqrt(2 kT dt) w_r of the owned particles (omega_, wr_ filled),
  /// and the lowest global index whose |phi| exceeds max_displacement (kNoParticle: none).
  std::uint64_t turn_angles();
  /// With free draining and rotation: omega_ = T / (8 pi eta a^3), wr_ = z_r / sqrt(8 pi eta a^3)
  /// of the owned particles, as rpy::FreeDrainingMobility gives them to the serial engine.
  void free_draining_rotation();
  /// With free draining and split displacements: dx_det_ = mu F dt and dx_brown_ = sqrt(2 kT dt)
  /// sqrt(mu) z of the owned particles (mu = 1 / (6 pi eta a)), rpy::FreeDrainingMobility's u and w
  /// as the serial engine splits them.
  void free_draining_split();
  /// With callbacks: adds their forces to f_, called on the whole system gathered on every rank.
  void add_callback_forces();
  /// The lists, halo and partition when the rebuild test asked for them, else the halo's positions;
  /// with the SAC scheme then the complexes (update_complexes).
  void prepare_part();
  /// With the SAC scheme (bd_complexes.cpp): the serial engine's checks of its options and of the
  /// whole system's carriers and adsorbers (collective).
  void check_sac(std::span<const std::uint32_t> share_types);
  /// With the SAC scheme: the complexes at the current positions: each owned adsorber's nearest
  /// carrier within R_A (bd::Complexes on the part), groups_ of every part particle from its
  /// owner, complex_ids_ of the owned particles.
  void update_complexes();
  /// With the SAC scheme: bd::Integrator's forces of Algorithm 2 from f_ (the forces from outside
  /// each particle's complex) and f_within_: a carrier's force summed over its complex, an
  /// adsorbed particle's the whole force on it.
  void complex_forces();
  /// With the SAC scheme: each owned adsorbed particle's new position x + (dx + dx_carrier), its
  /// carrier's displacement from the carrier's owner (dx_: the owned particles' own displacements).
  void follow_carriers(std::vector<double>& next) const;
  /// Throws on every rank the blow-up error of particle `id` (next: the refused positions).
  void fail_blow_up(std::uint64_t id, std::span<const double> next) const;

  Communicator comm_;
  bd::ForceField forces_;
  std::vector<bd::ForceCallback> callbacks_;  // the force field's callbacks (forces_ holds none)
  rpy::Geometry geometry_;
  DistributedBdOptions options_;
  std::uint64_t global_n_ = 0;
  std::uint64_t step_ = 0;
  double energy_ = 0.0;
  bool rebuild_due_ = true;
  std::uint64_t steps_since_rebuild_ = 0;
  // owned particles, increasing global index
  std::vector<double> x_, reference_, list_reference_, f_, z_, particle_energy_;
  std::vector<std::uint32_t> types_;
  std::vector<std::uint64_t> ids_;
  std::unique_ptr<detail::BondIndex> bonds_;  // the whole system's bonds by particle
  std::unique_ptr<Halo> halo_;
  std::unique_ptr<Hydrodynamics> hydrodynamics_;  // null: free draining
  double work_seconds_ = 0.0;                     // own force and update work since the last rebuild
  std::vector<double> radii_, u_, w_;             // with hydrodynamics: per owned particle
  std::vector<double> dx_det_, dx_brown_;         // split displacements of the owned particles (3 each)
  // rotation, per owned particle: orientations (4), those at step 0 (4), summed rotation vectors,
  // torques, angular velocities, rotational noise and its sample, the step's rotation vectors (3)
  std::vector<double> q_, reference_q_, rotation_sum_, torque_, omega_, zr_, wr_, phi_;
  // inertial particles on any rank; then the half-step velocities of the owned particles (3 each)
  bool inertial_ = false;
  std::vector<double> v_;
  // the SAC scheme: whether on, max R_A, the part's complexes (none when the part lacks a carrier
  // or an adsorber), each part particle's group (its carrier's global index in a complex, else its
  // own), per owned particle its complex id, its forces from inside its complex and its own
  // displacement (3 each); whether the part is ready for the next step (prepared after a step)
  bool sac_ = false;
  double sac_reach_ = 0.0;
  std::optional<bd::Complexes> part_complexes_;
  std::uint64_t complexes_rebuild_ = 0;  // the rebuild whose part part_complexes_ was made for
  std::vector<std::uint32_t> groups_, complex_ids_;
  std::vector<double> f_within_, dx_;
  bool part_ready_ = false;
  DistributedBdStats stats_;
};

/// Collective: the run of `checkpoint` (read on `root`; ignored elsewhere) continued on the ranks
/// of `comm`, whatever number of ranks wrote it: the particles are dealt to the ranks in blocks of
/// global indices, and the first rebuild partitions them. Throws on every rank when the
/// checkpoint's seed or dt differ from the options', when it holds orientations and the options
/// have no rotation or the reverse, or when it holds velocities and the options' inertial types
/// give its particles none, or the reverse.
[[nodiscard]] DistributedBd restart_distributed_bd(MPI_Comm comm, bd::ForceField forces, rpy::Geometry geometry,
                                                   DistributedBdOptions options, const bd::Checkpoint& checkpoint,
                                                   int root = 0);

}  // namespace rpyfmm::mpi
