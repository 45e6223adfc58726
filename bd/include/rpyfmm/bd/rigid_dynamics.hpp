// rpyfmm::bd — Brownian dynamics of rigid bodies made of beads, with full hydrodynamic
// interactions (the bodies' mobility N by rpyfmm::rpy::RigidBodies on any bead operator: direct,
// FMM, PSE).
//
// Body k has a reference point q_k and an orientation, a unit quaternion (w, x, y, z) with
// rotation matrix R_k; its beads sit at r_i = q_k + R_k rho_i, rho_i the body-frame shape. The
// generalized coordinates Q = (q_k, orientation_k) follow the overdamped Langevin equation
//     dQ = N W dt + sqrt(2 kT) N^{1/2} dB + kT (d/dQ . N) dt
// (rigid bodies: Delong, Balboa Usabiaga & Donev, J. Chem. Phys. 143, 144107 (2015)), with W the
// forces and torques about q_k, N the 6m x 6m body mobility, and the divergence taken with
// translations of q_k and rotations about q_k (the Lie derivative on the orientations). One step
// of the Euler-Maruyama scheme with a random finite difference (RFD) for the drift:
//   1. Y = N W + sqrt(2 kT / dt) N K^T M^{-1} B z: one bead square root B z (B B^T = M) and one
//      GMRES solve (the random slip of Sprinkle et al., J. Chem. Phys. 147, 244103 (2017));
//   2. drift = (kT / delta) [N(Q + delta/2 S w) - N(Q - delta/2 S w)] S^{-1} w with w ~ N(0, I_6m),
//      S = diag(l_k I, I) (translations by l_k delta w, rotations by delta w radians; l_k body k's
//      RMS lever arm): two GMRES solves at the two perturbed configurations. Its mean is
//      kT d/dQ . N + O(delta^2) (E[w w^T] = I);
//   3. q_k += dt (U_k + drift), R_k <- exp(dt [Omega_k + drift]_x) R_k (the exponential map on
//      the quaternion; renormalized).
// The drift matters whenever the reference point is not a body's centre of mobility (a tracked
// point off the centre drifts towards it at -2 D_r (q - c) for an isotropic body) and for
// hydrodynamically coupled, non-spherical bodies; drift = none leaves it out (for bodies known
// to have none, e.g. a lone sphere tracked at its centre; a step then costs 0.53-0.66 of one with
// the drift; docs/theory/rigid.md).
//
// Forces and torques come from a user function of the state (e.g. gravity, traps), and from an
// optional bead force field (set_bead_forces: pair potentials between beads of different bodies,
// e.g. steric repulsion, with a neighbour list; per-type constant forces), summed over each
// body's beads into its force and torque. The noise is counter-based (seed, step): a run
// is reproducible and independent of the thread count where the bead operator's products are.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/bd/quaternion.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

