// rpyfmm::bd — the stages of a rigid-body Brownian dynamics step (rpyfmm/bd/rigid_dynamics.hpp) on a
// run of whole bodies, shared by bd::RigidBodyDynamics (all bodies) and
// mpi::DistributedRigidBodyDynamics (each rank's bodies), so that both compute the same bits.
// Private to the library: bd/src and mpi/src include it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "rpyfmm/bd/rigid_dynamics.hpp"

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

}  // namespace rpyfmm::bd::rigid_detail
