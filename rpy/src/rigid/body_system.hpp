// rpyfmm — the rigid-body solve on the beads of a set of whole bodies, shared by
// rpy::RigidBodies (all bodies) and mpi::DistributedRigidBodies (each rank's bodies): the bodies'
// frames and lever-arm scaling, the body-block preconditioner, the saddle-point operator given a
// bead product, and the GMRES solve given an inner product (rpyfmm/rpy/rigid_bodies.hpp,
// docs/theory/rigid.md). Internal header.
//
// Every function here works on the beads and bodies it is given alone: K Y, K^T lambda, the
// preconditioner and the scaling never couple two bodies, so a rank that owns whole bodies applies
// them to its own share of the saddle-point vector [lambda; Y] without communication.
#pragma once

#include <cstddef>
#include <functional>
#include <span>
#include <string_view>
#include <vector>

#include "gmres.hpp"
#include "rpyfmm/rpy/geometry.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

namespace rpyfmm::rpy::rigid_detail {

/// The bodies of one configuration (body k holds beads offsets[k] .. offsets[k + 1] - 1).
struct BodySystem {
  std::vector<std::size_t> offsets;        // m + 1 entries; empty: not configured
  std::vector<double> arms;                // (r_i - q_k) / l_k (minimum image), 3N
  std::vector<double> scale;               // l_k: body k's RMS lever arm (rotations in length units)
  std::vector<double> reference;           // q_k, 3m
  std::vector<std::size_t> factor_offset;  // body k's Cholesky factor of M_kk at factors[factor_offset[k]]
  std::vector<double> factors;             // lower triangles, column-major (3 n_k)^2 each
  std::vector<double> minv_k;              // M_kk^{-1} K_k (3 n_k x 6, column-major) per body
  std::vector<double> body_mobility;       // N_k (6x6 row-major) per body
  int mobility_exponent = 0;               // e: the system is solved in units of 2^e ~ 1 / (6 pi eta a_max)

  [[nodiscard]] std::size_t bodies() const { return offsets.empty() ? 0 : offsets.size() - 1; }
  [[nodiscard]] std::size_t beads() const { return offsets.empty() ? 0 : offsets.back(); }
};

/// Throws invalid_argument naming `where` unless tolerance lies in (0, 1), max_iterations > 0 and
/// restart > 0.
void require_options(const RigidBodyOptions& options, std::string_view where);

/// Throws rpyfmm::Error naming `where` unless the beads (3 coordinates each, n of them), the body
/// offsets (0 to n, at least 3 beads per body) and the reference points (3 per body, or none) fit
/// together, and (with `precondition`) the dense body blocks fit in `max_preconditioner_bytes`.
/// `allow_no_bodies`: offsets {0} (no body, no bead) are accepted, as on a rank without bodies.
void require_bodies(std::span<const double> bead_positions, std::size_t n, std::span<const std::size_t> body_offsets,
                    std::span<const double> reference_points, const RigidBodyOptions& options, bool allow_no_bodies,
                    std::string_view where);

/// The exponent e of the mobility scale 2^e, the power of two at or below 1 / (6 pi eta a_max)
/// (the self mobility of the largest bead), clamped to [-900, 900]. The saddle-point system is
/// solved with bead forces in units of 2^-e (docs/theory/rigid.md Sec. 2, "Units"). Every MPI rank
/// passes the same eta and the largest radius over all ranks, so all get the same e.
int mobility_scale_exponent(double eta, double largest_radius);

/// The frames (reference points, lever arms and their scale) of bodies whose layout passed
/// require_bodies and whose positions and radii the bead operator accepted, the mobility scale's
/// exponent (mobility_scale_exponent(eta, largest_radius)), and with `precondition` the body-block
/// factors (bead blocks M_kk by the RPY tensor with viscosity `eta`). Throws invalid_input naming
/// `where` for beads on one line and singular bead blocks.
BodySystem make_body_system(std::span<const double> bead_positions, std::span<const double> radii,
                            std::span<const std::size_t> body_offsets, std::span<const double> reference_points,
                            const Geometry& geometry, double eta, double largest_radius, bool precondition,
                            std::string_view where);

/// Throws invalid_input naming `where` unless forces_torques and velocities have 6 entries per body
/// of `s`, bead_forces 3 per bead or none, and forces_torques are finite.
void require_call(const BodySystem& s, std::span<const double> forces_torques, std::span<double> velocities,
                  std::span<double> bead_forces, std::string_view where);

/// Throws invalid_input naming `where` unless the guesses of apply_from have 6 finite entries per
/// body (velocities) and 3 finite entries per bead (bead forces) of `s`.
void require_guesses(const BodySystem& s, std::span<const double> guess_velocities,
                     std::span<const double> guess_bead_forces, std::string_view where);

/// Throws naming `where` unless the bead noise z has 3 finite entries per bead of `s`
/// (invalid_input) and noise_scale is finite and >= 0 (invalid_argument).
void require_noise(const BodySystem& s, std::span<const double> z, double noise_scale, std::string_view where);

/// y = M x on the beads of `s` (3 entries per bead each).
using BeadProduct = std::function<void(std::span<const double> x, std::span<double> y)>;

/// The saddle-point solution x = [lambda; U_k, Omega_k l_k] of the system with bead rows b[0, 3N)
/// given (the slip) and body rows from forces_torques, started from the guesses (empty: zero), by
/// GMRES with `inner_product` (empty: sequential sums) and the body-block preconditioner of `s`
/// where options.precondition.
struct SaddleSolution {
  GmresResult gmres;
  std::vector<double> x;
};
SaddleSolution solve_saddle_point(const BodySystem& s, const BeadProduct& beads, const RigidBodyOptions& options,
                                  std::span<const double> forces_torques, std::vector<double>& b,
                                  std::span<const double> guess_velocities, std::span<const double> guess_bead_forces,
                                  const InnerProduct& inner_product = {});

/// Throws numerical_failure naming `where` when GMRES did not converge or x is not finite;
/// otherwise writes the velocities (U_k, Omega_k) and, unless empty, the bead forces lambda, and
/// returns the report's iterations, restarts and residual.
RigidBodyReport finish_solve(const BodySystem& s, const SaddleSolution& solution, const RigidBodyOptions& options,
                             std::span<double> velocities, std::span<double> bead_forces, std::string_view where);

/// Throws invalid_argument naming `where` when the mobility matrix of m bodies (6m solves) is asked
/// for with more than max_bodies bodies.
void require_matrix_bodies(std::size_t m, std::size_t max_bodies, std::string_view where);

/// Writes column c of the body mobility matrix (6m entries: the velocities under a unit force or
/// torque c, one solve).
using MobilityColumn = std::function<void(std::size_t c, std::span<double> column)>;

/// The body mobility matrix N (n x n row-major, n = 6m) from its n columns, computed in order
/// c = 0 ... n - 1, then symmetrized: N_rc = N_cr = (N_rc + N_cr) / 2, so N = N^T exactly (the
/// solves leave an asymmetry of about the GMRES tolerance).
std::vector<double> symmetric_mobility_matrix(std::size_t n, const MobilityColumn& column);

}  // namespace rpyfmm::rpy::rigid_detail
