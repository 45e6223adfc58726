// rpyfmm CLI — whole rigid bodies over the MPI ranks (body_shares.hpp).
#include "body_shares.hpp"

#include <mpi.h>

namespace rpyfmm::cli {
namespace {

// Rank r owns bodies [cuts[r], cuts[r + 1]): contiguous runs of bodies balanced by bead count,
// cuts[r] the first body whose first bead has a global index of at least r N / P.
std::vector<std::uint64_t> body_cuts(const std::vector<std::size_t>& offsets, int ranks) {
  const auto p = static_cast<std::size_t>(ranks);
  const std::size_t n = offsets.back();
  std::vector<std::uint64_t> cuts(p + 1, offsets.size() - 1);
  std::size_t k = 0;
  for (std::size_t r = 0; r < p; ++r) {
    while (k + 1 < offsets.size() && offsets[k] * p < r * n) ++k;
    cuts[r] = k;
  }
  return cuts;
}

}  // namespace

BodyLayout broadcast_body_layout(const std::vector<std::size_t>& root_offsets, const mpi::Communicator& comm) {
  BodyLayout z;
  if (comm.rank() == 0) {
    z.offsets.assign(root_offsets.begin(), root_offsets.end());
    z.cuts = body_cuts(root_offsets, comm.size());
  }
  broadcast(z.offsets, comm);
  broadcast(z.cuts, comm);
  return z;
}

Shares body_shares(const BodyLayout& z, int per, bool by_beads) {
  Shares s;
  int offset = 0;
  for (std::size_t r = 0; r + 1 < z.cuts.size(); ++r) {
    const std::uint64_t rows = by_beads ? z.offsets[z.cuts[r + 1]] - z.offsets[z.cuts[r]] : z.cuts[r + 1] - z.cuts[r];
    s.counts.push_back(per * static_cast<int>(rows));
    s.displs.push_back(offset);
    offset += s.counts.back();
  }
  return s;
}

std::vector<std::size_t> local_body_offsets(const BodyLayout& z, int rank) {
  const auto r = static_cast<std::size_t>(rank);
  std::vector<std::size_t> offsets;
  for (std::uint64_t k = z.cuts[r]; k <= z.cuts[r + 1]; ++k) offsets.push_back(z.offsets[k] - z.offsets[z.cuts[r]]);
  return offsets;
}

}  // namespace rpyfmm::cli
