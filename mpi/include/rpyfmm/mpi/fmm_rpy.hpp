// rpyfmm — DistributedFmmRpy: the RPY mobility U = M F by the Laplace FMM on particles distributed
// over the ranks of an MPI communicator (docs/mpi.md, "Distributed FmmRpy").
//
// For every pair that does not overlap (r >= a_i + a_j) the RPY block is a combination of Laplace
// sums of four densities (seven with different radii) and their gradients and Hessians
// (docs/theory/rpy.md; Zuk, Wajnryb, Mizerski & Szymczak, J. Fluid Mech. 741, R5 (2014), eq. (10);
// Guan, dissertation, Algorithm 2). The operator evaluates those sums over the far pairs with
// DistributedLaplaceFmm, combines them as the serial FmmRpy does, and sums the near pairs on each
// owner as exact RPY blocks with FmmRpy's own near-field code: the pairs of the owner's serial FMM
// leaves that it leaves out (near_field = false; its W/X leaf pairs among them, export_direct_far,
// as in FmmRpy) between its particles and the halo particles received with their loads, and the
// self terms I / (6 pi eta a_i). Leaves at least 2 a_max wide
// and no compressed cell within 2 a_max of a rank's region put every overlapping pair (r < a_i +
// a_j, coincident points included) there.
//
//   DistributedFmmRpy op(MPI_COMM_WORLD, viscosity, {.tolerance = 1e-6});  // collective
//   op.set_positions(local_x, local_radii);   // collective: plans once
//   op.apply(local_f, local_u);               // collective, any number of times
//   op.apply(local_f, local_t, local_u, local_w);  // with torques and angular velocities
//   op.apply_block(local_fs, local_us, nrhs);  // nrhs right-hand sides in one Laplace evaluation
//
// With rotation, [U; W] = M [F; T] (the grand mobility of Wajnryb, Mizerski, Zuk & Szymczak,
// J. Fluid Mech. 731, R3 (2013)): the far form of the rotational blocks is exactly the harmonic
// fields curl Phi / (8 pi eta) and grad div Phi_T / (16 pi eta) (docs/theory/rpy.md, section 7), so
// the same Laplace evaluation carries the three torque components beside the translational
// densities, as in FmmRpy, and the near pairs are summed with the exact grand blocks.
//
// Contract: on every rank the relative l2 error of U over all particles against the exact product
// (rpy::DirectRpy on the concatenation of the ranks' shares) is at most the tolerance, and with
// rotation that of U and that of W each (tested at 1e-3, 1e-6 and 1e-9). Results are deterministic:
// the same input on the same number of ranks gives the same bits, whatever the thread count; a
// different number of ranks gives other bits within the contract.
//
// communication() reports this rank's time in MPI exchanges of set_positions and of the last
// product (the Laplace FMM's and the near field's), the bytes received in it, and the sum over the
// products since set_positions (a sampler's), as DistributedDirectRpy's does.
//
// Every public call is collective and fails collectively (communicator.hpp).
#pragma once

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"
#include "rpyfmm/mpi/sampler_blocks.hpp"

