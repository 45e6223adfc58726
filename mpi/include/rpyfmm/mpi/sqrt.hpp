// rpyfmm — Brownian displacements w = M^{1/2} z on particles distributed over MPI ranks, and with
// rotation the displacements and rotations of the grand mobility (docs/mpi.md, "Samplers"): the
// Lanczos square root (Ando, Chow & Saad, J. Chem. Phys. 137, 064106 (2012)) and
// the Chebyshev square root (Fixman, Macromolecules 19, 1204 (1986); docs/theory/samplers.md) with
// global inner products, optionally with the block preconditioner of the whole set's serial blocks,
// and the serial samplers' noise for each rank's share of the particles.
//
// Vectors are distributed as the operator's particles: each rank holds the 3 local_size()
// entries of its own particles. Every call is collective and fails collectively
// (communicator.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::mpi {

/// Not collective. local_z[3 i + c] = rpy::normal3(seed, step, stream, offset + i)[c]: the noise
/// rpy::fill_normal draws for particles [offset, offset + local_z.size() / 3) of the whole set,
/// bit for bit, so a particle's noise depends on (seed, step, stream, global index) only, not on
/// the partition. Throws rpyfmm::Error as rpy::fill_normal does (size not a multiple of 3,
/// stream >= 2^31). The serial BD engine's noise of a step with rotation (bd/rotation_sampling.hpp)
/// is stream 0 for z_t and stream bd::kRotationNoiseStream (3) for z_r: fill_normal(local_z_t,
/// offset, seed, step) and fill_normal(local_z_r, offset, seed, step, bd::kRotationNoiseStream),
/// with offset = op.offset(), are the rank's shares of that z_t and z_r.
void fill_normal(std::span<double> local_z, std::size_t offset, std::uint64_t seed, std::uint64_t step,
                 std::uint32_t stream = 0);

/// Collective. w = M^{1/2} z on this rank's share (local_z, local_w: 3 op.local_size() entries)
/// by the serial samplers of rpy::sqrt_apply (the same iterations, stopping tests and errors), with
/// every inner product reduced over the ranks:
/// - options.method lanczos or automatic: the Lanczos square root (rpy/src/sqrt/lanczos.cpp);
///   chebyshev: the Chebyshev square root (rpy/src/sqrt/chebyshev.cpp), its bounds given or
///   estimated by Lanczos steps across the ranks; other methods are refused (not_supported).
/// - options.preconditioner none or automatic (none): the principal root. The result is, bit for
///   bit, this rank's share of what rpy::sqrt_apply gives with the serial DirectRpy on the whole
///   set, whatever the number of ranks and the partition: every inner product is summed in the
///   serial order (mpi/src/krylov_space.hpp, docs/mpi.md).
/// - block: w = G^{-1} (G M G^T)^{1/2} z with G the serial rpy::BlockPreconditioner of the whole
///   set in the global order (options.preconditioner_block, or automatic_block of the whole set
///   when 0), whatever the partition: every rank gathers all positions and radii (O(N) per rank and
///   build) and bisects them as the serial code does; each block is factored by the rank holding
///   most of its members, and G, G^T, G^{-1} gather each block's rows there and send the results
///   back (docs/mpi.md, "Brownian displacements"). The operator keeps the blocks
///   (op.sampler_blocks()), and later calls with the same block size and matrix use them again
///   until its next set_positions (InnerProductStats::blocks.reused). The result is, bit for bit,
///   this rank's share of DirectRpy::apply_sqrt with the block preconditioner on the whole set, for
///   every partition, whether the blocks were built or kept; report.preconditioner_blocks is the
///   serial count.
/// Every rank must pass the same options (checked collectively).
/// `inner_products_seconds`, where not null, receives this rank's time in the MPI calls of the
/// inner products (the products' own MPI time: op.communication().applies_seconds).
rpy::SqrtReport sqrt_apply(const DistributedDirectRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           const rpy::SqrtOptions& options, double* inner_products_seconds = nullptr);

