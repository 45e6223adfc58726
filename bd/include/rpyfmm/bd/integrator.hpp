// rpyfmm::bd — Euler-Maruyama Brownian dynamics with hydrodynamic interactions
// on any mobility operator (docs/theory/bd.md; Fiore et al. 2017, eq. 17):
//
//     dx = M F dt + sqrt(2 kT dt) M^{1/2} z,   z ~ N(0, I) keyed by (seed, step, particle)
//
// RPY is divergence-free, so no drift term kT div M dt is needed (docs/theory/rpy.md).
// With the free-draining operator (method "none") this is eq. 3 of Tran et al. (2015)
// (docs/theory/bd.md).
//
// One step: neighbour-list update (only when needed) -> forces -> mobility
// plan (set_positions, once per step) -> M F and M^{1/2} z (drift_and_noise,
// sharing the first Krylov product) -> blow-up check -> x += dx.
//
// With rotation (IntegratorOptions::rotation), every particle also carries an orientation, a
// unit quaternion q, and the torques T of the force field's TorqueField; the step uses the grand
// mobility [U; W] = M [F; T] and the 6N Brownian sample [w_t; w_r] (rotation_sampling.hpp) and
// turns each particle by the exponential map, q <- exp(W dt + sqrt(2 kT dt) w_r) q
// (docs/theory/bd.md Sec. 7). No drift term arises there either.
// With inertia (IntegratorOptions::inertia), the particles of the types given a mass move by the
// Langevin step of langevin.hpp instead, from the same forces F_n, with their own noise (stream 4,
// keyed by the particle's index in the system and the step) and half-step velocities; the others
// move as above (docs/theory/bd.md Sec. 8). Only with free draining (method "none") and without
// rotation: hydrodynamic interactions with inertia are not modelled.
// With the SAC scheme (IntegratorOptions::sac; Algorithm 2 of Tran et al. (2015), Sec. 4.2, and
// docs/theory/bd.md Sec. 9), the Brownian particles within the adsorption radius of a Langevin one
// form a complex with it (sac.hpp). Each step: (1) a complex moves as one Langevin body, with the
// carrier's mass and friction, under the sum of the forces on its members from outside the
// complex; free particles move as above; (2) its adsorbed particles follow the carrier's
// displacement rigidly, then take a Brownian step of their own under the whole force on them
// (from the other members of their complex and from outside it): Brownian motion of the adsorbed
// particles' coordinates relative to the carrier, which samples the Boltzmann distribution also
// where complexes touch (docs/theory/bd.md Sec. 9).
// Everything that enters x is independent of the thread count, provided the
// mobility operator's products are.
// With IntegratorOptions::engine set to the device engine (docs/gpu-bd.md), free-draining steps
// run entirely on a CUDA device (or on its host launcher) with the same physics, bit for bit where
// neither side fuses multiply-adds; features the device engine lacks are refused by name.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/langevin_group.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/bd/sac.hpp"
#include "rpyfmm/bd/sampling.hpp"
#include "rpyfmm/bd/step_engine.hpp"
#include "rpyfmm/bd/stepper.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::bd {