namespace rpyfmm::mpi {

namespace detail {
class RpyNearField;
}

/// Options of DistributedFmmRpy. Every rank must pass the same.
struct DistributedFmmRpyOptions {
  /// Requested relative l2 error of U against the exact product, in [1e-12, 1e-1] (as FmmRpy's).
  double tolerance = 1e-6;
  /// Particles per leaf of each owner's serial Laplace FMM, an owned particle counted once
  /// (DistributedFmmOptions::count_owned_once); 0 = FmmRpy's automatic capacity.
  int leaf_capacity = 0;
  /// DistributedFmmOptions::separation and cell_capacity of the Laplace FMM (0 = automatic).
  double separation = 0.0;
  std::size_t cell_capacity = 0;
  /// DistributedFmmOptions::overlap_exchange of the Laplace FMM: its serial FMM split to run during
  /// the exchanges of the essential charges (docs/mpi.md).
  bool overlap_exchange = false;
  /// DistributedFmmOptions::curve: the space-filling curve of the partition (docs/mpi.md).
  SfcCurve curve = SfcCurve::morton;
};

/// This rank's exchanges, as DistributedDirectRpy's CommunicationStats (docs/mpi.md, "Distributed
/// FmmRpy"). Seconds are wall time of the exchanges (packing, MPI calls and waits, as
/// FmmCommunication times them): in the last set_positions the gathers of the counts and the
/// summaries, the Laplace FMM's plan (its plan_seconds) and the near field's radii (to the owners
/// and the halo; none with equal radii); in the last apply, apply_block or apply with torques that
/// completed its exchanges, the load scale's reduction, the Laplace FMM's evaluation (its
/// evaluate_seconds, which moves the halo particles' loads among the essential charges) and the
/// near field's velocities back to the input ranks. applies_seconds sums apply_seconds over every
/// such product since the last set_positions (a sampler's many products), in their order. Bytes
/// received in the last product: the Laplace FMM's evaluate_bytes_received plus the near field's
/// velocities back (3 doubles per particle and right-hand side, 6 with torques; this rank's own
/// share of the partition's move included, as in FmmCommunication). The near_ entries are the near
/// field's share. near_sums_seconds is local work, not an exchange: this rank's wall time of the
/// last product's near sums (the RPY blocks of its near pairs and the self terms).
struct FmmRpyCommunication {
  double set_positions_seconds = 0.0;
  double apply_seconds = 0.0;
  std::uint64_t apply_bytes_received = 0;
  double applies_seconds = 0.0;
  double near_set_positions_seconds = 0.0;
  std::uint64_t near_set_positions_bytes_received = 0;
  double near_apply_seconds = 0.0;
  std::uint64_t near_apply_bytes_received = 0;
  double near_sums_seconds = 0.0;
};

class DistributedFmmRpy {
 public:
  /// Collective. Throws rpyfmm::Error (invalid_argument) on every rank when the viscosity of any
  /// rank is not finite and > 0, the tolerance lies outside [1e-12, 1e-1], the leaf capacity is
  /// negative, or the ranks pass different viscosities or options.
  DistributedFmmRpy(MPI_Comm comm, double viscosity = 1.0, const DistributedFmmRpyOptions& options = {});
  ~DistributedFmmRpy();
  DistributedFmmRpy(DistributedFmmRpy&&) noexcept;
  DistributedFmmRpy& operator=(DistributedFmmRpy&&) noexcept;

  [[nodiscard]] std::string name() const { return "fmm-mpi"; }
  [[nodiscard]] const Communicator& communicator() const { return comm_; }
  [[nodiscard]] double viscosity() const { return viscosity_; }
  [[nodiscard]] const DistributedFmmRpyOptions& options() const { return options_; }

  /// This rank's particles, all ranks' together, the global index of this rank's first particle
  /// (the ranks' shares concatenated in rank order) and every rank's count (0 / empty before
  /// set_positions).
  [[nodiscard]] std::size_t local_size() const { return local_n_; }
  [[nodiscard]] std::size_t global_size() const { return global_n_; }
  [[nodiscard]] std::size_t offset() const { return offset_; }
  [[nodiscard]] std::span<const std::size_t> counts() const { return counts_; }
  /// Whether every particle on every rank has the same radius (four Laplace densities, not seven).
  [[nodiscard]] bool equal_radii() const { return equal_radii_; }
  /// This rank's positions (3 local_size()) and radii (local_size()) as passed to set_positions
  /// (the block preconditioner of mpi::sqrt_apply factors their blocks; empty before).
  [[nodiscard]] std::span<const double> local_positions() const { return positions_; }
  [[nodiscard]] std::span<const double> local_radii() const { return radii_; }
  /// The blocks of the block preconditioner that the samplers (rpyfmm/mpi/sqrt.hpp) built for these
  /// positions, emptied by every set_positions (rpyfmm/mpi/sampler_blocks.hpp); for the samplers.
  [[nodiscard]] const SamplerBlocks& sampler_blocks() const { return sampler_blocks_; }
  /// The halo particles of this rank's near field: received as particles, with their loads in
  /// each product (0 before set_positions).
  [[nodiscard]] std::size_t halo_size() const;
  /// The Laplace FMM of the far field (and of the halo loads): its plan's and last evaluation's
  /// communication and work.
  [[nodiscard]] const DistributedLaplaceFmm& laplace() const { return laplace_; }
  /// This rank's exchanges in set_positions and the products (zero before set_positions; reset by
  /// each set_positions).
  [[nodiscard]] const FmmRpyCommunication& communication() const { return stats_; }

