// rpyfmm — DistributedDirectRpy: the exact O(N^2) RPY mobility U = M F on particles distributed
// over the ranks of an MPI communicator (docs/mpi.md).
//
// Each rank owns a share of the particles (its local N may be 0) and passes its own positions,
// radii and forces; it receives the velocities of its own particles. The global particle order is
// the concatenation of the ranks' shares in rank order. On every rank the result equals, bit for
// bit, what rpyfmm::rpy::DirectRpy gives for these particles on that concatenation (same binary,
// same instruction-set level, rpyfmm/core/simd_dispatch.hpp).
//
// How: positions, radii and forces are all-gathered, and every rank sums the rows of its own
// particles with the serial DirectRpy (DirectRpy::apply_rows: each target over all
// sources, with the whole set's length units and load scale). The N^2 pair work is divided by the
// number of ranks; every rank holds O(N) data (docs/mpi.md). The operator also serves as the
// reference that the distributed fast operators are to be checked against.
//
// Every public call is collective over the communicator and fails collectively
// (communicator.hpp): a bad input on one rank makes every rank throw the same rpyfmm::Error.
#pragma once

#include <mpi.h>

#include <cstddef>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"

namespace rpyfmm::mpi {

class DistributedDirectRpy {
 public:
  /// Collective. Throws rpyfmm::Error (invalid_argument) on every rank when the viscosity of any
  /// rank is not finite and > 0, or when the ranks pass different viscosities.
  explicit DistributedDirectRpy(MPI_Comm comm, double viscosity = 1.0);

  [[nodiscard]] std::string name() const { return "direct-mpi"; }
  [[nodiscard]] const Communicator& communicator() const { return comm_; }
  [[nodiscard]] double viscosity() const { return serial_.viscosity(); }

  /// This rank's number of particles (0 before set_positions).
  [[nodiscard]] std::size_t local_size() const { return local_n_; }
  /// The number of particles on all ranks together (0 before set_positions).
  [[nodiscard]] std::size_t global_size() const { return global_n_; }
  /// The global index of this rank's first particle: the sum of the lower ranks' local sizes.
  [[nodiscard]] std::size_t offset() const { return offset_; }
  /// Every rank's local size, by rank (empty before set_positions).
  [[nodiscard]] std::span<const std::size_t> counts() const { return counts_; }

  /// Collective. This rank's positions (3 n, n >= 0) and one radius for them (> 0, finite; the
  /// ranks may pass different radii). Throws rpyfmm::Error on every rank when any rank's input is
  /// malformed (size not a multiple of 3, NaN/Inf, radius not > 0), when no rank has a particle,
  /// and on what DirectRpy::set_positions refuses for the gathered set. After a failure the
  /// operator holds no positions on any rank until a later set_positions succeeds.
  void set_positions(std::span<const double> local_positions, double radius);
  /// Same with one radius per local particle (n entries, each finite and > 0).
  void set_positions(std::span<const double> local_positions, std::span<const double> local_radii);

  /// Collective. U = M F for this rank's particles: forces and velocities of 3 local_size()
  /// entries each. Throws rpyfmm::Error on every rank when positions are not set, or when any rank
  /// passes arrays of the wrong size or forces with NaN/Inf, and on what DirectRpy::apply refuses
  /// (a product beyond double precision).
  void apply(std::span<const double> local_forces, std::span<double> local_velocities) const;

 private:
  void gather_and_set(std::span<const double> local_positions, std::span<const double> local_radii);

  Communicator comm_;
  rpy::DirectRpy serial_;  // the gathered particles; used only while global_n_ > 0
  std::size_t local_n_ = 0;
  std::size_t global_n_ = 0;
  std::size_t offset_ = 0;
  std::vector<std::size_t> counts_;
  // MPI_Allgatherv's counts and displacements, in doubles, for 3-vectors per particle and for
  // one value per particle.
  std::vector<int> counts3_, displs3_, counts1_, displs1_;
};

}  // namespace rpyfmm::mpi
