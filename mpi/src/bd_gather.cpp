// rpyfmm — the whole system's per-particle values placed by global index (bd_gather.hpp).
#include "bd_gather.hpp"

#include <climits>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi::detail {

std::vector<double> gather_by_index(const Communicator& comm, std::span<const std::uint64_t> ids,
                                    std::span<const double> values, std::uint64_t total, std::size_t per, int root,
                                    const char* where) {
  const std::size_t stride = per + 1;  // the id, then the values
  std::vector<double> packed;
  packed.reserve(stride * ids.size());
  for (std::size_t i = 0; i < ids.size(); ++i) {
    packed.push_back(static_cast<double>(ids[i]));
    for (std::size_t c = 0; c < per; ++c) packed.push_back(values.empty() ? 0.0 : values[per * i + c]);
  }
  const bool everywhere = root == kEveryRank;
  require(stride * total <= static_cast<std::uint64_t>(INT_MAX), ErrorCode::not_supported, where,
          "gathering more than (2^31 - 1) / " + std::to_string(stride) + " values on " +
              (everywhere ? "every rank" : "rank " + std::to_string(root)));
  const int mine = static_cast<int>(packed.size());
  const bool receives = everywhere || comm.rank() == root;
  std::vector<int> counts(receives ? static_cast<std::size_t>(comm.size()) : 0), displs(counts.size(), 0);
  if (everywhere)
    check_mpi(MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm.get()), "MPI_Allgather");
  else
    check_mpi(MPI_Gather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, root, comm.get()), "MPI_Gather");
  for (std::size_t r = 1; r < counts.size(); ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(receives ? stride * total : 0);
  if (everywhere)
    check_mpi(MPI_Allgatherv(packed.data(), mine, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE,
                             comm.get()),
              "MPI_Allgatherv");
  else
    check_mpi(MPI_Gatherv(packed.data(), mine, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, root,
                          comm.get()),
              "MPI_Gatherv");
  std::vector<double> placed(receives ? per * total : 0);
  for (std::size_t k = 0; stride * k < all.size(); ++k) {
    const auto id = static_cast<std::size_t>(all[stride * k]);
    for (std::size_t c = 0; c < per; ++c) placed[per * id + c] = all[stride * k + 1 + c];
  }
  return placed;
}

}  // namespace rpyfmm::mpi::detail
