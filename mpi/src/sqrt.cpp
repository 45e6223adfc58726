// rpyfmm — the distributed Lanczos square root and the noise of a rank's share (sqrt.hpp).
#include "rpyfmm/mpi/sqrt.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

// rpy/src (private to rpyfmm::rpy and this layer): the Lanczos iteration on a KrylovSpace and the
// load checks, so that the distributed sampler is the serial one, on a distributed basis.
#include "krylov_space.hpp"
#include "load_scaling.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "sqrt/krylov_space.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "rpyfmm::mpi::sqrt_apply";

// The options rpy::sqrt_apply accepts for Lanczos, checked on this rank.
void check_options(const rpy::SqrtOptions& options) {
  require(options.method == rpy::SqrtMethod::lanczos || options.method == rpy::SqrtMethod::automatic,
          ErrorCode::not_supported, kWhere,
          std::string("method '") + rpy::to_string(options.method) +
              "' is not offered across ranks (lanczos or automatic: Lanczos)");
  require(options.preconditioner != rpy::SqrtPreconditioner::block, ErrorCode::not_supported, kWhere,
          "the block preconditioner is not offered across ranks (none or automatic: none)");
  require(std::isfinite(options.tolerance) && options.tolerance > 0.0 && options.tolerance < 1.0,
          ErrorCode::invalid_argument, kWhere, "tolerance must lie in (0, 1), got " + format_number(options.tolerance));
  require(options.max_iterations >= 0, ErrorCode::invalid_argument, kWhere,
          "max_iterations must be >= 0 (0 = automatic), got " + std::to_string(options.max_iterations));
}

// What steers the iteration must be the same on every rank, or the ranks would part ways.
void require_same_options(const Communicator& comm, const rpy::SqrtOptions& options) {
  const std::array<double, 4> mine{options.tolerance, static_cast<double>(options.max_iterations),
                                   options.reorthogonalize ? 1.0 : 0.0, options.throw_if_not_converged ? 1.0 : 0.0};
  std::array<double, 8> local{}, global{};
  for (std::size_t i = 0; i < 4; ++i) local[i] = mine[i], local[4 + i] = -mine[i];
  check_mpi(MPI_Allreduce(local.data(), global.data(), 8, MPI_DOUBLE, MPI_MIN, comm.get()), "MPI_Allreduce");
  for (std::size_t i = 0; i < 4; ++i) {
    require(global[i] == -global[4 + i], ErrorCode::invalid_argument, kWhere,
            "the ranks pass different options (tolerance, max_iterations, reorthogonalize or "
            "throw_if_not_converged); every rank must pass the same ones");
  }
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

// The Lanczos square root on a distributed operator: DistributedDirectRpy or DistributedFmmRpy
// (the same interface: communicator, global_size, local_size, counts, apply).
template <class Operator>
rpy::SqrtReport lanczos_across_ranks(const Operator& op, std::span<const double> local_z, std::span<double> local_w,
                                     const rpy::SqrtOptions& options, double* inner_products_seconds) {
  const Communicator& comm = op.communicator();
  require(op.global_size() > 0, ErrorCode::invalid_input, kWhere, "positions not set (call set_positions first)");
  comm.run([&] {
    check_options(options);
    const std::size_t n = 3 * op.local_size();
    require_size(local_z, n, kWhere, "local noise");
    require_size(std::span<const double>(local_w.data(), local_w.size()), n, kWhere, "local output");
    require_finite(local_z, kWhere, "local noise", 3);
  });
  require_same_options(comm, options);
  rpy::SqrtOptions resolved = options;
  resolved.method = rpy::SqrtMethod::lanczos;
  resolved.preconditioner = rpy::SqrtPreconditioner::none;

  const std::size_t n = 3 * op.local_size();
  DistributedKrylovSpace space(comm, op.counts());
  const rpy::SqrtReport report = rpy::sqrt_detail::lanczos_sqrt_in_space(
      space, [&](const double* x, double* y) { op.apply(std::span<const double>(x, n), std::span<double>(y, n)); },
      local_z.data(), local_w.data(), resolved);
  comm.run([&] { rpy::detail::require_finite_result(local_w, kWhere, "local output", "noise"); });
  if (inner_products_seconds != nullptr) *inner_products_seconds = space.communication_seconds();
  return report;
}

}  // namespace

rpy::SqrtReport sqrt_apply(const DistributedDirectRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           const rpy::SqrtOptions& options, double* inner_products_seconds) {
  return lanczos_across_ranks(op, local_z, local_w, options, inner_products_seconds);
}

rpy::SqrtReport sqrt_apply(const DistributedFmmRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           const rpy::SqrtOptions& options, double* inner_products_seconds) {
  return lanczos_across_ranks(op, local_z, local_w, options, inner_products_seconds);
}

}  // namespace rpyfmm::mpi
