// rpyfmm — Brownian displacements w = M^{1/2} z on particles distributed over MPI ranks
// (docs/mpi.md): the Lanczos square root (Ando, Chow & Saad, J. Chem. Phys. 137, 064106 (2012)) and
// the Chebyshev square root (Fixman, Macromolecules 19, 1204 (1986); docs/theory/samplers.md) with
// global inner products, optionally with the block preconditioner of each rank's particles, and the
// serial samplers' noise for each rank's share of the particles.
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
/// stream >= 2^31).
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
/// - block: w = G^{-1} (G M G^T)^{1/2} z with G the rpy::BlockPreconditioner of this rank's own
///   particles (op.local_positions(), op.local_radii(); options.preconditioner_block, or
///   automatic_block of the whole set when 0): blocks never straddle ranks, so G needs no
///   communication, and G, with it the sample (not its covariance M), depends on the partition.
///   Where one rank holds every particle it is bit for bit the serial preconditioned sampler.
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

}  // namespace rpyfmm::mpi
