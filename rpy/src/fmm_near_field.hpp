// The exact near field of FmmRpy: the translational and grand-mobility RPY pair blocks summed over
// the leaf pairs that a Laplace FMM planned with FmmOptions::near_field = false leaves to its caller
// (docs/theory/rpy.md; Guan, dissertation, §3.1 and Algorithm 2). Shared by rpy::FmmRpy and, on
// each owner's locally essential particles, by mpi::DistributedFmmRpy (docs/mpi.md, "Distributed
// FmmRpy").
#pragma once

#include <cstddef>
#include <span>

#include "near_schedule.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

namespace rpyfmm::rpy::detail {

/// The schedule of a near field's leaf pairs: each adjacent leaf pair once for both directions
/// where the near field's targets are its sources (same_points) and the tree has enough leaves to
/// keep every colour busy (64; a property of the tree only, so results stay thread-invariant),
/// every pair one-sided otherwise.
[[nodiscard]] NearSchedule near_schedule_for(const fmm::NearField& near, bool same_points);

/// A near field and the points of its numbering: source j of the near field is point j, and a
/// target index i names point i too (its position, radius and load), so a target never pairs with
/// itself. A target of the near field must therefore be one of its numbered points; with
/// schedule built with same_points the sources are the targets.
struct NearPoints {
  const fmm::NearField& near;
  const NearSchedule& schedule;
  std::span<const double> x, a;  // 3n positions and n radii in the units of the blocks
  std::size_t n = 0;             // points numbered (the stride of one right-hand side's loads)
  bool equal = true;             // every radius is a[0] (the equal-radii kernels)
  bool self_terms = true;        // add M_ii to every target (once over all near fields of a target)
};

/// Adds eta^-1 sum_j M_ij F_j over the near field's pairs (and the self terms where asked) to the
/// velocities, for nrhs right-hand sides of 3n forces and velocities each, one after another.
/// Each velocity receives its contributions in a fixed order (NearSchedule).
void add_near_velocities(const NearPoints& points, const double* forces, double* velocities, std::size_t nrhs,
                         double inv_eta);

/// Adds the grand-mobility sums (times eta; translational and rotational blocks, self terms
/// F_i / (6 pi a_i) and T_i / (8 pi a_i^3) where asked) of the loads [F; T] (6n: forces, then
/// torques in the units of rotation_pair_sums.hpp) to u (velocities) and w (angular velocities),
/// 3n each.
void add_grand_near_field(const NearPoints& points, const double* loads, double* u, double* w);

/// Adds the rotational near sums alone (times eta: the couplings of the torques to U, of the forces
/// and torques to W, rotation_pair_sum, and the self terms T_i / (8 pi a_i^3) where asked) of the
/// loads [F; T] to u and w, 3n each: with add_near_velocities for the translational blocks, the
/// grand product whose U with zero torques is add_near_velocities' bit for bit. The schedule must be
/// one-sided (near_schedule_for(near, false)).
void add_rotation_near_field(const NearPoints& points, const double* loads, double* u, double* w);

}  // namespace rpyfmm::rpy::detail
