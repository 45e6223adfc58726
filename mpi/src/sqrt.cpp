// rpyfmm — the distributed Lanczos and Chebyshev square roots, with or without the block
// preconditioner of each rank's particles, and the noise of a rank's share (sqrt.hpp).
#include "rpyfmm/mpi/sqrt.hpp"

#include <cmath>
#include <optional>
#include <string>
#include <vector>

// rpy/src (private to rpyfmm::rpy and this layer): the Lanczos and Chebyshev iterations on a
// KrylovSpace and the load checks, so that the distributed samplers are the serial ones, on a
// distributed basis.
#include "krylov_space.hpp"
#include "load_scaling.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "sqrt/detail.hpp"
#include "sqrt/krylov_space.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "rpyfmm::mpi::sqrt_apply";

// The options of the samplers offered across ranks, checked on this rank: Lanczos or Chebyshev,
// with or without the block preconditioner, as rpy::sqrt_apply and MobilityOperator::apply_sqrt
// check them.
void check_options(const rpy::SqrtOptions& options) {
  const rpy::SqrtMethod method = options.method;
  require(method == rpy::SqrtMethod::lanczos || method == rpy::SqrtMethod::chebyshev ||
              method == rpy::SqrtMethod::automatic,
          ErrorCode::not_supported, kWhere,
          std::string("method '") + rpy::to_string(method) +
              "' is not offered across ranks (lanczos, chebyshev or automatic: Lanczos)");
  require(std::isfinite(options.tolerance) && options.tolerance > 0.0 && options.tolerance < 1.0,
          ErrorCode::invalid_argument, kWhere, "tolerance must lie in (0, 1), got " + format_number(options.tolerance));
  require(options.max_iterations >= 0, ErrorCode::invalid_argument, kWhere,
          "max_iterations must be >= 0 (0 = automatic), got " + std::to_string(options.max_iterations));
  require(options.preconditioner_block >= 0, ErrorCode::invalid_argument, kWhere,
          "preconditioner_block must be >= 0 (0 = automatic), got " + std::to_string(options.preconditioner_block));
  if (method == rpy::SqrtMethod::chebyshev) rpy::sqrt_detail::require_chebyshev_bounds(options, kWhere);
}

// What steers the iteration must be the same on every rank, or the ranks would part ways.
void require_same_options(const Communicator& comm, const rpy::SqrtOptions& o) {
  const bool same =
      same_on_every_rank(comm, {static_cast<double>(o.method), static_cast<double>(o.preconditioner), o.tolerance,
                                static_cast<double>(o.max_iterations), o.reorthogonalize ? 1.0 : 0.0,
                                o.throw_if_not_converged ? 1.0 : 0.0, static_cast<double>(o.preconditioner_block),
                                o.lambda_min, o.lambda_max, static_cast<double>(o.bound_estimate_iterations)});
  require(same, ErrorCode::invalid_argument, kWhere,
          "the ranks pass different options (method, preconditioner, tolerance, max_iterations, reorthogonalize, "
          "throw_if_not_converged, preconditioner_block, lambda_min, lambda_max or bound_estimate_iterations); "
          "every rank must pass the same ones");
}

// automatic: Lanczos without the preconditioner (block would make the sample depend on the
// partition: docs/mpi.md).
rpy::SqrtOptions resolved(const rpy::SqrtOptions& options) {
  rpy::SqrtOptions r = options;
  if (r.method == rpy::SqrtMethod::automatic) r.method = rpy::SqrtMethod::lanczos;
  if (r.preconditioner == rpy::SqrtPreconditioner::automatic) r.preconditioner = rpy::SqrtPreconditioner::none;
  return r;
}

}  // namespace

void fill_normal(std::span<double> local_z, std::size_t offset, std::uint64_t seed, std::uint64_t step,
                 std::uint32_t stream) {
  constexpr const char* where = "rpyfmm::mpi::fill_normal";
  require(local_z.size() % 3 == 0, ErrorCode::invalid_input, where,
          "z has " + std::to_string(local_z.size()) + " entries, not a multiple of 3");
  require(stream < 0x80000000u, ErrorCode::invalid_argument, where,
          "stream " + std::to_string(stream) + " must be below 2^31 (the top bit selects the third component)");
  // normal3 per particle: rpy::fill_normal's values (this file is compiled without contraction
  // into fused multiply-adds, as rpy/src/random_batch.cpp is).
  const auto n = static_cast<long long>(local_z.size() / 3);
#pragma omp parallel for schedule(static)
  for (long long i = 0; i < n; ++i) {
    rpy::normal3(seed, step, stream, offset + static_cast<std::size_t>(i), &local_z[3 * static_cast<std::size_t>(i)]);
  }
}

