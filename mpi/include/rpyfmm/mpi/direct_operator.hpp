// rpyfmm — DistributedDirectRpy: the exact O(N^2) RPY mobility U = M F on particles distributed
// over the ranks of an MPI communicator (docs/mpi.md).
//
// Each rank owns a share of the particles (its local N may be 0) and passes its own positions,
// radii and forces; it receives the velocities of its own particles. The global particle order is
// the concatenation of the ranks' shares in rank order. On every rank the result equals, bit for
// bit, what rpyfmm::rpy::DirectRpy gives for these particles on that concatenation (same binary,
// same instruction-set level, rpyfmm/core/simd_dispatch.hpp).
//
// How: every rank keeps only its own particles. In apply() the ranks' source blocks (positions,
// radii and forces) pass by every rank in rank order, one nonblocking broadcast per rank, the next
// block in flight while the current one is summed; each rank adds every block's contribution to its
// own targets in DirectRpy's order (source blocks of 256 counted from the first particle of rank 0).
// apply_block passes the blocks once for nrhs right-hand sides, each block carrying the forces of
// all of them, and evaluates the pair terms of each source block once for all of them.
// Memory per rank: O(largest share); pair work: (local N) x N (docs/mpi.md).
//
// With rotation ([U; W] = M [F; T], docs/theory/rpy.md section 7; Wajnryb, Mizerski, Zuk &
// Szymczak (2013) J. Fluid Mech. 731 R3) the blocks carry the torques as well. DirectRpy sums the
// rotational pair terms of a target (c_ut (T x e) in U; the couplings and h I + k e e^T in W) over
// the same source blocks of 256 in increasing order as the translational ones; here the window of
// sources that completes a block straddling ranks' shares carries the torques too, and every block
// is summed whole by DirectRpy's own rotational block sums. So U and W are DirectRpy's bit for bit
// as well, for every number of ranks and every partition.
//
// Every public call is collective over the communicator and fails collectively
// (communicator.hpp): a bad input on one rank makes every rank throw the same rpyfmm::Error.
#pragma once

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/mpi/communication_stats.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/sampler_blocks.hpp"

namespace rpyfmm::mpi {

class DistributedDirectRpy {
 public:
  /// Collective. Throws rpyfmm::Error (invalid_argument) on every rank when the viscosity of any
  /// rank is not finite and > 0, or when the ranks pass different viscosities.
  explicit DistributedDirectRpy(MPI_Comm comm, double viscosity = 1.0);

  [[nodiscard]] std::string name() const { return "direct-mpi"; }
  [[nodiscard]] const Communicator& communicator() const { return comm_; }
  [[nodiscard]] double viscosity() const { return viscosity_; }

  /// This rank's number of particles (0 before set_positions).
  [[nodiscard]] std::size_t local_size() const { return local_n_; }
  /// The number of particles on all ranks together (0 before set_positions).
  [[nodiscard]] std::size_t global_size() const { return global_n_; }
  /// The global index of this rank's first particle: the sum of the lower ranks' local sizes.
  [[nodiscard]] std::size_t offset() const { return offset_; }
  /// Every rank's local size, by rank (empty before set_positions).
  [[nodiscard]] std::span<const std::size_t> counts() const { return counts_; }
  /// Whether every particle on every rank has the same radius (DirectRpy's equal-radii path).
  [[nodiscard]] bool equal_radii() const { return equal_radii_; }
  /// This rank's time in MPI calls (waits included) during the last set_positions and apply, and the
  /// bytes of other ranks' source blocks it received in the last apply (or apply_block).
  [[nodiscard]] const CommunicationStats& communication() const { return stats_; }
  /// This rank's positions (3 local_size()) and radii (local_size()) as passed to set_positions
  /// (the block preconditioner of mpi::sqrt_apply factors their blocks; empty before).
  [[nodiscard]] std::span<const double> local_positions() const { return positions_; }
  [[nodiscard]] std::span<const double> local_radii() const { return radii_; }
  /// The blocks of the block preconditioner that the samplers (rpyfmm/mpi/sqrt.hpp) built for these
  /// positions, emptied by every set_positions (rpyfmm/mpi/sampler_blocks.hpp); for the samplers.
  [[nodiscard]] const SamplerBlocks& sampler_blocks() const { return sampler_blocks_; }

  /// Collective. This rank's positions (3 n, n >= 0) and one radius for them (> 0, finite; the
  /// ranks may pass different radii). Throws rpyfmm::Error on every rank when any rank's input is
  /// malformed (size not a multiple of 3, NaN/Inf, radius not > 0), when no rank has a particle,
  /// and on what DirectRpy::set_positions refuses for the whole set (a radius below 2^-300 of the
  /// suspension's size, named by its global index). After a failure the operator holds no
  /// positions on any rank until a later set_positions succeeds.
  void set_positions(std::span<const double> local_positions, double radius);
  /// Same with one radius per local particle (n entries, each finite and > 0).
  void set_positions(std::span<const double> local_positions, std::span<const double> local_radii);

