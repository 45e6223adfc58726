// rpyfmm — DistributedLaplaceFmm: the Laplace FMM (rpyfmm/fmm/laplace_fmm.hpp) on sources
// distributed over the ranks of an MPI communicator, evaluated at every rank's own sources or at
// targets distributed independently of them (docs/mpi.md, "Distributed Laplace FMM").
//
//   phi(x) = sum_j q_j / |x - y_j|  and its gradient and Hessian, over all ranks' sources y_j
//   (pairs at distance 0 skipped).
//
// Plan once, evaluate many times, as the serial LaplaceFmm:
//   DistributedLaplaceFmm fmm(MPI_COMM_WORLD, {.fmm = {.tolerance = 1e-6}});  // collective
//   fmm.set_points(local_sources);                          // collective: builds the plan
//   fmm.evaluate(local_charges, nd, outputs, local_results); // collective, any number of times
//
// How: the sources are partitioned along a space-filling curve (SfcPartition; Morton by default, or
// Hilbert) and each owner builds a tree of cells over its key range. Every rank covers its targets'
// region by a few tight boxes and sends the cover only to the ranks whose root cell it does not
// compress as a whole (decided from an all-gather of the root cells); for each rank whose cover it
// receives it walks its cells top down (for the others it sends its root cell compressed) and sends
// a cell that is well separated from that rank's region, where the p^3 nodes its distance needs are
// fewer than its particles, as equivalent charges at the tensor Chebyshev nodes of the cell's cube
// (the anterpolation of the black-box FMM, Fong & Darve, J. Comput. Phys. 228 (2009) 8712, Sec. 2);
// other cells are opened, and leaves not compressed are sent as their particles (halo). The
// geometry of this locally essential tree is exchanged once in set_points; every evaluate sends
// only the equivalent and halo charges (one MPI_Alltoallv). Each owner then runs the serial
// LaplaceFmm, planned once, on its own sources + halo sources + equivalent nodes, with its owned
// targets (its own sources, or the targets' own partition, or the targets partitioned by the
// sources' cuts: targets_follow_sources), and the results go back to the input ranks and order.
//
// Every public call is collective and fails collectively (communicator.hpp).
#pragma once

#include <mpi.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/partition.hpp"

