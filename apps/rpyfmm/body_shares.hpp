// rpyfmm CLI — whole rigid bodies over the MPI ranks, shared by `rigid` and `rigid-bd` across ranks
// (docs/mpi.md, "The command-line tool under mpirun"): rank r owns a contiguous run of bodies,
// balanced by bead count (a rank may get none); rank 0 broadcasts the layout and scatters and
// gathers rows per body or per bead.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "rank_shares.hpp"
#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::cli {

/// Every rank's knowledge of the layout: the body offsets (m + 1) and the cuts (P + 1): rank r owns
/// bodies [cuts[r], cuts[r + 1]).
struct BodyLayout {
  std::vector<std::uint64_t> offsets, cuts;
  [[nodiscard]] std::uint64_t bodies() const { return offsets.size() - 1; }
  [[nodiscard]] std::uint64_t beads() const { return offsets.back(); }
};

/// Collective: rank 0's body offsets (ignored elsewhere) and their cuts over the ranks, cuts[r] the
/// first body whose first bead has a global index of at least r N / P, on every rank.
BodyLayout broadcast_body_layout(const std::vector<std::size_t>& root_offsets, const mpi::Communicator& comm);

/// Scatter and gather counts of `per` values per body (by_beads false) or per bead of each rank.
Shares body_shares(const BodyLayout& z, int per, bool by_beads);

/// This rank's body offsets, from 0 to its bead count ({0} without bodies).
std::vector<std::size_t> local_body_offsets(const BodyLayout& z, int rank);

}  // namespace rpyfmm::cli
