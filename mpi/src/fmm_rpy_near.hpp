// rpyfmm — the exact near field of DistributedFmmRpy (docs/mpi.md, "Distributed FmmRpy"): on each
// owner, the near pairs that its serial Laplace FMM (planned with near_field = false and
// export_direct_far, so its W/X leaf pairs among them) leaves out between particles, owned or
// halo, summed as RPY blocks by FmmRpy's own code (rpy/src/fmm_near_field.hpp): the pairs of owned
// particles once for both directions (as FmmRpy at its own points), the halo particles on the owned
// ones one-sided; and the velocities moved back to the input ranks.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "near_schedule.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"

namespace rpyfmm::mpi::detail {

/// One of the near field's exchanges on this rank: wall time (packing, MPI calls and waits) and
/// bytes received (this rank's own share of a partition's move included, as SfcPartition counts it).
struct RpyNearExchange {
  double seconds = 0.0;
  std::uint64_t bytes_received = 0;
};

class RpyNearField {
 public:
  /// Collective. On the plan of `laplace` (near_field = false, min_leaf_side = 2 a_max), with this
  /// rank's radii in input order (in the far field's units); equal: every radius of every rank is
  /// `radius` (no exchange). The plan must outlive this object (a later set_points replaces both).
  RpyNearField(const Communicator& comm, const DistributedLaplaceFmm& laplace, std::span<const double> local_radii,
               bool equal, double radius);

  /// Collective. Adds eta^-1 sum_j M_ij F_j over the near pairs, self terms included, to this
  /// rank's velocities (input order, 3n per right-hand side, nrhs of them): the forces of each
  /// right-hand side k are the densities k per_rhs + (0, 1, 2) of `essential` (the essential
  /// charges of DistributedLaplaceFmm::evaluate).
  void add_velocities(const std::vector<double>& essential, std::size_t per_rhs, std::size_t nrhs, double inv_eta,
                      std::span<double> local_u) const;

  /// Collective. The grand-mobility near sums of forces (densities 0..2 of `essential`) and torques
  /// (per_rhs + (0, 1, 2)): adds the translational blocks' eta^-1 M F to u as add_velocities does
  /// (so that with zero torques u gets the same bits), and the rotational sums (times eta, self
  /// terms included) to ut (U from the torques) and w (input order, 3n each).
  void add_grand(const std::vector<double>& essential, std::size_t per_rhs, double inv_eta, std::span<double> local_u,
                 std::span<double> local_ut, std::span<double> local_w) const;

  /// The halo particles of this rank's near field (received with their loads in each product).
  [[nodiscard]] std::size_t halo_size() const { return particles_ - owned_; }
  /// The radii to the owners and to the ranks holding them as halo, in the construction (none with
  /// equal radii); the velocities back to the input ranks, in the last product.
  [[nodiscard]] const RpyNearExchange& setup() const { return setup_; }
  [[nodiscard]] const RpyNearExchange& back() const { return back_; }
  /// Wall time of the last product's near sums on this rank (the loads gathered and the RPY blocks
  /// summed; no exchange).
  [[nodiscard]] double sums_seconds() const { return sums_seconds_; }

 private:
  // A near field over the particles (its sources renumbered as particles, nodes left out): one
  // serial FMM's, or its owned or its halo sources alone.
  struct Piece {
    fmm::NearField near;
    rpy::detail::NearSchedule schedule, one_sided;  // the translational sums', the rotational ones'
  };
  // Appends a piece, scheduled once per leaf pair for both directions where same_points (its
  // sources are its targets).
  void add_piece(fmm::NearField near, bool same_points);
  // The loads of the particles (width per particle, one block of 3 columns per density triple
  // `first`) gathered from the essential charges.
  [[nodiscard]] std::vector<double> gather_loads(const std::vector<double>& essential,
                                                 std::span<const std::size_t> first) const;
  // Adds the translational near sums of one right-hand side's forces (3 particles_) to `velocities`.
  void translational_sums(const double* forces, double inv_eta, double* velocities) const;
  // Moves `columns` blocks of 3 values per owned particle (each block particles_ x 3 long) back to
  // the input ranks and adds them to `to` (blocks of 3n).
  void add_back(const std::vector<double>& owned, std::size_t blocks, std::span<double* const> to) const;

  const DistributedLaplaceFmm::Plan* plan_ = nullptr;  // the Laplace FMM's, which outlives this
  std::vector<Piece> pieces_;
  std::vector<std::size_t> essential_of_;  // per particle (owned, then halo), its essential index
  std::vector<double> x_, a_;              // per particle, position and radius
  std::size_t owned_ = 0, particles_ = 0, essential_ = 0;
  bool equal_ = true;
  RpyNearExchange setup_;
  mutable RpyNearExchange back_;
  mutable double sums_seconds_ = 0.0;
};

}  // namespace rpyfmm::mpi::detail