namespace rpyfmm::bd {

enum class RigidDrift {
  random_finite_difference,  ///< the RFD of the header (two extra GMRES solves per step)
  none,                      ///< no drift term (correct only where kT d/dQ . N = 0)
};

struct RigidDynamicsOptions {
  /// Time step (> 0). No default: it must come from the user.
  double dt = 0.0;
  /// Thermal energy kT (>= 0; 0 = deterministic dynamics: one GMRES solve per step).
  double kT = 1.0;
  /// Key of the counter-based noise (with the step number).
  std::uint64_t seed = 1;
  /// Step number of the initial state: a restart from the state after step s (positions and
  /// orientations as saved, first_step = s, same seed and options) continues the run it restarts
  /// bit for bit, since the noise is keyed by the step and no other state carries over.
  std::uint64_t first_step = 0;
  RigidDrift drift = RigidDrift::random_finite_difference;
  /// RFD step delta (relative: translations by delta l_k, rotations by delta radians); in
  /// [1e-6, 0.1]. The RFD's bias is O(delta^2) from the difference and O(tolerance / delta) from
  /// the solves, whose tolerance is min(solver.tolerance, 1e-3 delta) (see rfd_tolerance()).
  double rfd_delta = 1e-3;
  /// The body-mobility solver (GMRES tolerance etc.) of step 1.
  rpy::RigidBodyOptions solver{};
  /// Bead square root B z (tolerance 1e-3, Lanczos with the block preconditioner by default).
  rpy::SqrtOptions sqrt{.preconditioner = rpy::SqrtPreconditioner::automatic};
  /// Blow-up guard: a step that would move a body's beads by more than this fraction of its
  /// RMS lever arm l_k (translation plus l_k times the rotation angle), or produces NaN/Inf, is
  /// refused with an error and the state stays at the last good step. > 0.
  double max_displacement = 1.0;
};

/// The state a force function sees.
struct RigidBodyState {
  double time = 0.0;
  std::span<const double> positions;       ///< reference points q_k (3m)
  std::span<const double> orientations;    ///< unit quaternions (4m)
  std::span<const double> bead_positions;  ///< r_i = q_k + R_k rho_i (3N; not wrapped into a box)
};

/// Writes the forces and torques (6m: F_k then T_k about q_k) for a state; starts from zeros.
using BodyForceFunction = std::function<void(const RigidBodyState& state, std::span<double> forces_torques)>;

/// What one step did.
struct RigidStepReport {
  int solve_iterations = 0;        ///< GMRES iterations of step 1
  int drift_iterations = 0;        ///< GMRES iterations of the two RFD solves
  int sqrt_iterations = 0;         ///< iterations of the bead square root
  double potential_energy = 0.0;   ///< of the bead force field (0 without one)
  bool neighbour_rebuild = false;  ///< the bead neighbour list was rebuilt this step
};

struct RigidDynamicsTotals {
  std::uint64_t steps = 0;
  std::uint64_t solve_iterations = 0;
  std::uint64_t drift_iterations = 0;
  std::uint64_t sqrt_iterations = 0;
  /// Seconds per part: "forces" (the force function and the bead force field), "plan" (bead plans and body
  /// factorizations of step 1), "sqrt" (B z), "solve" (step 1's GMRES), "drift" (both RFD configurations: plans and
  /// solves), "update".
  StageTimes seconds;
};

class RigidBodyDynamics {
 public:
  /// `shape`: bead positions rho_i in each body's frame, relative to its reference point (3N);
  /// `radii`: one or N bead radii; `body_offsets`: m + 1 entries (body k holds beads
  /// body_offsets[k] ... body_offsets[k+1] - 1); `positions`: reference points q_k (3m);
  /// `orientations`: 4m quaternions (empty = identity; normalized here unless already unit to
  /// 1e-14, zero refused).
  /// `beads` computes bead products (not owned: it must outlive this object). Throws
  /// rpyfmm::Error naming the problem (sizes, NaN/Inf, options, bodies RigidBodies refuses).
  RigidBodyDynamics(rpy::MobilityOperator& beads, std::vector<double> shape, std::vector<double> radii,
                    std::vector<std::size_t> body_offsets, std::vector<double> positions,
                    std::vector<double> orientations, RigidDynamicsOptions options, BodyForceFunction forces = {});
  /// The same, owning the bead operator.
  RigidBodyDynamics(std::unique_ptr<rpy::MobilityOperator> beads, std::vector<double> shape, std::vector<double> radii,
                    std::vector<std::size_t> body_offsets, std::vector<double> positions,
                    std::vector<double> orientations, RigidDynamicsOptions options, BodyForceFunction forces = {});

  /// Bead forces from a force field (ForceField: pair potentials by bead type, acting between
  /// beads of different bodies only; per-type and global constant forces), added to the force
  /// function's forces and torques every step. `bead_types`: N indices into field.types(), or
  /// empty for type 0 everywhere (radii of the types are not used: beads keep their own).
  /// Pair potentials whose sigma is 0 take the contact distance of the types' radii, so give
  /// the types the beads' radii or set sigma. A neighbour list with `neighbours` serves the
  /// pairs. Throws rpyfmm::Error on bad types or a periodic box smaller than twice the list
  /// radius.
  void set_bead_forces(ForceField field, std::vector<std::uint32_t> bead_types = {}, NeighbourOptions neighbours = {});

  /// Advances one step. On a blow-up, a force error or an unconverged solve the state stays at
  /// the last good step and rpyfmm::Error is thrown.
  const RigidStepReport& step();
  void run(std::uint64_t count);

  /// The random finite difference of step 2 without the factor kT, for a given w (6m):
  /// (1 / delta) [N(Q + delta/2 S w) - N(Q - delta/2 S w)] S^{-1} w at the current state. Its
  /// mean over w ~ N(0, I), and its sum over w = e_1 ... e_6m, is d/dQ . N to O(delta^2).
  /// Returns the GMRES iterations of both solves.
  int drift_estimate(std::span<const double> w, std::span<double> drift);