struct IntegratorOptions {
  /// Time step (> 0). No default: it must come from the user.
  double dt = 0.0;
  /// Thermal energy kT (>= 0; 0 = deterministic dynamics).
  double kT = 1.0;
  /// Key of the counter-based noise (with the step number and the particle index).
  std::uint64_t seed = 1;
  /// Square-root solver for the Brownian displacement B z, B B^T = M (default: the operator's
  /// preferred one, tol 1e-3; Lanczos runs with the block preconditioner, measured at 1.7-2.6x
  /// fewer products than M^{1/2} z: docs/theory/samplers.md).
  SqrtOptions sqrt{.preconditioner = rpy::SqrtPreconditioner::automatic};
  /// Blow-up guard: a step in which any particle would move more than this
  /// fraction of its radius (or produces NaN/Inf) is refused with an error. > 0.
  double max_displacement = 1.0;
  /// Keep the deterministic (M F dt) and Brownian parts of the last step separately.
  bool keep_split_displacements = false;
  /// Rotational dynamics: orientations, torques, rotational diffusion (docs/theory/bd.md Sec. 7).
  /// Needs an operator that supports_rotation() (none, direct, ...). max_displacement then
  /// bounds each step's rotation angle too (in radians: a surface point moves a |phi|).
  bool rotation = false;
  /// Inertial (Langevin) types: entry t set = particles of type t move by the Langevin step with
  /// that mass and friction (langevin.hpp); unset, or past the end, = Brownian. Needs the
  /// free-draining operator ("none"), no rotation and no split displacements.
  std::vector<std::optional<LangevinParticle>> inertia{};
  /// The silica-alumina complex scheme (sac.hpp): carriers are the inertial types, adsorbers the
  /// Brownian ones. Needs at least one of each, the free-draining operator, no rotation, no split
  /// displacements and no bonds.
  SacOptions sac{};
  /// What runs the steps (step_engine.hpp): the CPU engine, or the device engine, which takes the
  /// free-draining operator ("none") without rotation, inertial particles, the SAC scheme, split
  /// displacements or force callbacks, and refuses the others (not_supported, naming the feature).
  StepEngine engine = StepEngine::cpu;
};

/// What one step did (and cumulative counters in Integrator::totals()).
struct StepReport {
  int sqrt_iterations = 0;
  std::size_t preconditioner_blocks = 0;  ///< blocks of the sampler's block preconditioner (0: none)
  int mobility_products = 0;
  bool shared_first_product = false;
  bool neighbour_rebuild = false;
  double potential_energy = 0.0;
};

struct IntegratorTotals {
  std::uint64_t steps = 0;
  std::uint64_t sqrt_iterations = 0;
  std::uint64_t mobility_products = 0;
  /// Seconds per part: "neighbours", "forces", "plan" (set_positions), "drift" (M F,
  /// or the block M [F, z]), "sqrt" (drawing z and the rest of M^{1/2} z), "update".
  StageTimes seconds;
};

class Integrator {
 public:
  /// `positions` (3N, finite) and `types` (N, indices into forces.types()).
  /// Radii come from the particle types. Positions are kept unwrapped (for MSD);
  /// the mobility operator wraps them into a periodic box itself.
  /// `orientations` (options.rotation only): 4N quaternions w x y z, or empty for the identity
  /// (quaternion::checked: normalized unless already unit to 1e-14).
  /// `velocities` (with inertial types only): 3N half-step velocities v_{n-1/2} (0 for Brownian
  /// particles), or empty for the Maxwell distribution at kT keyed by the seed.
  /// Throws rpyfmm::Error naming the bad option or particle. With options.engine on the device
  /// engine, also not_supported naming the first feature it lacks, or why no device is usable.
  Integrator(std::unique_ptr<rpy::MobilityOperator> mobility, ForceField forces, IntegratorOptions options,
             std::vector<double> positions, std::vector<std::uint32_t> types, NeighbourOptions neighbours = {},
             std::uint64_t first_step = 0, std::vector<double> orientations = {}, std::vector<double> velocities = {});
  /// An Integrator whose steps `engine` takes, an engine the caller made for these particles
  /// (options.engine must be StepEngine::external; e.g. rpyfmm/mpi/bd_stepper.hpp across MPI ranks):
  /// the particles, forces and options are checked as above, and the Integrator reads the state
  /// through the engine as it reads the device engine's (the CPU engine's features refused alike).
  /// `mobility`: the operator the engine applies, whose name and viscosity the Integrator reports.
  Integrator(std::unique_ptr<rpy::MobilityOperator> mobility, ForceField forces, IntegratorOptions options,
             std::vector<double> positions, std::vector<std::uint32_t> types, NeighbourOptions neighbours,
             std::uint64_t first_step, std::unique_ptr<Stepper> engine);
  Integrator(Integrator&&) noexcept;
  Integrator& operator=(Integrator&&) noexcept;
  ~Integrator();

