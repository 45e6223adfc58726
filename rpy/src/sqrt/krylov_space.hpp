// rpyfmm — where a Lanczos basis lives: the vector operations of the Lanczos square root
// behind one interface, so that the same iteration runs on host vectors (HostKrylovSpace) and
// on device vectors (the CUDA PSE sampler's real-space part, pse_rpy_cuda.cu). Internal header
// (not installed); Eigen-free, so that nvcc can include it.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <span>
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

/// The fixed start vector of the spectrum-bound estimate, entries [first_entry, first_entry +
/// start.size()) of it: entry e is normal3(0x5eedb0cd, 0, 2^31 - 1, e / 3)[e % 3] (rpy/random.hpp),
/// so a rank's share of it is the serial vector's, whatever the partition.
void fill_bound_start(std::span<double> start, std::size_t first_entry);

/// estimate_spectrum_bounds (rpy/sqrt.hpp) on a Krylov space: `iterations` (>= 2) steps of
/// reorthogonalized Lanczos from `start` (in the space's memory), the Ritz values padded.
SpectrumBounds estimate_spectrum_bounds_in_space(KrylovSpace& space, const KrylovProduct& product, const double* start,
                                                 int iterations);

/// The products of the Chebyshev square root: `one` multiplies one vector of `space` (the bound
/// estimate's Lanczos steps), `all` the recurrence's vectors of `len` entries (one right-hand
/// side, several one after another, or a rank's share), counting the call in the report and
/// checking the result. `first_entry` / `entries`: the global index of the space's first entry in
/// this memory and their number (the bound estimate's start vector). Where this memory holds
/// `segments` such runs of `entries` one after another (a rank's shares of the translations and
/// the rotations), run s starts at global entry first_entry + s * segment_stride.
struct ChebyshevProducts {
  KrylovSpace& space;
  KrylovProduct one;
  std::size_t first_entry = 0;
  std::size_t entries = 0;
  std::function<void(const double* x, double* y, SqrtReport& report)> all;
  std::size_t len = 0;
  std::size_t segments = 1;
  std::size_t segment_stride = 0;
};

/// w = p_d(M) z by the Chebyshev square root (Fixman 1986; chebyshev_sqrt's bounds, degree,
/// recurrence and errors): the bounds of `options`, or estimated by estimate_spectrum_bounds_in_space
/// when both are 0; then the three-term recurrence, elementwise but for the products, so that a
/// rank's share of the vectors recurs as the serial vectors do.
SqrtReport chebyshev_sqrt_in_space(const ChebyshevProducts& products, const double* z, double* w,
                                   const SqrtOptions& options);

}  // namespace rpyfmm::rpy::sqrt_detail
