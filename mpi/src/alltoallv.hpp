// rpyfmm — one MPI_Alltoallv of doubles from per-rank vectors, with MPI's int counts checked
// collectively.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::mpi::detail {

/// Collective: send[r] goes to rank r; returns what came from every rank, concatenated in rank
/// order, recv_counts[r] doubles from rank r. Fails on every rank (not_supported, naming `where`
/// and `what`) when the counts or their sum exceed INT_MAX on any rank.
[[nodiscard]] std::vector<double> alltoallv(const Communicator& comm, const std::vector<std::vector<double>>& send,
                                            std::span<const std::size_t> recv_counts, const char* where,
                                            const char* what);

/// Collective: as above, with the receive counts first exchanged by one MPI_Alltoall; recv_counts,
/// where not null, receives them (doubles from each rank).
[[nodiscard]] std::vector<double> alltoallv(const Communicator& comm, const std::vector<std::vector<double>>& send,
                                            const char* where, const char* what,
                                            std::vector<std::size_t>* recv_counts = nullptr);

}  // namespace rpyfmm::mpi::detail
