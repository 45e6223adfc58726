// rpyfmm — a Lanczos basis distributed over MPI ranks (private to rpyfmm::mpi; sqrt.cpp).
//
// Each rank holds the entries of its own particles (a HostKrylovSpace: the serial kernels), and
// every inner product is the serial one bit for bit: rpy/src/sqrt/kernels.cpp sums each chunk of
// kReductionChunk entries in index order from 0, then the chunk sums in order. Here a chunk that
// straddles ranks is summed as a chain: a rank continues the sum that the previous rank passed
// on (one value per vector, point to point), and the finished chunk sums are all-gathered in
// chunk order and added on every rank. So every rank holds the serial value and takes the
// serial iteration's branches, and the distributed Lanczos square root is the serial one.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"
#include "sqrt/krylov_space.hpp"

namespace rpyfmm::mpi {

class DistributedKrylovSpace final : public rpy::sqrt_detail::KrylovSpace {
 public:
  /// `counts`: every rank's number of particles (3 entries each), in rank order.
  DistributedKrylovSpace(const Communicator& comm, std::span<const std::size_t> counts);

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

  /// This rank's time in the MPI calls of the inner products.
  [[nodiscard]] double communication_seconds() const { return seconds_; }

 private:
  // The chunk sums of x_q . y (q < k) that end on this rank, in chunk order, q fastest; the sum
  // of a chunk that goes on to the next rank is sent there instead.
  std::vector<double> chunk_sums(std::size_t k, const double* const* x, const double* y);
  // out[q] = the serial sum of the chunk sums of all ranks; `always_fold`: also for one chunk
  // (dots adds it to 0, dot returns it).
  void sum_chunks(std::size_t k, const std::vector<double>& mine, bool always_fold, double* out);

  const Communicator& comm_;
  rpy::sqrt_detail::HostKrylovSpace local_;
  std::size_t offset_ = 0, local_n_ = 0, total_ = 0;  // in entries
  int previous_ = -1, next_ = -1;                     // nearest ranks with entries below and above (-1: none)
  std::vector<int> finished_;                         // chunks that end on each rank
  double seconds_ = 0.0;
};

}  // namespace rpyfmm::mpi