/// Collective. The same samplers on a DistributedFmmRpy: w = M_fmm^{1/2} z with M_fmm the FMM
/// product (within its tolerance of M), not bit for bit any serial result (the operator's own bits
/// depend on the number of ranks). `inner_products_seconds` as above.
rpy::SqrtReport sqrt_apply(const DistributedFmmRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           const rpy::SqrtOptions& options, double* inner_products_seconds = nullptr);

/// What one of G, G^T and G^{-1} of the block preconditioner (mpi/src/global_blocks.hpp) cost this
/// rank over a sampler call: its applications, the columns they carried (summed over the
/// applications), this rank's time in their MPI calls (one MPI_Alltoallv to the blocks' owners and
/// one back per application, waits included) and the bytes it received from other ranks in them:
/// 8 x dofs x columns x (particles_sent + particles_received) of BlockPreconditionerStats, dofs = 3
/// (6 with rotation).
struct BlockExchangeStats {
  long long applications = 0;
  long long columns = 0;
  double seconds = 0.0;
  std::uint64_t bytes_received = 0;
};

/// What the block preconditioner cost this rank in a sampler call (all zero without it;
/// docs/mpi.md, "Brownian displacements").
struct BlockPreconditionerStats {
  /// The blocks an earlier call built for the operator's current positions, the same block size
  /// and the same matrix (translation or scaled grand), used again: no build, its fields 0.
  bool reused = false;
  /// The build's wall time on this rank: the blocks by the distributed bisection, the factoring
  /// of this rank's blocks and the exchanges' lists.
  double build_seconds = 0.0;
  /// The build's distributed bisection with the blocks' members sent to their owners
  /// (mpi/src/distributed_bisection.hpp; docs/mpi.md, "Brownian displacements"), its time on this
  /// rank and the bytes this rank received from the others in it: each MPI_Allreduce counted by its
  /// result's size, each MPI_Allgather by the other ranks' parts, and 48 bytes (index, block,
  /// position, radius) per member of this rank's blocks held by another rank; none on one rank.
  double gather_seconds = 0.0;
  std::uint64_t gather_bytes_received = 0;
  /// This rank's particles in blocks owned by other ranks, and the other ranks' particles in the
  /// blocks this rank owns: the rows each application sends and receives per column, each way.
  std::size_t particles_sent = 0;
  std::size_t particles_received = 0;
  BlockExchangeStats apply_g;
  BlockExchangeStats apply_g_transpose;
  BlockExchangeStats solve_g;

  /// The three exchanges' seconds and bytes together.
  [[nodiscard]] double exchange_seconds() const {
    return apply_g.seconds + apply_g_transpose.seconds + solve_g.seconds;
  }
  [[nodiscard]] std::uint64_t exchange_bytes_received() const {
    return apply_g.bytes_received + apply_g_transpose.bytes_received + solve_g.bytes_received;
  }
};

/// What a sampler's inner products cost this rank: its time in their MPI calls, and their
/// exchanges, each one MPI_Allgatherv of chunk sums (after a point-to-point chain where a chunk
/// straddles ranks: mpi/src/krylov_space.hpp). A Lanczos step with reorthogonalization takes three
/// exchanges (alpha and the first Gram-Schmidt pass, the second pass, the norm), without it two;
/// the start one. The same counts serve every column of a call with several right-hand sides.
struct InnerProductStats {
  double seconds = 0.0;
  long long exchanges = 0;
  /// The block preconditioner's build and exchanges, which neither `seconds` nor the operator's
  /// applies_seconds count.
  BlockPreconditionerStats blocks;
};

