// rpyfmm — the block-diagonal preconditioner of the Krylov Brownian samplers, Lanczos and
// Chebyshev (SqrtOptions::preconditioner = SqrtPreconditioner::block).
//
// Any invertible G gives a valid Brownian displacement
//     w = G^{-1} (G M G^T)^{1/2} z,   since  (G^{-1} A^{1/2}) (G^{-1} A^{1/2})^T = G^{-1} A G^{-T} = M
// for A = G M G^T (the preconditioned Krylov sampler of Ando, Chow, Saad & Skolnick, J. Chem. Phys.
// 137, 064106 (2012); docs/theory/samplers.md).
// Here G = L^{-1}, where L L^T ~ the block diagonal of M over spatial blocks of nearby particles:
// the blocks of A on its diagonal are (nearly) identities, so the short-range couplings that spread M's
// small eigenvalues are gone and Lanczos on A needs fewer products than on M. Chebyshev gains
// more: its degree grows as sqrt(condition number), and A's is 5-10x below M's. The blocks come
// from a recursive median bisection of the particles along the widest axis, so every block has
// between max_block / 2 and max_block particles whatever the density of the cloud.
//
// L is stored in single precision (packed lower triangles), and G x, G^T x are triangular solves
// with it: they read a quarter of the memory of a double square block. The rounding makes L a
// slightly different invertible matrix, and every operation uses that same L, so w w^T still
// averages to M exactly.
//
// With rotation (PreconditionedMatrix::scaled_grand) the blocks are those of the scaled grand
// mobility S M S that MobilityOperator::apply_sqrt_rotation samples (S = diag(I, a_i I)): every
// particle of a spatial block contributes 6 rows, its translation and its scaled rotation, and
// the vectors are [x_t; x_r] (3N each, particle-major) as there.
#pragma once

#include <algorithm>
#include <cstddef>
#include <span>
#include <vector>

#include "rpyfmm/rpy/block_factors.hpp"
#include "rpyfmm/rpy/geometry.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::rpy {

class MobilityOperator;

/// The matrix whose diagonal blocks the preconditioner factors.
enum class PreconditionedMatrix {
  translation,   ///< M, 3N x 3N (3 rows per particle)
  scaled_grand,  ///< S M S with rotation, 6N x 6N (MobilityOperator::apply_sqrt_rotation; 6 rows per particle)
};

class BlockPreconditioner {
 public:
  /// Particles per block when none is asked for: N / 64, between 16 and 32. Small blocks are
  /// cheap to factor and whiten enough below ~2000 particles. Larger blocks than 32 save a few
  /// more iterations, which pays for the FMM operator at 10^5 particles (4%) but not for
  /// operators with cheaper products (PSE: measured 1.1x faster with 32 than with 64 at 8000
  /// particles; docs/theory/samplers.md).
  static std::size_t automatic_block(std::size_t n) { return std::clamp<std::size_t>(n / 64, 16, 32); }

  /// Partitions N = radii.size() particles into blocks of at most `max_block` particles and
  /// factors each diagonal block of the RPY mobility (viscosity eta; minimum-image separations
  /// in a periodic geometry). A block whose Cholesky factorization fails (coincident particles
  /// make it singular) keeps only its diagonal, so L is always invertible. `matrix`: the blocks of
  /// M, or of the scaled grand mobility with rotation. Throws rpyfmm::Error for positions that are
  /// not 3N finite values, or a radius or viscosity that is not finite, > 0 and normal. Blocks of
  /// extreme eta a are factored scaled by a power of two (block_scale_exponent).
  BlockPreconditioner(std::span<const double> positions, std::span<const double> radii, double viscosity,
                      const Geometry& geometry, std::size_t max_block,
                      PreconditionedMatrix matrix = PreconditionedMatrix::translation);
  /// From an operator's positions, radii, viscosity and geometry; max_block 0 = automatic_block(N).
  explicit BlockPreconditioner(const MobilityOperator& mobility, std::size_t max_block = 0,
                               PreconditionedMatrix matrix = PreconditionedMatrix::translation);
  /// The same with the block size of a sampler's options (options.preconditioner_block: >= 0,
  /// else rpyfmm::Error; 0 = automatic).
  BlockPreconditioner(const MobilityOperator& mobility, const SqrtOptions& options,
                      PreconditionedMatrix matrix = PreconditionedMatrix::translation);

  /// x <- G x = L^{-1} x, one vector of rows() entries (3N, or 6N with rotation).
  void apply_g(double* x) const;
  /// x <- G^T x = L^{-T} x.
  void apply_g_transpose(double* x) const;
  /// x <- G^{-1} x = L x.
  void solve_g(double* x) const;

  /// A = G M G^T as a linear operator (for the Krylov solvers); refers to `m` and to this.
  [[nodiscard]] LinearOperatorView precondition(const LinearOperatorView& m) const;
  /// w = G^{-1} (G M G^T)^{1/2} z by `options` (method lanczos or chebyshev, whose bounds, if
  /// given, are those of G M G^T; nrhs vectors one after another).
  SqrtReport sample(const LinearOperatorView& m, std::span<const double> z, std::span<double> w, std::size_t nrhs,
                    const SqrtOptions& options) const;

  /// Particles N.
  [[nodiscard]] std::size_t size() const { return n_; }
  /// Rows of the preconditioned matrix: 3N, or 6N for PreconditionedMatrix::scaled_grand.
  [[nodiscard]] std::size_t rows() const { return dofs_ * n_; }
  [[nodiscard]] std::size_t blocks() const { return offsets_.size() - 1; }
  /// Blocks that fell back to their diagonal.
  [[nodiscard]] std::size_t diagonal_blocks() const { return diagonal_blocks_; }

 private:
  void apply(BlockOp op, double* x) const;
  /// Entry of particle i's row c (0 <= c < dofs_) in a vector: translation 3i + c, rotation 3N + 3i + c - 3.
  [[nodiscard]] std::size_t entry(std::size_t i, std::size_t c) const {
    return c < 3 ? 3 * i + c : 3 * (n_ + i) + c - 3;
  }

  std::size_t n_ = 0;
  std::size_t dofs_ = 3;                    // rows per particle: 3, or 6 with rotation
  std::vector<std::size_t> order_;          // particle indices, block after block
  std::vector<std::size_t> offsets_;        // block b holds order_[offsets_[b] .. offsets_[b + 1])
  std::vector<std::size_t> factor_offset_;  // block b's L_b starts at factors_[factor_offset_[b]]
  std::vector<float> factors_;              // L_b's lower triangle, row after row (row i: i + 1 entries)
  std::size_t diagonal_blocks_ = 0;
};

}  // namespace rpyfmm::rpy