  /// F_k = sum f_i, T_k = sum (r_i - q_k) x f_i over each body's beads (bead forces, 3N, at
  /// the current bead positions), added to forces_torques (6m).
  void bead_forces_to_bodies(std::span<const double> bead_forces, std::span<double> forces_torques) const;

  [[nodiscard]] std::size_t bodies() const { return offsets_.size() - 1; }
  [[nodiscard]] std::size_t beads() const { return radii_.size(); }
  [[nodiscard]] std::span<const double> positions() const { return q_; }
  [[nodiscard]] std::span<const double> orientations() const { return quat_; }
  /// Current bead positions (3N).
  [[nodiscard]] std::span<const double> bead_positions() const { return beads_now_; }
  [[nodiscard]] std::span<const double> shape() const { return shape_; }
  [[nodiscard]] std::span<const double> radii() const { return radii_; }
  [[nodiscard]] std::span<const std::size_t> body_offsets() const { return offsets_; }
  /// Body k's RMS lever arm l_k (of its shape about the reference point).
  [[nodiscard]] std::span<const double> lever_arms() const { return lever_; }
  /// The step number (first_step + steps taken).
  [[nodiscard]] std::uint64_t step_count() const { return step_; }
  [[nodiscard]] double time() const { return static_cast<double>(step_) * options_.dt; }
  [[nodiscard]] const RigidDynamicsOptions& options() const { return options_; }
  /// GMRES tolerance of the RFD solves: min(solver.tolerance, 1e-3 rfd_delta).
  [[nodiscard]] double rfd_tolerance() const;
  [[nodiscard]] const RigidStepReport& last_report() const { return report_; }
  [[nodiscard]] const RigidDynamicsTotals& totals() const { return totals_; }
  /// Forces and torques (6m) and velocities (6m, with noise, drift not included) of the last
  /// step; the drift velocity of the last step (6m, zeros without RFD).
  [[nodiscard]] std::span<const double> last_forces_torques() const { return w_; }
  [[nodiscard]] std::span<const double> last_velocities() const { return y_; }
  [[nodiscard]] std::span<const double> last_drift() const { return drift_; }

 private:
  // The stages of step(), in order.
  /// w_ = forces and torques at the current state (user function and bead force field).
  void gather_forces_and_torques();
  /// y_ = N W, plus the random slip sqrt(2 kT / dt) N^{1/2} z when kT > 0.
  void solve_velocities();
  /// drift_ = kT d/dQ . N by a random finite difference (zero without it).
  void estimate_drift();
  /// Q += dt (Y + drift) (rotations by quaternion), refused beyond max_displacement; beads moved.
  void update_bodies();
  /// Bead positions of (positions, orientations) into out (3N).
  void place_beads(std::span<const double> positions, std::span<const double> orientations,
                   std::vector<double>& out) const;
  /// Perturbed configuration Q + sign delta/2 S w, planned on the solver `solver`, and the
  /// solve N(Q +- ...) S^{-1} w into out (bead forces into rfd_lambda_); `warm`: GMRES starts
  /// from the other side's solution (rfd_plus_, rfd_lambda_). Returns GMRES iterations.
  int perturbed_solve(rpy::RigidBodies& solver, std::span<const double> w, double sign, std::span<double> out,
                      bool warm);

  std::unique_ptr<rpy::MobilityOperator> owned_;
  rpy::MobilityOperator& bead_operator_;
  RigidDynamicsOptions options_;
  BodyForceFunction forces_;
  std::vector<double> shape_, radii_;
  std::vector<std::size_t> offsets_;
  std::vector<double> q_, quat_, lever_;
  rpy::RigidBodies solver_, rfd_solver_;
  std::optional<ForceField> bead_field_;
  std::vector<std::uint32_t> bead_types_, bead_body_;
  std::unique_ptr<NeighbourList> bead_list_;
  std::vector<double> bead_forces_;
  std::uint64_t step_ = 0;
  RigidStepReport report_;
  RigidDynamicsTotals totals_;
  // work arrays
  std::vector<double> beads_now_, w_, y_, drift_, z_, rfd_w_, rfd_v_, rfd_plus_, rfd_minus_, rfd_lambda_, q_work_,
      quat_work_, beads_work_;
};

}  // namespace rpyfmm::bd