  /// Collective. This rank's positions (3n, n >= 0) and one radius for them (> 0, finite; ranks may
  /// pass different radii), or one radius per particle. Throws rpyfmm::Error on every rank when
  /// any rank's input is malformed (size, NaN/Inf, radius not > 0), when no rank has a particle,
  /// on what rpy::FmmRpy refuses for the whole set (a radius below 2^-300 of the suspension's size,
  /// named by its global index). After a failure the operator holds no positions on any rank until
  /// a later set_positions succeeds.
  void set_positions(std::span<const double> local_positions, double radius);
  void set_positions(std::span<const double> local_positions, std::span<const double> local_radii);

  /// Collective. U = M F for this rank's particles (3 local_size() entries each, input order).
  /// Throws rpyfmm::Error on every rank before set_positions, for wrong sizes or NaN/Inf forces on
  /// any rank, and for a product beyond double precision.
  void apply(std::span<const double> local_forces, std::span<double> local_velocities) const;

  /// Collective. U_r = M F_r for nrhs right-hand sides (r < nrhs), forces and velocities of
  /// 3 local_size() nrhs entries each, one right-hand side after another
  /// (rpy::MobilityOperator::apply_block's layout, on this rank's particles): the densities of every
  /// right-hand side in one Laplace evaluation, and one move of the near field's velocities back for
  /// all of them. Each right-hand side is load-scaled by itself; the Laplace FMM treats each density
  /// alike whatever their number and the near field sums each right-hand side as apply does, so U_r
  /// is apply(F_r) bit for bit (tested; docs/mpi.md). Throws rpyfmm::Error on every
  /// rank before set_positions, when any rank passes nrhs = 0 or the ranks pass different nrhs, for wrong sizes or
  /// NaN/Inf forces on any rank, and for a product beyond double precision.
  void apply_block(std::span<const double> local_forces, std::span<double> local_velocities, std::size_t nrhs) const;

  /// The grand mobility with rotation (rpy::MobilityOperator::apply's).
  [[nodiscard]] bool supports_rotation() const { return true; }
  /// Collective. [U; W] = M [F; T] for this rank's particles (3 local_size() entries each, input
  /// order). Throws rpyfmm::Error on every rank before set_positions, for wrong sizes or NaN/Inf
  /// forces or torques on any rank, and for a product beyond double precision.
  void apply(std::span<const double> local_forces, std::span<const double> local_torques,
             std::span<double> local_velocities, std::span<double> local_angular_velocities) const;

 private:
  // U = M F for nrhs right-hand sides (nrhs agreed); `where` names the call in errors.
  void product(const char* where, std::span<const double> local_forces, std::span<double> local_velocities,
               std::size_t nrhs) const;
  // The statistics of a product whose exchanges completed: `reduction_seconds` of the load scale's
  // MPI_Allreduce, the Laplace evaluation's and the near field's.
  void record_product(double reduction_seconds) const;

  Communicator comm_;
  double viscosity_ = 1.0;
  DistributedFmmRpyOptions options_;
  DistributedFmmOptions laplace_options_;  // of the far field; min_leaf_side and leaves per configuration
  DistributedLaplaceFmm laplace_;
  std::unique_ptr<detail::RpyNearField> near_;  // on laplace_'s plan
  std::size_t local_n_ = 0, global_n_ = 0, offset_ = 0;
  std::vector<std::size_t> counts_;
  // This rank's particles in the frame of the far field (rpy/src/length_units.hpp, to_fmm_frame):
  // centred positions, or positions and radii in units of 2^scale_exponent_.
  std::vector<double> x_, a_;
  std::vector<double> positions_, radii_;  // as passed to set_positions
  int scale_exponent_ = 0;
  double largest_radius_ = 0.0;  // of all ranks, as passed (the load scale of torques)
  bool equal_radii_ = true;
  mutable FmmRpyCommunication stats_;
  SamplerBlocks sampler_blocks_;
};

}  // namespace rpyfmm::mpi
