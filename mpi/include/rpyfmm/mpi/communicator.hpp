// rpyfmm — a view of an MPI communicator, and collective error agreement.
//
// The caller owns MPI: it calls MPI_Init (or MPI_Init_thread) before and MPI_Finalize after using
// anything in rpyfmm::mpi, and owns the communicator, which must outlive every object holding it.
//
// Collective calls fail collectively: when the input of any rank is bad, every rank throws
// rpyfmm::Error with the same code and the same message, which names the first failing rank and its
// problem, e.g. "rank 2 of 4: DistributedDirectRpy::set_positions: positions entry (5, 1) is NaN".
// No rank is left waiting in a collective that another rank skipped.
#pragma once

#include <mpi.h>

#include <exception>
#include <new>
#include <optional>
#include <string>
#include <vector>

#include "rpyfmm/core/error.hpp"

namespace rpyfmm::mpi {

class Communicator {
 public:
  /// Throws rpyfmm::Error (invalid_argument) when MPI is not initialized or already finalized, for
  /// MPI_COMM_NULL and for an inter-communicator (not collective: these hold on every rank alike).
  explicit Communicator(MPI_Comm comm);

  [[nodiscard]] MPI_Comm get() const { return comm_; }
  /// This process's rank in the communicator, 0 <= rank() < size().
  [[nodiscard]] int rank() const { return rank_; }
  /// The number of ranks.
  [[nodiscard]] int size() const { return size_; }

  /// Collective. Each rank passes its own problem (nullopt: none). When no rank has one, returns
  /// on every rank; otherwise every rank throws rpyfmm::Error with the code and message of the
  /// lowest failing rank r, as "rank r of P: <message>", followed by " (k other ranks failed too)"
  /// when k > 0 more ranks had a problem, or by " (all P ranks failed)" when every rank of several
  /// did (a problem of the data all ranks share). One allreduce when no rank fails.
  void agree(const std::optional<Error>& local_problem) const;

  /// Collective: runs `body` on this rank, catching what it throws, then agree() on the outcome.
  /// rpyfmm::Error keeps its code, std::bad_alloc becomes out_of_memory and any other
  /// std::exception invalid_input with its what().
  template <class Body>
  void run(Body&& body) const {
    std::optional<Error> problem;
    try {
      body();
    } catch (const Error& e) {
      problem = e;
    } catch (const std::bad_alloc&) {
      problem = Error(ErrorCode::out_of_memory, "out of memory");
    } catch (const std::exception& e) {
      problem = Error(ErrorCode::invalid_input, e.what());
    }
    agree(problem);
  }

 private:
  MPI_Comm comm_;
  int rank_ = 0;
  int size_ = 1;
};

/// Collective: whether every rank passed the same values (the minimum and the maximum of each entry
/// over the ranks agree; one MPI_Allreduce). Every rank must pass as many values.
[[nodiscard]] bool same_on_every_rank(const Communicator& comm, std::vector<double> values);

/// Throws rpyfmm::Error (io_error) naming `call` when an MPI call returned an error code
/// (reachable only where the communicator's error handler returns errors instead of aborting).
void check_mpi(int rc, const char* call);

}  // namespace rpyfmm::mpi
