// rpyfmm — where a Lanczos basis lives: the vector operations of the Lanczos square root
// behind one interface, so that the same iteration runs on host vectors (HostKrylovSpace) and
// on device vectors (the CUDA PSE sampler's real-space part, pse_rpy_cuda.cu). Internal header
// (not installed); Eigen-free, so that nvcc can include it.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <vector>

#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::rpy::sqrt_detail {

/// Vectors of length n() in one memory space: a basis v_0, v_1, ... that grows one vector at a
/// time, a work vector for products, and the operations the Lanczos process needs. Pointers
/// handed out stay valid until clear() or the space's end.
class KrylovSpace {
 public:
  virtual ~KrylovSpace() = default;
  [[nodiscard]] virtual std::size_t n() const = 0;
  /// Forgets the basis (its memory may be kept for the next one).
  virtual void clear() = 0;
  /// Appends a basis vector (contents unspecified) and returns it.
  virtual double* push() = 0;
  /// Basis vector q (q < basis_size()).
  [[nodiscard]] virtual double* vector(std::size_t q) = 0;
  [[nodiscard]] virtual std::size_t basis_size() const = 0;
  /// A vector outside the basis, for the product y = M v_j.
  [[nodiscard]] virtual double* work() = 0;
  /// x . y, deterministic (the same value for the same inputs, whatever the threads).
  virtual double dot(const double* x, const double* y) = 0;
  /// h[q] = v_q . y for q < k, each equal to dot(v_q, y).
  virtual void dots(std::size_t k, const double* y, double* h) = 0;
  /// y -= sum_{q < k} h[q] v_q.
  virtual void subtract_combination(std::size_t k, const double* h, double* y) = 0;
  /// y += a x.
  virtual void axpy(double a, const double* x, double* y) = 0;
  /// out = a x.
  virtual void scale_into(double a, const double* x, double* out) = 0;
  /// out = sum_{q < k} c[q] v_q (zeros for k = 0).
  virtual void combine(std::size_t k, const double* c, double* out) = 0;
  /// Throws numerical_failure naming `where` if y (the result of product number `product`)
  /// holds NaN or Inf.
  virtual void require_finite(const double* y, const char* where, long long product) = 0;
};

/// Host memory, the kernels of detail.hpp (OpenMP, thread-count-independent sums).
class HostKrylovSpace final : public KrylovSpace {
 public:
  explicit HostKrylovSpace(std::size_t n) : n_(n) {}
  [[nodiscard]] std::size_t n() const override { return n_; }
  void clear() override { count_ = 0; }
  double* push() override;
  [[nodiscard]] double* vector(std::size_t q) override { return basis_[q].get(); }
  [[nodiscard]] std::size_t basis_size() const override { return count_; }
  [[nodiscard]] double* work() override;
  double dot(const double* x, const double* y) override;
  void dots(std::size_t k, const double* y, double* h) override;
  void subtract_combination(std::size_t k, const double* h, double* y) override;
  void axpy(double a, const double* x, double* y) override;
  void scale_into(double a, const double* x, double* out) override;
  void combine(std::size_t k, const double* c, double* out) override;
  void require_finite(const double* y, const char* where, long long product) override;

 private:
  std::size_t n_;
  std::vector<std::unique_ptr<double[]>> basis_;  // uninitialised storage, kept across clear()
  std::size_t count_ = 0;
  std::vector<double> work_;
};

/// y = M x for one vector, both in the space's memory.
using KrylovProduct = std::function<void(const double* x, double* y)>;

/// w = M^{1/2} z for one right-hand side by the Lanczos square root (lanczos_sqrt's iteration,
/// stopping test and errors), z and w in the space's memory. Counts the products in the report.
/// `first_product`, if not null, is M z (in the space's memory): the first Lanczos product
/// M (z / |z|) is then scaled from it instead of calling `product`.
SqrtReport lanczos_sqrt_in_space(KrylovSpace& space, const KrylovProduct& product, const double* z, double* w,
                                 const SqrtOptions& options, const double* first_product = nullptr);

}  // namespace rpyfmm::rpy::sqrt_detail
