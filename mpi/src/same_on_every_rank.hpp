// rpyfmm — whether every rank passed the same values (private): options and arguments that steer
// a collective computation must agree, or the ranks would part ways.
#pragma once

#include <mpi.h>

#include <cstddef>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::mpi::detail {

/// Collective: whether every rank passed the same values (the minimum and the maximum of each
/// entry agree; one MPI_Allreduce). Every rank must pass as many values.
[[nodiscard]] inline bool same_on_every_rank(const Communicator& comm, std::vector<double> values) {
  const std::size_t n = values.size();
  for (std::size_t i = 0; i < n; ++i) values.push_back(-values[i]);
  std::vector<double> seen(values.size());
  check_mpi(MPI_Allreduce(values.data(), seen.data(), static_cast<int>(values.size()), MPI_DOUBLE, MPI_MIN, comm.get()),
            "MPI_Allreduce");
  for (std::size_t i = 0; i < n; ++i) {
    if (seen[i] != -seen[n + i]) return false;
  }
  return true;
}

}  // namespace rpyfmm::mpi::detail