namespace {

// The Chebyshev square root (rpy/src/sqrt/chebyshev.cpp) on this rank's share: the bound
// estimate's Lanczos steps in the distributed space, from the serial start vector's share.
rpy::SqrtReport chebyshev_across_ranks(DistributedKrylovSpace& space, const rpy::sqrt_detail::KrylovProduct& product,
                                       std::size_t offset, std::size_t n, const double* z, double* w,
                                       const rpy::SqrtOptions& options) {
  const rpy::sqrt_detail::ChebyshevProducts products{space,
                                                     product,
                                                     3 * offset,
                                                     n,
                                                     [&](const double* x, double* y, rpy::SqrtReport& report) {
                                                       product(x, y);
                                                       ++report.operator_applications;
                                                       ++report.vector_products;
                                                       space.require_finite(y, "sqrt_apply(chebyshev)",
                                                                            report.operator_applications);
                                                     },
                                                     n};
  return rpy::sqrt_detail::chebyshev_sqrt_in_space(products, z, w, options);
}

// The sum of `mine` over the ranks, on every rank.
std::size_t global_count(const Communicator& comm, std::size_t mine) {
  const auto local = static_cast<std::uint64_t>(mine);
  std::uint64_t total = 0;
  check_mpi(MPI_Allreduce(&local, &total, 1, MPI_UINT64_T, MPI_SUM, comm.get()), "MPI_Allreduce");
  return static_cast<std::size_t>(total);
}

// The block preconditioner of this rank's particles (blocks never straddle ranks), with the
// serial sampler's block size: options.preconditioner_block, or automatic_block of the whole set.
template <class Operator>
rpy::BlockPreconditioner local_blocks(const Operator& op, const rpy::SqrtOptions& options) {
  const std::size_t block = options.preconditioner_block > 0
                                ? static_cast<std::size_t>(options.preconditioner_block)
                                : rpy::BlockPreconditioner::automatic_block(op.global_size());
  return rpy::BlockPreconditioner(op.local_positions(), op.local_radii(), op.viscosity(), rpy::Geometry::open(), block);
}

// The Krylov samplers on a distributed operator, DistributedDirectRpy or DistributedFmmRpy (the
// same interface). With the block preconditioner G = L^{-1} of this rank's blocks they run on
// A = G M G^T (G applied to this rank's share alone: no communication) and return
// w = G^{-1} A^{1/2} z, as BlockPreconditioner::sample does.
template <class Operator>
rpy::SqrtReport sample_across_ranks(const Operator& op, std::span<const double> local_z, std::span<double> local_w,
                                    const rpy::SqrtOptions& options, double* inner_products_seconds) {
  const Communicator& comm = op.communicator();
  require(op.global_size() > 0, ErrorCode::invalid_input, kWhere, "positions not set (call set_positions first)");
  const std::size_t n = 3 * op.local_size();
  comm.run([&] {
    check_options(options);
    require_size(local_z, n, kWhere, "local noise");
    require_size(std::span<const double>(local_w.data(), local_w.size()), n, kWhere, "local output");
    require_finite(local_z, kWhere, "local noise", 3);
  });
  require_same_options(comm, options);
  const rpy::SqrtOptions r = resolved(options);

  const rpy::LinearOperatorView m{
      n, [&op](std::span<const double> x, std::span<double> y, std::size_t) { op.apply(x, y); }};
  std::optional<rpy::BlockPreconditioner> blocks;
  if (r.preconditioner == rpy::SqrtPreconditioner::block) comm.run([&] { blocks.emplace(local_blocks(op, r)); });
  const rpy::LinearOperatorView a = blocks ? blocks->precondition(m) : m;
  const rpy::sqrt_detail::KrylovProduct product = [&a, n](const double* x, double* y) {
    a.apply(std::span<const double>(x, n), std::span<double>(y, n), 1);
  };
  DistributedKrylovSpace space(comm, op.counts());
  rpy::SqrtReport report =
      r.method == rpy::SqrtMethod::chebyshev
          ? chebyshev_across_ranks(space, product, op.offset(), n, local_z.data(), local_w.data(), r)
          : rpy::sqrt_detail::lanczos_sqrt_in_space(space, product, local_z.data(), local_w.data(), r);
  if (blocks) {
    blocks->solve_g(local_w.data());
    report.preconditioner_blocks = global_count(comm, blocks->blocks());
  }
  comm.run([&] { rpy::detail::require_finite_result(local_w, kWhere, "local output", "noise"); });
  if (inner_products_seconds != nullptr) *inner_products_seconds = space.communication_seconds();
  return report;
}

}  // namespace

rpy::SqrtReport sqrt_apply(const DistributedDirectRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           const rpy::SqrtOptions& options, double* inner_products_seconds) {
  return sample_across_ranks(op, local_z, local_w, options, inner_products_seconds);
}

rpy::SqrtReport sqrt_apply(const DistributedFmmRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           const rpy::SqrtOptions& options, double* inner_products_seconds) {
  return sample_across_ranks(op, local_z, local_w, options, inner_products_seconds);
}

}  // namespace rpyfmm::mpi
