// rpyfmm::bd — the stages of a rigid-body Brownian dynamics step (rpyfmm/bd/rigid_dynamics.hpp) on a
// run of whole bodies, shared by bd::RigidBodyDynamics (all bodies) and
// mpi::DistributedRigidBodyDynamics (each rank's bodies), so that both compute the same bits.
// Private to the library: bd/src and mpi/src include it.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "rpyfmm/bd/rigid_dynamics.hpp"
#include "rpyfmm/core/timer.hpp"

namespace rpyfmm::bd::rigid_detail {

/// The options, checked (dt > 0, kT >= 0 and finite, rfd_delta in [1e-6, 0.1], max_displacement
/// > 0); rpyfmm::Error naming the problem after `where`.
const RigidDynamicsOptions& checked_options(const RigidDynamicsOptions& options, const char* where);
/// The solver options of the RFD solves: GMRES to min(solver.tolerance, 1e-3 rfd_delta).
rpy::RigidBodyOptions rfd_options(const RigidDynamicsOptions& options);

/// Lever arms l_k, the RMS distance of body k's shape (3 per bead) from its reference point, for the
/// bodies of `offsets` (m + 1 entries from 0). Refuses a body without beads or with every bead at
/// its reference point, naming it by first_body + k.
std::vector<double> lever_arms(std::span<const double> shape, std::span<const std::size_t> offsets,
                               std::size_t first_body, const char* where);

/// Bead positions r_i = q_k + R_k rho_i of (positions, orientations) into out (3N).
void place_beads(std::span<const double> shape, std::span<const std::size_t> offsets, std::span<const double> positions,
                 std::span<const double> orientations, std::vector<double>& out);

/// F_k += sum f_i, T_k += sum (r_i - q_k) x f_i over the beads of each body of `offsets` (bead
/// forces and positions 3 per bead, reference points 3 per body), added to forces_torques (6m), the
/// beads summed in order.
void add_bead_loads(std::span<const std::size_t> offsets, std::span<const double> beads, std::span<const double> q,
                    std::span<const double> bead_forces, std::span<double> forces_torques);

/// Refuses a non-finite force or torque in forces_torques (6m), naming the step and the body by
/// first_body + k.
void require_finite_loads(std::span<const double> forces_torques, std::uint64_t step, std::size_t first_body,
                          const char* where);

/// The RFD configuration Q + sign delta/2 S w into (q_out, quat_out) and S^{-1} w into v_out
/// (6m), for the bodies of (q, quat, lever) and w (6m).
void perturb(std::span<const double> q, std::span<const double> quat, std::span<const double> lever,
             std::span<const double> w, double half_step, std::vector<double>& q_out, std::vector<double>& quat_out,
             std::span<double> v_out);

/// Q + dt (Y + drift) into (q_out, quat_out) (rotations by the exponential map on the quaternion),
/// refused with rpyfmm::Error (numerical_failure) where a body's beads would move by more than
/// max_displacement l_k or the update is not finite; bodies named by first_body + k.
void advance(std::span<const double> q, std::span<const double> quat, std::span<const double> lever,
             std::span<const double> velocities, std::span<const double> drift, const RigidDynamicsOptions& options,
             std::uint64_t step, std::size_t first_body, std::vector<double>& q_out, std::vector<double>& quat_out,
             const char* where);

/// Step 1 of the header on `solver` (rpy::RigidBodies or mpi::DistributedRigidBodies, configured):
/// y = N w, plus the random slip sqrt(2 kT / dt) N K^T M^{-1} B z with the bead noise z when
/// kT > 0; its iterations into `report`, its seconds ("sqrt", "solve") into `totals`.
template <class Solver>
void solve_velocities(const Solver& solver, std::span<const double> w, std::span<const double> z, std::span<double> y,
                      const RigidDynamicsOptions& options, RigidStepReport& report, RigidDynamicsTotals& totals) {
  const StopWatch watch;
  rpy::RigidBodyReport solve;
  if (options.kT > 0.0) {
    solve = solver.apply_with_noise(w, std::sqrt(2.0 * options.kT / options.dt), z, y, options.sqrt);
    report.sqrt_iterations = solve.sqrt.iterations;
    totals.seconds["sqrt"] += solve.seconds_sqrt;
    totals.seconds["solve"] += watch.seconds() - solve.seconds_sqrt;
  } else {
    solve = solver.apply(w, y);
    totals.seconds["solve"] += watch.seconds();
  }
  report.solve_iterations = solve.iterations;
}

/// Step 2's difference without the factor kT: drift = (plus - minus) / delta (6m), plus and minus
/// the solves at the two perturbed configurations.
void rfd_difference(std::span<const double> plus, std::span<const double> minus, double delta, std::span<double> drift);

/// One step in the header's order, each stage a callable: forces (timed as "forces"), velocities,
/// drift, then update (timed as "update"); then the step's iterations added to `totals`.
template <class Forces, class Velocities, class Drift, class Update>
void take_step(const RigidStepReport& report, RigidDynamicsTotals& totals, Forces&& forces, Velocities&& velocities,
               Drift&& drift, Update&& update) {
  StopWatch watch;
  forces();  // at the current state
  totals.seconds["forces"] += watch.seconds();
  velocities();  // 1. velocities with the random slip, at the current configuration
  drift();       // 2. the drift kT d/dQ . N by a random finite difference
  watch.restart();
  update();  // 3. the update, checked before it is committed
  totals.seconds["update"] += watch.seconds();
  ++totals.steps;
  totals.solve_iterations += static_cast<std::uint64_t>(report.solve_iterations);
  totals.drift_iterations += static_cast<std::uint64_t>(report.drift_iterations);
  totals.sqrt_iterations += static_cast<std::uint64_t>(report.sqrt_iterations);
}

}  // namespace rpyfmm::bd::rigid_detail
