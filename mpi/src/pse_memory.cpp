// rpyfmm — DistributedPseRpy's memory limit per rank (pse_memory.hpp).
#include "pse_memory.hpp"

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "pse_slab_wave.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi::detail {
namespace {

/// The windows of n particles as PseRpy's memory estimate counts them (rpy/src/pse/parameters.cpp,
/// memory_estimate): 8 bytes per support point of the three axes and 8 more per particle.
std::size_t window_bytes(const rpy::pse::PseParameters& p, std::size_t n) {
  const auto per_particle = static_cast<std::size_t>(p.support[0] + p.support[1] + p.support[2] + 8);
  return 8 * n * per_particle;
}

}  // namespace

std::size_t whole_grid_budget(std::size_t per_rank_limit, int ranks) {
  const auto r = static_cast<std::size_t>(ranks);
  constexpr std::size_t most = std::numeric_limits<std::size_t>::max();
  return per_rank_limit > most / r ? most : per_rank_limit * r;
}

std::size_t check_rank_memory(const Communicator& comm, const rpy::pse::PseParameters& p, std::size_t local_n,
                              std::size_t limit, const char* where) {
  const std::size_t slab = SlabWaveSpace::memory_bytes(comm, p);
  const std::size_t windows = window_bytes(p, local_n);
  // Every rank's (slab, windows, particles), so that every rank forms the same message.
  const std::uint64_t mine[3] = {slab, windows, local_n};
  std::vector<std::uint64_t> all(3 * static_cast<std::size_t>(comm.size()));
  check_mpi(MPI_Allgather(mine, 3, MPI_UINT64_T, all.data(), 3, MPI_UINT64_T, comm.get()), "MPI_Allgather");
  std::size_t worst = 0;
  for (std::size_t r = 1; r < static_cast<std::size_t>(comm.size()); ++r)
    if (all[3 * r] + all[3 * r + 1] > all[3 * worst] + all[3 * worst + 1]) worst = r;
  const std::uint64_t need = all[3 * worst] + all[3 * worst + 1];
  require(need <= limit, ErrorCode::out_of_memory, where,
          "rank " + std::to_string(worst) + " of " + std::to_string(comm.size()) + " needs " + std::to_string(need) +
              " bytes (its slab of the FFT grid " + std::to_string(p.grid[0]) + " x " + std::to_string(p.grid[1]) +
              " x " + std::to_string(p.grid[2]) + " with c(k): " + std::to_string(all[3 * worst]) +
              " bytes; the windows of its " + std::to_string(all[3 * worst + 2]) +
              " particles: " + std::to_string(all[3 * worst + 1]) + " bytes), over the limit of " +
              std::to_string(limit) + " bytes per rank (PseOptions::max_memory_bytes)");
  return slab + windows;
}

}  // namespace rpyfmm::mpi::detail
