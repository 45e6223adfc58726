// rpyfmm — DistributedPseRpy: the periodic RPY mobility U = M F by Positively Split Ewald
// (rpyfmm/rpy/pse/pse_rpy.hpp; Fiore, Balboa Usabiaga, Donev & Swan, J. Chem. Phys. 146, 124116
// (2017), "[PSE]"; docs/theory/pse.md) on particles distributed over the ranks of an MPI
// communicator (docs/mpi.md, "Distributed PSE").
//
// Each rank passes its own particles (its local N may be 0) and receives the velocities of its own
// particles in input order. The global particle set is the concatenation of the ranks' shares in
// rank order; the operator uses the parameters rpyfmm::rpy::pse::PseRpy chooses for that whole set
// (splitting xi, grid, Gaussian support, real-space cutoff), and its result equals PseRpy's on the
// whole set to round-off (the same sums, added in another order).
//
// Memory: PseOptions::max_memory_bytes is the memory one rank may use (docs/mpi.md, "Distributed
// PSE"). The parameter choice is PseRpy's with P x max_memory_bytes (the P ranks together) as the
// budget of the whole grid, on one rank PseRpy's exactly; then each rank's own need, its slab of
// the grid as FFTW-MPI's local size gives it (with c(k)) and its particles' windows as PseRpy's
// estimate counts them, must fit in max_memory_bytes, and the pair cache is kept within what is
// left beside it (memory_bytes()).
//
// How ([PSE] eq. 10 and 19): M = M_r + M_w.
//  - M_w: the grid is split into slabs of x planes by FFTW-MPI. Each particle's position goes, once
//    per set_positions, to the ranks whose slabs its Gaussian window touches; in apply its force
//    follows, each slab owner spreads onto its own planes, the transforms and the scaling run on the
//    slabs, and each slab owner sends back its planes' share of the interpolation, which the
//    particle's rank adds up in rank order.
//  - M_r (with the self term): each rank receives the other ranks' particles within r_cut of the
//    box of its own particles (a halo, positions once per set_positions, forces in every apply) and
//    runs the serial real-space sum on its particles and the halo, keeping its own rows.
//  - with rotation ([U; W] = M [F; T], PseRpy's grand mobility; docs/theory/pse.md Sec. 5): the
//    torques travel with the forces to the slabs and the halo; the slab owners spread them onto a
//    second set of slabs and scale both spectra mode by mode as PseRpy does (rotation_modes), and
//    each rank adds the rotational real-space blocks over the same neighbour lists of its particles
//    and halo (PseRpy's RotationRealSpaceSum). Equal to PseRpy's product with rotation on the whole
//    set (double grids) to round-off, as U = M F is.
//  - sample(): PseRpy's split sampler ([PSE] eqs. 17-21), Lanczos on M_r with inner products over
//    all ranks and the wave-space noise drawn mode by mode on the slabs.
//  - apply_sqrt_rotation(): the same split sampler on the grand mobility, as PseRpy's: Lanczos on
//    S M_r S (S = diag(I, a I)) with z = [z_t; z_r] on a basis of two segments (translations, then
//    rotations), and the wave noise of the translational field z2 keyed by the hash of the whole z,
//    scaled per mode with rotation on the slabs, so that its translational part is apply_sqrt's
//    wave noise for the same key.
//
// Every public call is collective over the communicator and fails collectively
// (communicator.hpp): a bad input on one rank makes every rank throw the same rpyfmm::Error.
#pragma once

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/mpi/communication_stats.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/rpy/geometry.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::mpi {

/// What one rank exchanged in the last set_positions (counts of particles): the positions it sent to
/// other ranks' slabs and received for its own slab, and the halo particles it received.
struct PseExchangeCounts {
  std::size_t wave_sent = 0;
  std::size_t wave_received = 0;
  std::size_t halo_received = 0;
};

class DistributedPseRpy {
 public:
  /// Collective. Throws rpyfmm::Error on every rank when any rank passes what PseRpy's constructor
  /// refuses (an open geometry, a viscosity not finite and > 0, a tolerance out of range, ...), or
  /// when the ranks pass different boxes, viscosities or options.
  DistributedPseRpy(MPI_Comm comm, rpy::Geometry geometry, double viscosity, const rpy::pse::PseOptions& options = {});
  ~DistributedPseRpy();
  DistributedPseRpy(const DistributedPseRpy&) = delete;
  DistributedPseRpy& operator=(const DistributedPseRpy&) = delete;

  [[nodiscard]] std::string name() const { return "pse-mpi"; }
  [[nodiscard]] const Communicator& communicator() const;
  [[nodiscard]] double viscosity() const;
  /// The periodic box the operator was built with (the same on every rank).
  [[nodiscard]] const rpy::Geometry& geometry() const;

  /// This rank's number of particles, all ranks' together, this rank's first global index (0 before
  /// set_positions).
  [[nodiscard]] std::size_t local_size() const;
  [[nodiscard]] std::size_t global_size() const;
  [[nodiscard]] std::size_t offset() const;
  /// The parameters PseRpy chooses for the whole set (throws before set_positions). The wave-space
  /// grids are double precision whatever wave_single says (FFTW-MPI's double transforms).
  [[nodiscard]] const rpy::pse::PseParameters& parameters() const;
  [[nodiscard]] const PseExchangeCounts& exchange_counts() const;
  /// This rank's time in the particle exchanges (MPI_Alltoallv of the slabs' and the halo's lists,
  /// waits included) of the last set_positions and of the last product, and the bytes it received
  /// from other ranks in that product. A product is one call of apply, sample, apply_sqrt,
  /// apply_sqrt_rotation or apply_with_noise (with the samplers' Lanczos products inside it);
  /// applies_seconds sums them since the last set_positions. Not counted: FFTW-MPI's transposes
  /// inside the distributed transforms (communication and work in one call), the small collectives
  /// (the load scale, the Lanczos inner products) and the noise hash's messages (its chain, or its
  /// entries sent in global order).
  [[nodiscard]] const CommunicationStats& communication() const;
  /// This rank's memory (bytes) as set_positions checked it against PseOptions::max_memory_bytes:
  /// its slab's three grid components as fftw_mpi_local_size_3d sizes them (with the planes and
  /// padding FFTW asks for) and c(k) of its modes, plus 8 (P_x + P_y + P_z + 8) bytes per particle
  /// of this rank (the windows, as PseRpy's estimate counts them). Not counted, as PseRpy's estimate
  /// does not count them: the torque slabs of the first product with rotation, the neighbour lists,
  /// the halo, and the pair cache (kept only within what the limit leaves beside this). Throws
  /// before set_positions.
  [[nodiscard]] std::size_t memory_bytes() const;

  /// Collective. This rank's positions (3 n, n >= 0) and one radius for them. Positions are wrapped
  /// into the box as PseRpy wraps them. Throws rpyfmm::Error on every rank when any rank's input is
  /// malformed (size not a multiple of 3, NaN/Inf, radius not finite and > 0), when no rank has a
  /// particle, when the radii differ (PSE supports equal radii only, as PseRpy), on what
  /// PseRpy's parameter choice refuses for the whole set (its memory budget that of all ranks
  /// together, P x max_memory_bytes), and with out_of_memory when any rank's memory_bytes() would
  /// exceed max_memory_bytes (the message names the rank of the largest need, its bytes and the
  /// limit). After a failure the operator holds no positions on any rank until a later
  /// set_positions succeeds.
  void set_positions(std::span<const double> local_positions, double radius);
  /// Same with one radius per local particle (n entries, all equal on all ranks).
  void set_positions(std::span<const double> local_positions, std::span<const double> local_radii);

  /// Collective. U = M F for this rank's particles (3 local_size() entries each). Throws
  /// rpyfmm::Error on every rank when positions are not set, or when any rank passes arrays of the
  /// wrong size or forces with NaN/Inf.
  void apply(std::span<const double> local_forces, std::span<double> local_velocities) const;

  /// Collective. [U; W] = M [F; T], the grand mobility with rotation, for this rank's particles:
  /// forces, torques, velocities and angular velocities of 3 local_size() entries each (see the
  /// header comment for how; equal to PseRpy's product with rotation on the whole set, double
  /// grids, to round-off). The first call builds the rotational real-space table and allocates the
  /// torque slabs (PseRpy does the same on its first product with torques). Throws rpyfmm::Error on
  /// every rank when positions are not set, or when any rank passes arrays of the wrong size or
  /// forces or torques with NaN/Inf, and for a product beyond double precision.
  void apply(std::span<const double> local_forces, std::span<const double> local_torques,
             std::span<double> local_velocities, std::span<double> local_angular_velocities) const;
  /// True: the four-argument apply is available (as rpy::MobilityOperator::supports_rotation).
  [[nodiscard]] bool supports_rotation() const { return true; }

  /// Collective. w = M^{1/2} z for this rank's particles (3 local_size() entries) by PseRpy::sample's
  /// split sampler ([PSE] eqs. 17-21): w = M_r^{1/2} z1 + M_w^{1/2} z2, z1 the noise of
  /// (seed, step, stream 1) of each particle by its global index (rpyfmm::mpi::fill_normal), M_r^{1/2}
  /// z1 by Lanczos to the PSE's Lanczos tolerance with inner products over all ranks, z2 the
  /// wave-space field of (seed, step) drawn mode by mode on the slabs. Equal to PseRpy::sample on
  /// the whole set (double grids) to round-off, whatever the partition. Throws rpyfmm::Error on
  /// every rank when positions are not set or any rank's output has the wrong size.
  rpy::SqrtReport sample(std::uint64_t seed, std::uint64_t step, std::span<double> local_w) const;
  /// Collective. PseRpy::apply_sqrt's split sampler (options.method automatic or split) on this
  /// rank's share of z (3 local_size() entries): z is z1, and z2 is keyed by pse::noise_hash of the
  /// whole z, which the ranks compute as a chain over their shares in rank order (point-to-point
  /// messages with tag 19283 on the operator's communicator). Equal to PseRpy::apply_sqrt on the
  /// whole set (double grids) to round-off. Throws rpyfmm::Error on every rank when positions are
  /// not set, any rank's arrays have the wrong size or z has NaN/Inf, or for another method or the
  /// block preconditioner (not_supported: the generic solvers are not offered across ranks).
  rpy::SqrtReport apply_sqrt(std::span<const double> local_z, std::span<double> local_w,
                             const rpy::SqrtOptions& options = {}) const;
  /// Collective. PseRpy::apply_sqrt_rotation's split sampler on the grand mobility (options.method
  /// automatic or split) for this rank's particles (3 local_size() entries each): w' = (S M_r S)^{1/2}
  /// [z_t; z_r] with S = diag(I, a I) by Lanczos to the PSE's Lanczos tolerance (the basis and its
  /// inner products over all ranks, translations then rotations), [w_t; w_r] = S^{-1} w', plus the
  /// wave part's noise with rotation from the translational field z2 keyed by pse::noise_hash of the
  /// whole [z_t; z_r] (all ranks' z_t in rank order, then all ranks' z_r; the chain of apply_sqrt
  /// twice) and step 0. Equal to PseRpy::apply_sqrt_rotation on the whole set (double grids) to
  /// round-off, with the same number of Lanczos iterations. This is what a Brownian dynamics step
  /// with rotation samples besides the grand product apply(F, T, U, W)
  /// (bd::rotational_drift_and_noise). Throws rpyfmm::Error on every rank as apply_sqrt does, for
  /// either noise or output (wrong size, NaN/Inf in z_t or z_r).
  rpy::SqrtReport apply_sqrt_rotation(std::span<const double> local_z_translation,
                                      std::span<const double> local_z_rotation, std::span<double> local_w_translation,
                                      std::span<double> local_w_rotation, const rpy::SqrtOptions& options = {}) const;
  /// Collective. The same with the wave noise keyed by pse::noise_hash of [z_t; z_r] in the global
  /// order `local_indices` gives (local_size() entries, together over all ranks a permutation of
  /// 0 ... N - 1: each below N is checked, and a repeated index fails every rank) instead of the
  /// concatenation of the ranks' shares: the entries are sent once to the ranks holding contiguous
  /// blocks of that order (one MPI_Alltoallv of 7 doubles per particle) and hashed there in order.
  /// Equal to PseRpy::apply_sqrt_rotation on the whole set in that global order (double grids) to
  /// round-off: what DistributedBd's step with rotation samples, its ranks holding stretches of a
  /// space-filling curve.
  rpy::SqrtReport apply_sqrt_rotation(std::span<const double> local_z_translation,
                                      std::span<const double> local_z_rotation,
                                      std::span<const std::uint64_t> local_indices,
                                      std::span<double> local_w_translation, std::span<double> local_w_rotation,
                                      const rpy::SqrtOptions& options = {}) const;
  /// Collective. U = M F + noise_scale M^{1/2} z for this rank's particles, as
  /// PseRpy::apply_with_noise: z as sample(seed, step) draws it, the deterministic and the Brownian
  /// wave parts in one wave-space pass. For BD: noise_scale = sqrt(2 kT / dt). Equal to
  /// PseRpy::apply_with_noise on the whole set (double grids) to round-off. Throws rpyfmm::Error on
  /// every rank as apply() does, and for a noise_scale not finite and >= 0 on any rank.
  rpy::SqrtReport apply_with_noise(std::span<const double> local_forces, double noise_scale, std::uint64_t seed,
                                   std::uint64_t step, std::span<double> local_velocities) const;
  /// Collective. The same with the real-space noise z1 of each particle keyed by the global index
  /// it is given in `local_indices` (local_size() entries, together over all ranks a permutation of
  /// 0 ... N - 1; each below N is checked, the permutation is not) instead of its place in the
  /// concatenation of the ranks' shares: for callers whose global order is not the rank order
  /// (DistributedBd's ranks hold stretches of a space-filling curve). Equal to
  /// PseRpy::apply_with_noise on the whole set in that global order to round-off (the Lanczos
  /// iteration of [PSE] eq. 19 on a permuted system: the same Krylov space, sums in another order).
  rpy::SqrtReport apply_with_noise(std::span<const double> local_forces, double noise_scale, std::uint64_t seed,
                                   std::uint64_t step, std::span<const std::uint64_t> local_indices,
                                   std::span<double> local_velocities) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rpyfmm::mpi
