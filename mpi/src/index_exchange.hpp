// rpyfmm — values of some of a rank's particles sent to other ranks by fixed lists, and values of
// what it received sent back: the particle exchanges of the distributed PSE (its halo and its
// slabs), planned once per set of positions and repeated in every product.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::mpi::detail {

struct IndexExchange {
  /// send[r]: this rank's particles (indices) whose values go to rank r, in order.
  std::vector<std::vector<std::uint32_t>> send;
  /// recv_counts[r]: the particles received from rank r (set by the first forward()).
  std::vector<std::size_t> recv_counts;
  /// This rank (its own list, if any, passes through the exchange too but is not counted below).
  int self = -1;
  /// The wall time of every exchange's MPI call (forward and backward) and the bytes received from
  /// other ranks in them, summed since the plan was made (its owners report differences:
  /// DistributedPseRpy::communication()).
  struct Traffic {
    double seconds = 0.0;
    std::uint64_t bytes_received = 0;
  };
  mutable Traffic traffic;

  /// Collective: `width` values per listed particle (values[width i + c]) to the ranks of the lists;
  /// returns the received values, rank by rank in rank order, each rank's in its list order. With
  /// recv_counts empty the counts are exchanged first and kept.
  [[nodiscard]] std::vector<double> forward(const Communicator& comm, const double* values, std::size_t width,
                                            const char* where, const char* what);
  /// Collective, the way back: `width` values per received particle (in forward()'s order) to the
  /// ranks they came from; returns, per rank r in rank order, the values of send[r] in list order.
  [[nodiscard]] std::vector<double> backward(const Communicator& comm, const std::vector<double>& values,
                                             std::size_t width, const char* where, const char* what) const;
  /// The particles listed to other ranks (with multiplicity), and those received from them.
  [[nodiscard]] std::size_t sent() const;
  [[nodiscard]] std::size_t received() const;
};

}  // namespace rpyfmm::mpi::detail