namespace rpyfmm::mpi {

/// Options of the distributed plan. Every rank must pass the same.
struct DistributedFmmOptions {
  /// The serial FMM that every rank runs on its locally essential sources (tolerance, leaf capacity,
  /// order, ...). A min_leaf_side > 0 also keeps every cell closer than it to a rank's region from
  /// being compressed for that rank, so that pairs closer than it are summed exactly, as in the
  /// serial FMM's near field. near_field = false (for DistributedFmmRpy, which sums them as RPY
  /// blocks): the owners' serial FMMs leave out the pairs of their near fields between particles
  /// (owned or halo) and sum only their near pairs with equivalent nodes; the results then lack
  /// those pairs. export_direct_far (only with near_field = false): the W/X leaf pairs that the
  /// serial FMM would sum directly join its near field (fmm::NearField::pairs) and are treated as
  /// near pairs, those between particles left out, those with equivalent nodes summed.
  fmm::FmmOptions fmm{};
  /// With fmm.leaf_capacity > 0: where an owner's serial FMM runs at its owned sources as separate
  /// targets (it received halo sources or equivalent nodes), whose tree counts a leaf's sources
  /// and targets together, the capacity and the fitted grid's occupancy and point counts are
  /// doubled, so that an owned particle, a source and a target, counts once, as in the serial FMM
  /// at its own points: leaves with the owned particles split as on one rank (halo-only leaves
  /// split at twice the capacity). Off: the serial FMM's own count. DistributedFmmRpy sets it
  /// (docs/mpi.md, "Distributed FmmRpy").
  bool count_owned_once = false;
  /// Acceptance ratio eta: a cell whose cube (around its particles' tight box, half-side h) lies at a
  /// distance d >= eta h from every box of another rank's region may be sent to it as equivalent
  /// charges, with the Chebyshev order its own ratio d / h needs (chebyshev_order_for). 0 = automatic
  /// (kDefaultSeparation).
  double separation = 0.0;
  /// > 0: this Chebyshev order for every compressed cell instead of the rule (for measuring the
  /// compression error); 0 = the rule.
  int chebyshev_order = 0;
  /// Particles per leaf of the tree of cells that decides what is sent (not the serial FMM's tree).
  /// 0 = automatic (kDefaultCellCapacity).
  std::size_t cell_capacity = 0;
  /// Overlap the serial FMM with the exchange of the essential charges: the FMM of the owned
  /// sources at the owned targets (its tree, M2L and P2P among them) runs while the halo and
  /// equivalent charges travel, and the FMM of the received sources at the same targets after
  /// they arrived; the two sum to the same contract. It costs a second tree and a second pass over
  /// the targets' leaves, so it pays only where the exchanges take longer than that pass (few
  /// sources per rank, slow networks); off by default (docs/mpi.md, "Overlapping the serial FMM
  /// with the exchanges").
  bool overlap_exchange = false;
  /// Every rank gathers every other rank's cover of its region and walks its cells against each
  /// (O(P) covers and walks per rank). Off (the default): a rank's cover goes only to the ranks
  /// whose cells it needs beyond their root cell, decided from one all-gather of every rank's root
  /// cell (docs/mpi.md, "Distributed Laplace FMM"). Both plans are the same bit for bit; the
  /// gathered one is the reference that the tests compare with.
  bool gather_all_regions = false;
  /// The space-filling curve of the partition of the sources and of the targets (SfcPartition;
  /// docs/mpi.md, "Space-filling-curve partition"). Both meet the same accuracy contract.
  SfcCurve curve = SfcCurve::morton;
  /// Separate targets partitioned by the sources' cuts (SfcPartition::aligned_with) instead of
  /// their own balanced cuts: the owner of a region's sources owns its targets, so a rank's region
  /// is that of its sources and its essential set is built for it. Keys of the targets in the
  /// sources' key cube, a target outside it keyed as its nearest boundary cell. The load balance is
  /// then the sources': a rank with few sources and many targets gets all of those targets
  /// (docs/mpi.md, "Distributed Laplace FMM"). No effect where the results are at the sources.
  bool targets_follow_sources = false;
};

/// The acceptance ratio used when DistributedFmmOptions::separation is 0.
inline constexpr double kDefaultSeparation = 2.0;
/// The cell capacity used when DistributedFmmOptions::cell_capacity is 0.
inline constexpr std::size_t kDefaultCellCapacity = 32;

/// The Chebyshev order p of a cell at distance eta × its half-side from a rank's region: the
/// smallest p >= 2 with rho^-p <= tolerance / 10, rho = eta + sqrt(1 + eta^2), at most 32
/// (docs/mpi.md, "Error rule").
[[nodiscard]] int chebyshev_order_for(double tolerance, double separation);

/// This rank's share of the work and traffic of the plan and of the last evaluate. Seconds are the
/// wall time of each exchange (packing, MPI calls and waits) or of this rank's named local work;
/// bytes are what this rank received (its own share of the partition's exchanges included).
struct FmmCommunication {
  /// set_points: "partition" (SfcPartition and positions to the owners), "summaries" (the
  /// exchange of the regions: the root cells' all-gather, the requests and the covers),
  /// "geometry" (the locally essential tree's cells and halo).
  StageTimes plan_seconds;
  std::uint64_t plan_bytes_received = 0;
  /// The last evaluate: "charges" (to the owners), "essential" (equivalent and halo charges),
  /// "results" (back to the input ranks).
  StageTimes evaluate_seconds;
  std::uint64_t evaluate_bytes_received = 0;
  /// Local work of the last set_points ("plan_fmm": the serial plan) and evaluate ("anterpolation",
  /// "fmm").
  StageTimes compute_seconds;
  /// The locally essential tree of this rank: particles, equivalent cells and their nodes received
  /// from the other ranks, and what this rank sends to them (counted once per receiving rank).
  std::uint64_t halo_received = 0, cells_received = 0, nodes_received = 0;
  std::uint64_t halo_sent = 0, cells_sent = 0, nodes_sent = 0;
  /// The regions in set_points: the boxes of this rank's cover; the other ranks whose covers it
  /// received (and walked its cells against) and the bytes of those covers (48 per box); the other
  /// ranks it sent its own cover to. With gather_all_regions every other rank with a non-empty
  /// cover counts as received, and every other rank as sent to where this rank's cover is not empty.
  std::uint64_t region_boxes = 0, region_neighbours = 0, region_bytes_received = 0, region_sent_to = 0;
};

class DistributedLaplaceFmm {
 public:
  /// Collective. Throws rpyfmm::Error on every rank for options the serial FMM refuses, for
  /// export_direct_far = true with near_field = true, a separation that is not 0 or in [1, 100], a
  /// Chebyshev order outside [0, 32], and for options that differ between ranks.
  DistributedLaplaceFmm(MPI_Comm comm, const DistributedFmmOptions& options = {});
  ~DistributedLaplaceFmm();
  DistributedLaplaceFmm(DistributedLaplaceFmm&&) noexcept;
  DistributedLaplaceFmm& operator=(DistributedLaplaceFmm&&) noexcept;

