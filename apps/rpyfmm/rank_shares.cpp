// rpyfmm CLI — contiguous shares of rows over MPI ranks (rank_shares.hpp).
#include "rank_shares.hpp"

#include <mpi.h>

#include <climits>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

Shares shares_of(std::size_t n, int ranks, int per) {
  require(static_cast<std::size_t>(per) * n <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, "rpyfmm",
          std::to_string(n) + " rows of " + std::to_string(per) +
              " values: more than MPI's int counts address in one scatter");
  Shares s;
  int offset = 0;
  const auto p = static_cast<std::size_t>(ranks);
  for (std::size_t r = 0; r < p; ++r) {
    const auto share = static_cast<int>(n / p + (r < n % p ? 1 : 0));
    s.counts.push_back(per * share);
    s.displs.push_back(offset);
    offset += per * share;
  }
  return s;
}

std::vector<double> scatter(const double* whole, const Shares& s, const mpi::Communicator& comm) {
  std::vector<double> local(s.count(comm.rank()));
  mpi::check_mpi(MPI_Scatterv(whole, s.counts.data(), s.displs.data(), MPI_DOUBLE, local.data(),
                              static_cast<int>(local.size()), MPI_DOUBLE, 0, comm.get()),
                 "MPI_Scatterv");
  return local;
}

void gather(const std::vector<double>& local, const Shares& s, double* whole, const mpi::Communicator& comm) {
  mpi::check_mpi(MPI_Gatherv(local.data(), static_cast<int>(local.size()), MPI_DOUBLE, whole, s.counts.data(),
                             s.displs.data(), MPI_DOUBLE, 0, comm.get()),
                 "MPI_Gatherv");
}

std::vector<double> all_gather(const std::vector<double>& local, const Shares& s, const mpi::Communicator& comm) {
  std::vector<double> whole(static_cast<std::size_t>(s.displs.back()) + s.count(comm.size() - 1));
  mpi::check_mpi(MPI_Allgatherv(local.data(), static_cast<int>(local.size()), MPI_DOUBLE, whole.data(), s.counts.data(),
                                s.displs.data(), MPI_DOUBLE, comm.get()),
                 "MPI_Allgatherv");
  return whole;
}

void broadcast(std::vector<std::uint64_t>& values, const mpi::Communicator& comm) {
  std::uint64_t size = values.size();
  mpi::check_mpi(MPI_Bcast(&size, 1, MPI_UINT64_T, 0, comm.get()), "MPI_Bcast");
  values.resize(size);
  mpi::check_mpi(MPI_Bcast(values.data(), static_cast<int>(size), MPI_UINT64_T, 0, comm.get()), "MPI_Bcast");
}

namespace {

StageTimes reduced(const StageTimes& mine, MPI_Op op, const mpi::Communicator& comm) {
  std::vector<double> local, global;
  for (const auto& [stage, value] : mine) local.push_back(value);
  global.resize(local.size());
  mpi::check_mpi(MPI_Reduce(local.data(), global.data(), static_cast<int>(local.size()), MPI_DOUBLE, op, 0, comm.get()),
                 "MPI_Reduce");
  StageTimes out;
  std::size_t i = 0;
  for (const auto& [stage, value] : mine) out[stage] = global[i++];
  return out;
}

}  // namespace

StageTimes slowest(const StageTimes& mine, const mpi::Communicator& comm) {
  return reduced(mine, MPI_MAX, comm);
}

StageTimes summed(const StageTimes& mine, const mpi::Communicator& comm) {
  return reduced(mine, MPI_SUM, comm);
}

}  // namespace rpyfmm::cli