  /// Advances one step. On a blow-up or a force error the state is left at the
  /// last good step and rpyfmm::Error (numerical_failure / invalid_input) is thrown.
  const StepReport& step();
  /// Advances `count` steps.
  void run(std::uint64_t count);

  /// The positions (3N, unwrapped). On the device engine, copied from the device when read at a
  /// step not copied yet, into one host array: a span kept across steps shows the last read. On an
  /// engine across processes (StepEngine::external), as its Stepper::positions gives them: maybe on
  /// one process only (empty elsewhere), read on all of them.
  [[nodiscard]] std::span<const double> positions() const;
  [[nodiscard]] std::span<const std::uint32_t> types() const { return types_; }
  [[nodiscard]] std::span<const double> radii() const { return radii_; }
  [[nodiscard]] std::size_t size() const { return types_.size(); }
  /// Number of steps taken since the start of the run (including before a restart).
  [[nodiscard]] std::uint64_t step_count() const { return step_; }
  [[nodiscard]] double time() const { return static_cast<double>(step_) * options_.dt; }
  [[nodiscard]] const IntegratorOptions& options() const { return options_; }
  [[nodiscard]] const StepReport& last_report() const { return report_; }
  [[nodiscard]] const IntegratorTotals& totals() const { return totals_; }
  [[nodiscard]] std::size_t neighbour_rebuilds() const;
  /// The CPU engine's list; the device engine keeps its Verlet rows on the device and refuses
  /// (not_supported).
  [[nodiscard]] const NeighbourList& neighbour_list() const;
  /// The engine's own positions and forces read in place (Stepper::StateView: the device
  /// engine's device buffers, or its host launcher's arrays), valid until the next step; nullopt on
  /// the CPU engine (its positions() are its own array) and on an engine without one address space.
  [[nodiscard]] std::optional<Stepper::StateView> engine_state() const;
  [[nodiscard]] const ForceField& force_field() const { return forces_; }
  [[nodiscard]] const rpy::MobilityOperator& mobility() const { return *mobility_; }
  /// Forces at the start of the last step (3N). With the SAC scheme, those the step used: on a
  /// carrier with adsorbed particles the complex's force from outside it, on an adsorbed particle
  /// the whole force on it (its relative step's). On the device engine, copied as positions().
  [[nodiscard]] std::span<const double> last_forces() const;
  /// M F dt and sqrt(2 kT dt) M^{1/2} z of the last step (needs keep_split_displacements). On an
  /// engine across processes, as its Stepper gives them (read as positions()).
  [[nodiscard]] std::span<const double> deterministic_displacement() const;
  [[nodiscard]] std::span<const double> brownian_displacement() const;
  /// With rotation: the orientations (4N unit quaternions w x y z), the torques at the start of
  /// the last step (3N), and the rotation vectors phi = W dt + sqrt(2 kT dt) w_r by which the
  /// last step turned each particle (3N, lab frame). Empty without rotation. On an engine across
  /// processes the orientations and rotation vectors are read as positions() (Stepper), the
  /// torques are not kept (empty).
  [[nodiscard]] std::span<const double> orientations() const;
  [[nodiscard]] std::span<const double> last_torques() const { return torque_; }
  [[nodiscard]] std::span<const double> last_rotations() const;
  /// The inertial particles, their half-step velocities and kinetic temperature (empty() when
  /// every particle is Brownian).
  [[nodiscard]] const LangevinGroup& inertial() const { return inertial_; }
  /// The half-step velocities (3N; empty without inertial particles) and their kinetic temperature,
  /// of the CPU engine's inertial() or of an engine that holds them (Stepper::velocities, read as
  /// positions()).
  [[nodiscard]] std::span<const double> velocities() const;
  [[nodiscard]] double kinetic_temperature() const;
  /// With the SAC scheme, the complexes at the current positions (empty() otherwise).
  [[nodiscard]] const Complexes& complexes() const { return complexes_; }
  /// With the SAC scheme: each particle's complex (Complexes::owner()) and the numbers of complexes
  /// and of adsorbed particles (Complexes::count(), adsorbed_total()) at the current positions, of
  /// the CPU engine's complexes() or of an engine that holds them (Stepper::complex_ids, read as
  /// positions(), and Stepper::complex_counts); empty and {0, 0} otherwise.
  [[nodiscard]] std::span<const std::uint32_t> complex_ids() const;
  [[nodiscard]] std::array<std::uint64_t, 2> complex_counts() const;

