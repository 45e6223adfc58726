// rpyfmm — a Lanczos basis distributed over MPI ranks (private to rpyfmm::mpi; sqrt.cpp).
//
// The global vector is one or more segments, each the concatenation of the ranks' shares in rank
// order (3 entries per particle): the translations [x_0; ...; x_{N-1}], or with rotation the
// translations and then the scaled rotations, [x_t; x_r] as rpy::MobilityOperator's
// apply_sqrt_rotation orders them. Each rank holds its shares of the segments one after another
// (a HostKrylovSpace: the serial kernels), and every inner product is the serial one bit for bit:
// rpy/src/sqrt/kernels.cpp sums each chunk of kReductionChunk entries in index order from 0, then
// the chunk sums in order. Here a chunk that straddles shares is summed as a chain: the owner of a
// share continues the sum that the owner of the previous nonempty share passed on (one value per
// vector, point to point; with two segments the chain runs through the ranks twice), and the
// finished chunk sums are all-gathered and added in chunk order on every rank. So every rank
// holds the serial value and takes the serial iteration's branches, and the distributed Lanczos
// square root is the serial one.
#pragma once

#include <mpi.h>

#include <cstddef>
#include <span>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"
#include "sqrt/krylov_space.hpp"

namespace rpyfmm::mpi {

class DistributedKrylovSpace final : public rpy::sqrt_detail::KrylovSpace {
 public:
  /// `counts`: every rank's number of particles (3 entries each per segment), in rank order;
  /// `segments`: 1 (translations) or 2 (translations, then rotations).
  DistributedKrylovSpace(const Communicator& comm, std::span<const std::size_t> counts, std::size_t segments = 1);

  [[nodiscard]] std::size_t n() const override { return total_; }  // the global length
  void clear() override { local_.clear(); }
  double* push() override { return local_.push(); }
  [[nodiscard]] double* vector(std::size_t q) override { return local_.vector(q); }
  [[nodiscard]] std::size_t basis_size() const override { return local_.basis_size(); }
  [[nodiscard]] double* work() override { return local_.work(); }
  double dot(const double* x, const double* y) override;
  void dots(std::size_t k, const double* y, double* h) override;
  void subtract_combination(std::size_t k, const double* h, double* y) override {
    local_.subtract_combination(k, h, y);
  }
  void axpy(double a, const double* x, double* y) override { local_.axpy(a, x, y); }
  void scale_into(double a, const double* x, double* out) override { local_.scale_into(a, x, out); }
  void combine(std::size_t k, const double* c, double* out) override { local_.combine(k, c, out); }
  void require_finite(const double* y, const char* where, long long product) override;

  /// out[q] = x_q . y_q for k pairs of global vectors of this space's layout (any memory of this
  /// rank's length, not only the basis), each bit for bit dot(x_q, y_q), all in one exchange: one
  /// chain of the partial chunk sums and one MPI_Allgatherv whatever k. The samplers of several
  /// right-hand sides reduce the inner products of all their columns' spaces (one per column,
  /// all of one layout) with it (docs/mpi.md, "Samplers").
  void pair_dots(std::size_t k, const double* const* x, const double* const* y, double* out);

  /// This rank's time in the MPI calls of the inner products.
  [[nodiscard]] double communication_seconds() const { return seconds_; }
  /// The exchanges of inner products (each one MPI_Allgatherv of the chunk sums) so far.
  [[nodiscard]] long long exchanges() const { return exchanges_; }

 private:
  // This rank's share of one segment: its entries [global, global + n) of the global vector,
  // stored from local entry `local`, and the ranks that hold the nonempty shares just before and
  // after it in the global order (-1: none; possibly this rank itself).
  struct Share {
    std::size_t global = 0, local = 0, n = 0;
    int previous = -1, next = -1;
  };
  // The chunk sums of x_q . y_q (q < k) that end in this rank's shares, in chunk order, q fastest;
  // the sum of a chunk that goes on past a share is sent to the holder of the next one instead.
  std::vector<double> chunk_sums(std::size_t k, const double* const* x, const double* const* y);
  // The same for one share; `sends` keeps the sent sums and requests until they are complete.
  void share_sums(const Share& share, std::size_t k, const double* const* x, const double* const* y,
                  std::vector<double>& mine, std::vector<std::vector<double>>& sent, std::vector<MPI_Request>& sends);
  // out[q] = the serial sum of the chunk sums of all ranks; `always_fold`: also for one chunk
  // (dots adds it to 0, dot returns it).
  void sum_chunks(std::size_t k, const std::vector<double>& mine, bool always_fold, double* out);
  // Runs `body` (an MPI call) and adds its time to seconds_.
  template <class Body>
  void timed(Body&& body) {
    const double t0 = MPI_Wtime();
    body();
    seconds_ += MPI_Wtime() - t0;
  }

  const Communicator& comm_;
  rpy::sqrt_detail::HostKrylovSpace local_;
  std::size_t total_ = 0;                // global length, in entries
  std::vector<Share> shares_;            // this rank's nonempty shares, in global order
  std::vector<int> finished_;            // chunks that end on each rank
  std::vector<std::size_t> chunk_slot_;  // chunk c's place among the gathered chunk sums
  double seconds_ = 0.0;
  long long exchanges_ = 0;
};

}  // namespace rpyfmm::mpi
