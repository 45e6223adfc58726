// rpyfmm — the pieces of the block preconditioner (block_preconditioner.hpp) one block at a time:
// the spatial blocks of a set of particles, one block's Cholesky factor, and the triangular
// kernels with it. BlockPreconditioner is built from them; the distributed samplers use them to
// factor and apply the serial blocks of the whole set across ranks (docs/mpi.md, "Brownian
// displacements"), so both give the same bits.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <vector>

#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::rpy {

enum class PreconditionedMatrix;

/// Spatial blocks of N particles: `order` lists the particle indices block after block, block b
/// is order[offsets[b] .. offsets[b + 1]).
struct BlockPartition {
  std::vector<std::size_t> order;
  std::vector<std::size_t> offsets{0};
  [[nodiscard]] std::size_t blocks() const { return offsets.size() - 1; }
};

/// The recursive median bisection along the axis of widest extent of N = positions.size() / 3
/// particles until every block has at most max(max_block, 1) particles. A part of n > max_block
/// particles splits into its floor(n / 2) smallest members in the strict order bisection_less
/// (coordinate along the axis, then index), the lower part, and the others, the upper part; the
/// blocks come in depth-first order, lower part first, each block's members in ascending index.
/// So the partition is a function of the positions alone (no dependence on the selection
/// algorithm's internal permutation), reproduced across ranks by mpi/src/distributed_bisection.hpp.
[[nodiscard]] BlockPartition bisect_blocks(std::span<const double> positions, std::size_t max_block);

/// The bisection's strict total order of particles along one axis: by coordinate, then by index.
[[nodiscard]] constexpr bool bisection_less(double xi, std::size_t i, double xj, std::size_t j) {
  return xi < xj || (!(xj < xi) && i < j);
}

/// The axis of widest extent hi - lo (the lowest axis on a tie), the bisection's split axis.
[[nodiscard]] int widest_axis(const std::array<double, 3>& lo, const std::array<double, 3>& hi);
/// The same for the bounding box of the members' positions (3 per particle in `positions`).
[[nodiscard]] int widest_axis(std::span<const double> positions, std::span<const std::size_t> members);

/// Rows of the preconditioned matrix per particle: 3, or 6 for the scaled grand mobility.
[[nodiscard]] std::size_t block_dofs(PreconditionedMatrix matrix);

/// Entries of a packed lower triangle of m rows: m (m + 1) / 2.
[[nodiscard]] constexpr std::size_t packed_entries(std::size_t m) {
  return m * (m + 1) / 2;
}

/// The power of two 2^e by which factor_block scales the blocks of particles whose radii lie in
/// [min_radius, max_radius] (viscosity eta) so that they fit single precision: 0 where every self
/// mobility 1 / (6 pi eta a) lies in [2^-60, 2^60] (the blocks of ordinary suspensions, bit for bit
/// as unscaled), else the exponent that centres the self mobilities on 1. Without it, eta a = 1e-40
/// (eta and a = 1e-20, both in their documented ranges) overflowed the float blocks to infinity.
/// Any scale gives a valid sampler: G = L^{-1} need only be invertible (block_preconditioner.hpp).
[[nodiscard]] int block_scale_exponent(double min_radius, double max_radius, double viscosity);

/// Factors the diagonal block of `matrix` (M, or S M S with rotation) of the particles `members`
/// (indices into positions and radii; rows particle after particle, dofs rows each) with viscosity
/// eta and the minimum image of a periodic geometry, times 2^scale_exponent (block_scale_exponent):
/// L L^T = 2^scale_exponent x the block, in single precision, packed by rows into `packed`
/// (packed_entries(dofs x members.size()) entries). Where the Cholesky factorization fails
/// (coincident particles, or pair entries that are not finite in single precision)
/// L = diag(sqrt(diagonal)); returns false then.
bool factor_block(std::span<const double> positions, std::span<const double> radii, double viscosity,
                  const Geometry& geometry, std::span<const std::size_t> members, PreconditionedMatrix matrix,
                  float* packed, int scale_exponent = 0);

/// What a kernel does with a block's factor L (G = L^{-1}).
enum class BlockOp {
  apply_g,            ///< out = G in (forward substitution)
  apply_g_transpose,  ///< out = G^T in (back substitution)
  solve_g,            ///< out = G^{-1} in = L in
};

/// `op` with the packed factor l of m rows on the m entries of in; out has m entries (not in).
void apply_block_factor(BlockOp op, const float* l, std::size_t m, const double* in, double* out);

}  // namespace rpyfmm::rpy