 private:
  /// u = M F and w = M^{1/2} z (or, fused, u = M F + noise / dt M^{1/2} z; with rotation
  /// rotational_products) at the current state.
  void drift_and_noise_products(StepReport& rep, bool fused, bool brownian, double noise);
  /// With rotation: u, omega = M [F; T] and w_t, w_r = B [z_t; z_r] (z drawn).
  DriftNoiseReport rotational_products(bool brownian);
  /// Checks the inertia options against the operator and the other options.
  void check_inertia() const;
  /// With the SAC scheme: the forces of step 1 and 2 of Algorithm 2 into f_ (see last_forces()).
  double complex_forces();
  /// dx = u dt + noise w (the Langevin step's displacement for inertial particles; with
  /// rotation, phi = omega dt + noise w_r), refused (numerical_failure, state unchanged) when a
  /// particle would move more than max_displacement x its radius, or turn by more than
  /// max_displacement radians.
  void checked_displacements(double dt, double noise, bool brownian);
  /// The blow-up error for particle i (dx_ and phi_ hold its step).
  [[noreturn]] void fail_blow_up(std::size_t i) const;
  /// The checks and state of every engine (the particles, forces and options), none started.
  struct Unstarted {};
  Integrator(Unstarted, std::unique_ptr<rpy::MobilityOperator> mobility, ForceField forces, IntegratorOptions options,
             std::vector<double> positions, std::vector<std::uint32_t> types, const NeighbourOptions& neighbours,
             std::uint64_t first_step);
  /// The CPU engine's state: work arrays, orientations, inertial particles, SAC complexes.
  void start_cpu_engine(std::vector<double> orientations, std::vector<double> velocities);
  /// The device engine (integrator_device.cpp) from the checked particles and forces; refuses
  /// what it lacks, orientations and velocities included.
  void start_device_engine(const NeighbourOptions& neighbours, bool orientations, bool velocities);
  /// One step of the device engine, with the report and totals the CPU engine gives for "none".
  const StepReport& device_step();

  std::unique_ptr<rpy::MobilityOperator> mobility_;
  ForceField forces_;
  IntegratorOptions options_;
  std::vector<double> x_;
  std::vector<std::uint32_t> types_;
  std::vector<double> radii_;
  NeighbourList list_;
  std::uint64_t step_;
  StepReport report_;
  IntegratorTotals totals_;
  // work arrays
  std::vector<double> f_, z_, u_, w_, dx_, dx_det_, dx_brown_;
  // rotation: orientations (4N), torques, angular velocities M_rt F + M_rr T, rotational noise,
  // its sample, the rotation vectors of the step (3N each)
  std::vector<double> q_, torque_, omega_, zr_, wr_, phi_;
  LangevinGroup inertial_;
  // SAC scheme: the complexes, each particle's group (its carrier in a complex, else itself), the
  // forces from inside its complex (3N)
  Complexes complexes_;
  std::vector<std::uint32_t> groups_;
  std::vector<double> f_within_;
  // The device engine (null: the CPU engine's steps); it holds the positions then.
  std::unique_ptr<Stepper> device_;
};

}  // namespace rpyfmm::bd
