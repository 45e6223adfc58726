// rpyfmm — the Lanczos square root of several right-hand sides across ranks (private to
// rpyfmm::mpi; sqrt.cpp): the serial block variant's iteration (rpy/src/sqrt/lanczos.cpp), each
// column its own Krylov process and stopping test, with one product call per iteration for the
// columns still iterating and each stage of their Lanczos steps' inner products in one exchange
// for all of them (docs/mpi.md, "Samplers").
#pragma once

#include <cstddef>
#include <functional>
#include <span>

#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::mpi::detail {

/// y = A x for `nrhs` vectors of this rank's share, one after another (the product's failures are
/// collective).
using ColumnsProduct = std::function<void(const double* x, double* y, std::size_t nrhs)>;

/// Collective. w_c = A^{1/2} z_c for the nrhs columns of z and w (this rank's shares, 3 segments
/// counts[rank] entries each, one after another; DistributedKrylovSpace's layout of `counts` and
/// `segments`). Each column's bits are those of the same iteration on that column alone; the report
/// aggregates as rpy::sqrt_apply's block variant (iterations and error_estimate the largest over
/// the columns, operator_applications the product calls, vector_products the columns multiplied).
/// `stats`, where not null, receives the inner products' MPI time and exchanges.
rpy::SqrtReport lanczos_columns(const Communicator& comm, std::span<const std::size_t> counts, std::size_t segments,
                                const ColumnsProduct& product, std::size_t nrhs, const double* z, double* w,
                                const rpy::SqrtOptions& options, InnerProductStats* stats);

}  // namespace rpyfmm::mpi::detail