  /// Collective. This rank's sources (3n, n >= 0 on any rank), targets (3t) and optional partition
  /// weights of the sources (n entries, finite and >= 0; empty: 1 each, SfcPartition). When no rank
  /// passes a target the results are at the sources (the self pair skipped); when any rank does,
  /// every rank's results are at its own targets (t may be 0), partitioned apart from the sources.
  /// Throws on every rank when any rank's input is malformed (size, NaN/Inf, weights) and when no
  /// rank has a source. After a failure no plan is held on any rank until a later set_points
  /// succeeds.
  void set_points(std::span<const double> local_sources, std::span<const double> local_targets = {},
                  std::span<const double> local_weights = {});

  /// Collective. charges: nd x n (density d at charges[d n + j]); outputs: nd flags
  /// (rpyfmm::fmm::potential | gradient | hessian); results: nd x local_target_size() x 10, as
  /// LaplaceFmm::evaluate, at this rank's targets (or sources) in input order, the sum over all
  /// ranks' sources (pairs at distance 0 skipped). nd and outputs must be the same on every rank. Throws on every rank
  /// for wrong sizes, NaN/Inf charges or bad flags on any rank, or before set_points.
  void evaluate(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                std::span<double> results) const;
  /// The same output flags for every density.
  void evaluate(std::span<const double> charges, std::size_t nd, unsigned outputs, std::span<double> results) const;
  /// Collective. evaluate, also returning this rank's essential charges: nd x essential_size()
  /// (density d of the serial FMM's source j at d essential_size() + j; empty where no serial FMM
  /// runs), for a caller that sums the near field itself (near_field = false; plan()).
  void evaluate(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                std::span<double> results, std::vector<double>& essential_charges) const;

  [[nodiscard]] const Communicator& communicator() const { return comm_; }
  [[nodiscard]] const DistributedFmmOptions& options() const { return options_; }
  /// The acceptance ratio in use.
  [[nodiscard]] double separation() const { return separation_; }
  /// This rank's sources in the last set_points (0 before), the sources it owns after the
  /// partition, and the number on all ranks.
  [[nodiscard]] std::size_t local_size() const;
  [[nodiscard]] std::size_t owned_size() const;
  [[nodiscard]] std::uint64_t global_size() const;
  /// This rank's rows of results (its targets, or its sources when there are none) and the targets
  /// it owns (the owned sources when there are none).
  [[nodiscard]] std::size_t local_target_size() const;
  [[nodiscard]] std::size_t owned_target_size() const;
  /// The serial FMM's sources on this rank: owned + halo + equivalent nodes (0 where it runs no
  /// serial FMM: no owned target or no source to sum).
  [[nodiscard]] std::size_t essential_size() const;
  [[nodiscard]] const FmmCommunication& communication() const { return stats_; }

  /// Collective. Partition weights of this rank's sources (local_size() entries, input order) from
  /// the measured per-leaf cost of the last evaluate: each owned source's share of the seconds its
  /// owner's serial FMM spent on its target leaf (fmm::LaplaceFmm::last_target_costs; 0 where no
  /// serial FMM ran or before an evaluate). Passed to set_points with the same sources, they
  /// balance the next plan by the measured work of each leaf instead of by source counts. A
  /// measurement: weights, and so partitions, differ from run to run (results stay within the
  /// tolerance contract). Results at the sources only: with separate targets the work is the
  /// targets', which a source's weight does not describe, whether or not they follow the sources'
  /// cuts (throws not_supported on every rank).
  [[nodiscard]] std::vector<double> measured_weights() const;

  struct Plan;  // implementation (mpi/src/laplace_fmm.cpp)
  /// The plan (null before set_points succeeds), for the layer's own operators (mpi/src/fmm_plan.hpp).
  [[nodiscard]] const Plan* plan() const noexcept { return plan_.get(); }

 private:
  // The essential charges' exchanges and the serial FMM of evaluate: one FMM after the exchanges,
  // or (overlap_exchange) the owned sources' FMM during them and the received sources' after.
  // The essential charges are kept in `essential` where it is given.
  void evaluate_one(const Plan& plan, std::span<const double> owned_q, std::size_t nd,
                    std::span<const unsigned> outputs, std::span<double> owned_results,
                    std::vector<double>* essential) const;
  void evaluate_split(const Plan& plan, std::span<const double> owned_q, std::size_t nd,
                      std::span<const unsigned> outputs, std::span<double> owned_results,
                      std::vector<double>* essential) const;
  void evaluate_impl(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                     std::span<double> results, std::vector<double>* essential) const;

  Communicator comm_;
  DistributedFmmOptions options_;
  double separation_ = kDefaultSeparation;
  std::size_t cell_capacity_ = kDefaultCellCapacity;
  std::unique_ptr<Plan> plan_;
  mutable FmmCommunication stats_;
};

}  // namespace rpyfmm::mpi
