// rpyfmm — the plan of DistributedLaplaceFmm (laplace_fmm.hpp, docs/mpi.md): the partitions, the
// owner's cells, what it sends to and receives from every rank, and the serial FMM; and the stages
// that build the locally essential tree and exchange its charges (essential_exchange.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "alltoallv.hpp"
#include "cell_tree.hpp"
#include "essential_tree.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"
#include "rpyfmm/mpi/partition.hpp"

namespace rpyfmm::mpi {

struct DistributedLaplaceFmm::Plan {
  std::unique_ptr<SfcPartition> partition;
  std::vector<double> owned_x;  // 3 per owned source, in the owned (key) order
  // Separate targets: their own partition and the owned targets; null and empty at the sources.
  std::unique_ptr<SfcPartition> target_partition;
  std::vector<double> owned_targets;
  detail::CellTree tree;
  // Per rank: the cells this rank sends to it, with the slot of each compressed one in `jobs`; the
  // particles, cells and nodes it receives from it.
  std::vector<detail::EssentialCells> sent;
  std::vector<std::vector<std::size_t>> slots;
  std::vector<std::size_t> recv_halo, recv_cells, recv_nodes;
  // The distinct (cell, order) compressed for any rank, increasing, and the offset of each one's
  // equivalent charges in units of nd values (the sum of the earlier ones' p^3).
  std::vector<detail::Compressed> jobs;
  std::vector<std::size_t> job_offset;
  std::size_t sources = 0;  // of the serial FMM: owned + halo + equivalent nodes; 0 when it does not run
  fmm::LaplaceFmm fmm;      // on all `sources`, unless split
  // DistributedFmmOptions::overlap_exchange: the serial FMM split into the owned sources' FMM and
  // the received sources' FMM at the same targets, each planned where it has sources and targets.
  bool split = false;
  bool own_runs = false, received_runs = false;
  fmm::LaplaceFmm own_fmm, received_fmm;
  // FmmOptions::near_field = false: the serial FMM's source positions (3 per source) and, where
  // any node was received, whether each source is an equivalent node (1) or a particle (0), for
  // the near pairs left out of it (essential_near.hpp); empty otherwise.
  std::vector<double> essential_x;
  std::vector<std::uint8_t> node;

  // The partition and owned positions of the targets (the sources' when evaluating at them).
  [[nodiscard]] const SfcPartition& targets() const { return target_partition ? *target_partition : *partition; }
  [[nodiscard]] const std::vector<double>& target_x() const { return target_partition ? owned_targets : owned_x; }
};

namespace detail {

using Plan = DistributedLaplaceFmm::Plan;

/// The p^3 nodes of a cell compressed with order p.
[[nodiscard]] inline std::size_t cube_nodes(int order) {
  const auto p = static_cast<std::size_t>(order);
  return p * p * p;
}

/// What this rank knows of another rank's region: the cover it walks its cells against
/// (essential_cells), or, where its root cell is compressed for that rank as a whole, the order of
/// that compression (the walk's result, without the cover); neither where nothing is sent.
struct Region {
  std::vector<Box> cover;
  int root_order = 0;
};

/// Collective: every other rank's Region for this rank's cells `tree`, by rank, with this rank's
/// region the cover of `region_tree` (region_cover, at most 64 boxes). gather_all: every rank's
/// cover by one all-gather (each walked). Otherwise one all-gather of every rank's root cell (cube
/// and particles), from which each rank decides which ranks' root cells its cover compresses (the
/// first step of their walks, compressed_order) and tells them their orders in one all-to-all of
/// one int per rank; its cover goes point to point only to the ranks whose root cells it does not
/// compress. Both give every rank the same cells to send, bit for bit. Records the regions' counts
/// and bytes in `stats`.
[[nodiscard]] std::vector<Region> exchange_regions(const Communicator& comm, const CellTree& region_tree,
                                                   const CellTree& tree, const Acceptance& acceptance, bool gather_all,
                                                   FmmCommunication& stats);

/// Not collective: the cells this rank sends to every other rank (essential_cells against its
/// region, or its root cell alone where the region compresses it), the distinct (cell, order)
/// compressed, and the slot of each sent one among them.
void select_cells(Plan& plan, const std::vector<Region>& regions, int rank, const Acceptance& acceptance);

/// Collective: the locally essential geometry (halo positions and cubes) from every rank, one
/// all-to-all of counts and one of the geometry; returns the serial FMM's sources: owned, then
/// per rank in rank order its halo sources and the nodes of its cells.
[[nodiscard]] std::vector<double> exchange_geometry(const Communicator& comm, Plan& plan, std::uint64_t& bytes);

/// The locally essential tree's counts in the statistics.
void count_essential(const Plan& plan, FmmCommunication& stats);

/// The equivalent charges of every (cell, order) in plan.jobs from the owned charges (nd x m):
/// job j's nd x p^3 values at nd × job_offset[j]. OpenMP over the jobs, in pieces of 64 jobs with
/// between_pieces (where given) called after each on the calling thread: the progress of an
/// exchange that overlaps the anterpolation.
[[nodiscard]] std::vector<double> anterpolate_cells(const Plan& plan, std::span<const double> owned_q, std::size_t nd,
                                                    const std::function<void()>& between_pieces = {});

/// Collective: posts the exchange of the halo charges (per rank, per density, its halo particles'
/// charges), which needs the owned charges only, so that it runs while the cells are anterpolated.
[[nodiscard]] std::unique_ptr<PendingAlltoallv> post_halo_charges(const Communicator& comm, const Plan& plan,
                                                                  std::span<const double> owned_q, std::size_t nd);

/// Collective: the equivalent charges to every rank and from every rank (per rank, per density,
/// its cells' nodes), one all-to-all.
[[nodiscard]] std::vector<double> exchange_node_charges(const Communicator& comm, const Plan& plan,
                                                        std::span<const double> equivalent, std::size_t nd);
/// Collective: posts the same exchange without waiting for it (the split serial FMM's overlap).
[[nodiscard]] std::unique_ptr<PendingAlltoallv> post_node_charges(const Communicator& comm, const Plan& plan,
                                                                  std::span<const double> equivalent, std::size_t nd);

/// What came from the other ranks in an evaluation: the halo charges and the equivalent charges.
struct ReceivedCharges {
  std::vector<double> halo, nodes;
};

/// The serial FMM's charges (nd x plan.sources): owned, then what came from each rank.
[[nodiscard]] std::vector<double> assemble_charges(const Plan& plan, std::span<const double> owned_q,
                                                   const ReceivedCharges& received, std::size_t nd);
/// The received sources' charges alone (nd x (plan.sources - owned)), for the split serial FMM.
[[nodiscard]] std::vector<double> assemble_received(const Plan& plan, const ReceivedCharges& received, std::size_t nd);

}  // namespace detail
}  // namespace rpyfmm::mpi