  /// Collective. U = M F for this rank's particles: forces and velocities of 3 local_size()
  /// entries each. Throws rpyfmm::Error on every rank when positions are not set, or when any rank
  /// passes arrays of the wrong size or forces with NaN/Inf, and on what DirectRpy::apply refuses
  /// (a product beyond double precision).
  void apply(std::span<const double> local_forces, std::span<double> local_velocities) const;

  /// Collective. [U; W] = M [F; T], the grand mobility with rotation, for this rank's particles:
  /// forces, torques, velocities and angular velocities of 3 local_size() entries each (see the
  /// header comment for how the result compares with DirectRpy's). Throws rpyfmm::Error on every
  /// rank when positions are not set, when a rank holds more than INT_MAX / 10 particles (a source
  /// block with torques beyond MPI's int count: not_supported), or when any rank passes arrays of
  /// the wrong size or forces or torques with NaN/Inf, and on what DirectRpy::apply refuses (a
  /// product beyond double precision).
  void apply(std::span<const double> local_forces, std::span<const double> local_torques,
             std::span<double> local_velocities, std::span<double> local_angular_velocities) const;
  /// Collective. U_r = M F_r for nrhs right-hand sides (r < nrhs) in one pass of the source blocks:
  /// forces and velocities of 3 local_size() nrhs entries each, one right-hand side after another
  /// (rpy::MobilityOperator::apply_block's layout, on this rank's particles). Each block broadcast
  /// carries the forces of every right-hand side, and each source block's pair terms are evaluated
  /// once for all of them. Each right-hand side is load-scaled by itself, so U_r is apply(F_r) bit
  /// for bit (docs/mpi.md). Throws rpyfmm::Error on every rank when positions are not set, when
  /// any rank passes nrhs = 0 or the ranks pass different nrhs, when a source block would exceed
  /// MPI's int count (not_supported: (4 + 3 nrhs) x the largest share > INT_MAX), for wrong sizes
  /// or NaN/Inf forces on any rank, and for a product beyond double precision.
  void apply_block(std::span<const double> local_forces, std::span<double> local_velocities, std::size_t nrhs) const;

  /// True: the four-argument apply is available (as rpy::MobilityOperator::supports_rotation).
  [[nodiscard]] bool supports_rotation() const { return true; }

 private:
  class SourceWindow;

  // Every product: nrhs right-hand sides of forces, or with rotation one of forces and torques
  // (empty torques and angular velocities for U = M F). `where` names the call in errors.
  void product(const char* where, std::size_t nrhs, bool rotation, std::span<const double> local_forces,
               std::span<const double> local_torques, std::span<double> local_velocities,
               std::span<double> local_angular_velocities) const;
  // The load scale exponent of each right-hand side (collective).
  [[nodiscard]] std::vector<int> load_exponents(bool rotation, std::span<const double> local_forces,
                                                std::span<const double> local_torques, std::size_t nrhs) const;
  // This rank's source block as broadcast, one load exponent per right-hand side.
  [[nodiscard]] std::vector<double> packed_block(std::span<const double> local_forces,
                                                 std::span<const double> local_torques,
                                                 std::span<const int> load_exponents) const;
  // Adds the window's first `usable` sources to every own target's sums: acc (3 nrhs per target)
  // and, unless empty, rotation_acc (6 per target: U, W), polling `pending` between batches of
  // targets.
  void sum_block(const SourceWindow& window, std::size_t nrhs, std::size_t usable, std::vector<double>& acc,
                 std::vector<double>& rotation_acc, MPI_Request* pending) const;

  Communicator comm_;
  double viscosity_ = 1.0;
  std::size_t local_n_ = 0;
  std::size_t global_n_ = 0;
  std::size_t offset_ = 0;
  std::vector<std::size_t> counts_;
  // This rank's particles in the length units 2^scale_exponent_ (rpy/src/length_units.hpp), as
  // structure of arrays, with inv_a_ = 1 / a_.
  std::vector<double> x_, y_, z_, a_, inv_a_;
  std::vector<double> positions_, radii_;  // as passed to set_positions
  int scale_exponent_ = 0;
  double largest_radius_ = 0.0;  // of all ranks, for the load scale with rotation
  bool equal_radii_ = true;
  mutable CommunicationStats stats_;
  SamplerBlocks sampler_blocks_;
};

}  // namespace rpyfmm::mpi