/// Collective. The same samplers for nrhs right-hand sides in one call, as rpy::sqrt_apply's block
/// variant: local_z and local_w hold nrhs vectors of 3 op.local_size() entries one after another
/// (apply_block's layout). Lanczos: each column runs its own Krylov process and stopping test (a
/// column that converged stops changing), each iteration multiplies the columns still iterating in
/// one op.apply_block, and each stage of their steps' inner products is one exchange for all of
/// them, so a call takes as many exchanges as the column with the most iterations would alone.
/// Chebyshev: one bound estimate (the bounds do not depend on z) and the recurrence on all columns,
/// one op.apply_block per degree. Column c of w is, bit for bit, what sqrt_apply gives on column c
/// alone (apply_block is apply on every column bit for bit), with or without the block
/// preconditioner. The report aggregates as the serial block variant's: iterations and
/// error_estimate the largest over the columns, operator_applications the product calls (the bound
/// estimate's included), vector_products the columns multiplied. Throws rpyfmm::Error on every
/// rank, as sqrt_apply does, and where nrhs is 0, differs between the ranks, or an array is not
/// nrhs x 3 op.local_size() entries. With rotation (sqrt_apply_rotation) one right-hand side per
/// call only. `stats`, where not null, receives the inner products' cost (the products' own MPI
/// time: op.communication().applies_seconds).
rpy::SqrtReport sqrt_apply(const DistributedDirectRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           std::size_t nrhs, const rpy::SqrtOptions& options, InnerProductStats* stats = nullptr);
rpy::SqrtReport sqrt_apply(const DistributedFmmRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           std::size_t nrhs, const rpy::SqrtOptions& options, InnerProductStats* stats = nullptr);

/// Collective. [w_t; w_r] = S^{-1} (S M S)^{1/2} [z_t; z_r] on this rank's share (each array
/// 3 op.local_size() entries): the Brownian displacements and rotations of the grand mobility M
/// with rotation (covariance M), by the serial rpy::MobilityOperator::apply_sqrt_rotation's
/// scaling S = diag(I, a_i I) and samplers (the tolerance bounds the error relative to |S B z|, the
/// rotations weighted by a_i). The global vector is [x_t; x_r], the translations of all ranks in
/// rank order and then their scaled rotations, as the serial sampler's; every inner product over it
/// is summed in the serial order (mpi/src/krylov_space.hpp). Methods, options and their checks as
/// sqrt_apply:
/// - preconditioner none or automatic (none): with DistributedDirectRpy, bit for bit this rank's
///   share of what DirectRpy::apply_sqrt_rotation gives on the whole set, for Lanczos and
///   Chebyshev, whatever the number of ranks and the partition.
/// - block: G the serial rpy::BlockPreconditioner of the whole set for the scaled grand mobility
///   (rpy::PreconditionedMatrix::scaled_grand: 6 rows per particle), across ranks as for
///   sqrt_apply: with DistributedDirectRpy bit for bit DirectRpy::apply_sqrt_rotation with the
///   block preconditioner, for every partition.
/// With DistributedFmmRpy the product is the FMM's (within its tolerance of M).
/// `inner_products_seconds` as above.
rpy::SqrtReport sqrt_apply_rotation(const DistributedDirectRpy& op, std::span<const double> local_z_translation,
                                    std::span<const double> local_z_rotation, std::span<double> local_w_translation,
                                    std::span<double> local_w_rotation, const rpy::SqrtOptions& options,
                                    double* inner_products_seconds = nullptr);
rpy::SqrtReport sqrt_apply_rotation(const DistributedFmmRpy& op, std::span<const double> local_z_translation,
                                    std::span<const double> local_z_rotation, std::span<double> local_w_translation,
                                    std::span<double> local_w_rotation, const rpy::SqrtOptions& options,
                                    double* inner_products_seconds = nullptr);

/// Collective. sqrt_apply_rotation as above, `stats` receiving the inner products' cost (seconds and
/// exchanges, as InnerProductStats describes) and the block preconditioner's.
rpy::SqrtReport sqrt_apply_rotation(const DistributedDirectRpy& op, std::span<const double> local_z_translation,
                                    std::span<const double> local_z_rotation, std::span<double> local_w_translation,
                                    std::span<double> local_w_rotation, const rpy::SqrtOptions& options,
                                    InnerProductStats& stats);
rpy::SqrtReport sqrt_apply_rotation(const DistributedFmmRpy& op, std::span<const double> local_z_translation,
                                    std::span<const double> local_z_rotation, std::span<double> local_w_translation,
                                    std::span<double> local_w_rotation, const rpy::SqrtOptions& options,
                                    InnerProductStats& stats);

}  // namespace rpyfmm::mpi
