// rpyfmm — one MPI_Alltoallv of doubles from per-rank vectors, with MPI's int counts checked
// collectively.
#pragma once

#include <mpi.h>

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

/// A non-blocking MPI_Ialltoallv of doubles, for communication that overlaps other work: the
/// constructor (collective, with the counts checked as alltoallv checks them) posts it, test()
/// lets MPI progress it between pieces of that work, wait() completes it and returns what came
/// from every rank as alltoallv does. The buffers live in the object; its destructor completes a
/// posted exchange that was not waited for.
class PendingAlltoallv {
 public:
  PendingAlltoallv(const Communicator& comm, const std::vector<std::vector<double>>& send,
                   std::span<const std::size_t> recv_counts, const char* where, const char* what);
  ~PendingAlltoallv();
  PendingAlltoallv(const PendingAlltoallv&) = delete;
  PendingAlltoallv& operator=(const PendingAlltoallv&) = delete;

  /// Not collective: one MPI_Test (progress of the exchange; a no-op once it completed).
  void test();
  /// Not collective: MPI_Wait, then the received values (once).
  [[nodiscard]] std::vector<double> wait();

 private:
  std::vector<int> send_counts_, send_displs_, recv_counts_, recv_displs_;
  std::vector<double> packed_, received_;
  MPI_Request request_ = MPI_REQUEST_NULL;
};

}  // namespace rpyfmm::mpi::detail
