// rpyfmm — the whole system's per-particle values of distributed Brownian dynamics
// (rpyfmm/mpi/brownian_dynamics.hpp) placed by global index, on one rank or on every rank.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::mpi::detail {

/// gather_by_index's root that places the values on every rank (MPI_Allgatherv).
constexpr int kEveryRank = -1;

/// Collective: the values (`per` per particle: 3 for positions, 4 for orientations, ...) of every
/// rank's particles `ids` (global indices, together a permutation of 0 ... total - 1), placed by
/// global index (per x total entries), on `root` alone (an empty array on the other ranks) or, with
/// root = kEveryRank, on every rank. An empty `values` counts as zeros. Throws on every rank
/// (not_supported, naming `where`) when the gathered values exceed MPI's int counts.
[[nodiscard]] std::vector<double> gather_by_index(const Communicator& comm, std::span<const std::uint64_t> ids,
                                                  std::span<const double> values, std::uint64_t total, std::size_t per,
                                                  int root, const char* where);

}  // namespace rpyfmm::mpi::detail
