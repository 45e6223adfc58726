// rpyfmm — the distributed Lanczos and Chebyshev square roots, with or without the block
// preconditioner of the whole set, and the noise of a rank's share (sqrt.hpp).
#include "rpyfmm/mpi/sqrt.hpp"

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <memory>
#include <string>
#include <utility>
#include <vector>

// rpy/src (private to rpyfmm::rpy and this layer): the Lanczos and Chebyshev iterations on a
// KrylovSpace and the load checks, so that the distributed samplers are the serial ones, on a
// distributed basis.
#include "global_blocks.hpp"
#include "krylov_space.hpp"
#include "lanczos_columns.hpp"
#include "load_scaling.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "sqrt/detail.hpp"
#include "sqrt/krylov_space.hpp"

namespace rpyfmm::mpi {

namespace detail {
// The one writer of SamplerBlocks (rpyfmm/mpi/sampler_blocks.hpp): the samplers below.
struct SamplerBlocksWriter {
  static void replace(const SamplerBlocks& kept, std::shared_ptr<const GlobalBlocks> blocks) noexcept {
    kept.blocks_ = std::move(blocks);
  }
};
}  // namespace detail

namespace {

constexpr const char* kWhere = "rpyfmm::mpi::sqrt_apply";
constexpr const char* kWhereRotation = "rpyfmm::mpi::sqrt_apply_rotation";

// The options of the samplers offered across ranks, checked on this rank: Lanczos or Chebyshev,
// with or without the block preconditioner, as rpy::sqrt_apply and MobilityOperator::apply_sqrt
// check them. `where` names the sampler in the messages.
void check_options(const rpy::SqrtOptions& options, const char* where) {
  const rpy::SqrtMethod method = options.method;
  require(method == rpy::SqrtMethod::lanczos || method == rpy::SqrtMethod::chebyshev ||
              method == rpy::SqrtMethod::automatic,
          ErrorCode::not_supported, where,
          std::string("method '") + rpy::to_string(method) +
              "' is not offered across ranks (lanczos, chebyshev or automatic: Lanczos)");
  require(std::isfinite(options.tolerance) && options.tolerance > 0.0 && options.tolerance < 1.0,
          ErrorCode::invalid_argument, where, "tolerance must lie in (0, 1), got " + format_number(options.tolerance));
  require(options.max_iterations >= 0, ErrorCode::invalid_argument, where,
          "max_iterations must be >= 0 (0 = automatic), got " + std::to_string(options.max_iterations));
  require(options.preconditioner_block >= 0, ErrorCode::invalid_argument, where,
          "preconditioner_block must be >= 0 (0 = automatic), got " + std::to_string(options.preconditioner_block));
  if (method == rpy::SqrtMethod::chebyshev) rpy::sqrt_detail::require_chebyshev_bounds(options, where);
}

// What steers the iteration must be the same on every rank, or the ranks would part ways: the
// options and the number of right-hand sides.
void require_same_options(const Communicator& comm, const rpy::SqrtOptions& o, std::size_t nrhs, const char* where) {
  const bool same = same_on_every_rank(
      comm, {static_cast<double>(o.method), static_cast<double>(o.preconditioner), o.tolerance,
             static_cast<double>(o.max_iterations), o.reorthogonalize ? 1.0 : 0.0, o.throw_if_not_converged ? 1.0 : 0.0,
             static_cast<double>(o.preconditioner_block), o.lambda_min, o.lambda_max,
             static_cast<double>(o.bound_estimate_iterations), static_cast<double>(nrhs)});
  require(same, ErrorCode::invalid_argument, where,
          "the ranks pass different options (method, preconditioner, tolerance, max_iterations, reorthogonalize, "
          "throw_if_not_converged, preconditioner_block, lambda_min, lambda_max or bound_estimate_iterations) "
          "or numbers of right-hand sides; every rank must pass the same ones");
}

// automatic: Lanczos without the preconditioner (docs/mpi.md, "Brownian displacements"; the
// serial MobilityOperator::apply_sqrt's automatic preconditioner is block).
rpy::SqrtOptions resolved(const rpy::SqrtOptions& options) {
  rpy::SqrtOptions r = options;
  if (r.method == rpy::SqrtMethod::automatic) r.method = rpy::SqrtMethod::lanczos;
  if (r.preconditioner == rpy::SqrtPreconditioner::automatic) r.preconditioner = rpy::SqrtPreconditioner::none;
  return r;
}

// One array of a sampler's call, by name.
struct NamedArray {
  const char* name;
  std::span<const double> values;
};

// The array sizes of a call with nrhs right-hand sides of n = 3 op.local_size() entries each.
void check_sizes(std::initializer_list<NamedArray> arrays, std::size_t n, std::size_t nrhs, const char* where) {
  require(nrhs > 0, ErrorCode::invalid_argument, where, "number of right-hand sides (nrhs) must be > 0");
  for (const NamedArray& a : arrays) {
    require(a.values.size() == n * nrhs, ErrorCode::invalid_input, where,
            std::string(a.name) + " has " + std::to_string(a.values.size()) + " entries, expected " +
                std::to_string(n * nrhs) +
                (nrhs > 1 ? " (nrhs " + std::to_string(nrhs) + " x " + std::to_string(n) +
                                ": 3 entries per particle of this rank)"
                          : ""));
  }
}

// The collective checks of a sampler's call (`where`): positions set, every input and output of
// nrhs x 3 op.local_size() entries, the inputs finite, the options valid, and the options and
// nrhs the same on every rank. Returns the resolved options.
template <class Operator>
rpy::SqrtOptions checked_call(const Operator& op, const char* where, std::initializer_list<NamedArray> inputs,
                              std::initializer_list<NamedArray> outputs, const rpy::SqrtOptions& options,
                              std::size_t nrhs = 1) {
  const Communicator& comm = op.communicator();
  require(op.global_size() > 0, ErrorCode::invalid_input, where, "positions not set (call set_positions first)");
  const std::size_t n = 3 * op.local_size();
  comm.run([&] {
    check_options(options, where);
    check_sizes(inputs, n, nrhs, where);
    check_sizes(outputs, n, nrhs, where);
    for (const NamedArray& a : inputs) require_finite(a.values, where, a.name, 3);
  });
  require_same_options(comm, options, nrhs, where);
  return resolved(options);
}

// Collective: throws numerical_failure on every rank where an output of any rank holds NaN/Inf.
void require_finite_outputs(const Communicator& comm, const char* where, std::initializer_list<NamedArray> outputs) {
  comm.run([&] {
    for (const NamedArray& a : outputs) rpy::detail::require_finite_result(a.values, where, a.name, "noise");
  });
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

// The Chebyshev square root (rpy/src/sqrt/chebyshev.cpp) on this rank's shares of nrhs columns
// of `segments` segments of 3 op.local_size() entries each: the bound estimate's Lanczos steps in
// the distributed space, from the serial start vector's shares, once for every column (the bounds
// do not depend on z); then the recurrence on all the columns, one product call per degree.
template <class Operator>
rpy::SqrtReport chebyshev_across_ranks(DistributedKrylovSpace& space, const detail::ColumnsProduct& product,
                                       const Operator& op, std::size_t segments, std::size_t nrhs, const double* z,
                                       double* w, const rpy::SqrtOptions& options) {
  const std::size_t n = 3 * op.local_size();
  const auto all = [&](const double* x, double* y, rpy::SqrtReport& report) {
    product(x, y, nrhs);
    ++report.operator_applications;
    report.vector_products += static_cast<long long>(nrhs);
    op.communicator().run([&] {
      rpy::sqrt_detail::require_finite_product(y, segments * n, nrhs, "sqrt_apply(chebyshev)",
                                               report.operator_applications);
    });
  };
  const rpy::sqrt_detail::ChebyshevProducts products{space,
                                                     [&product](const double* x, double* y) { product(x, y, 1); },
                                                     3 * op.offset(),
                                                     n,
                                                     all,
                                                     segments * n * nrhs,
                                                     segments,
                                                     3 * op.global_size()};
  return rpy::sqrt_detail::chebyshev_sqrt_in_space(products, z, w, options);
}

// The serial block preconditioner's blocks of the whole set for `matrix` (global_blocks.hpp), with
// the serial sampler's block size (options.preconditioner_block, or automatic_block of the whole
// set): those the operator keeps where they were built for its current positions, this block size,
// matrix and viscosity, else built (collective) and kept in their place. `stats` receives the
// build's cost, or reused. Every input of the decision is the same on every rank (set_positions and
// the builds are collective, the options are checked alike), and one reduction confirms it, so no
// rank gathers for a build that another skips.
template <class Operator>
std::shared_ptr<const detail::GlobalBlocks> global_blocks(const Operator& op, const rpy::SqrtOptions& options,
                                                          rpy::PreconditionedMatrix matrix,
                                                          BlockPreconditionerStats& stats) {
  const std::size_t block = options.preconditioner_block > 0
                                ? static_cast<std::size_t>(options.preconditioner_block)
                                : rpy::BlockPreconditioner::automatic_block(op.global_size());
  const SamplerBlocks& kept = op.sampler_blocks();
  const bool here = kept.get() != nullptr && kept.get()->built_for(block, matrix, op.viscosity());
  if (same_on_every_rank(op.communicator(), {here ? 1.0 : 0.0}) && here) {
    stats = BlockPreconditionerStats{};
    stats.reused = true;
    stats.particles_sent = kept.get()->build_cost().particles_sent;
    stats.particles_received = kept.get()->build_cost().particles_received;
    return kept.get();
  }
  detail::SamplerBlocksWriter::replace(kept, nullptr);  // the old blocks' memory before the new ones'
  detail::SamplerBlocksWriter::replace(
      kept, std::make_shared<const detail::GlobalBlocks>(op.communicator(), op.counts(), op.local_positions(),
                                                         op.local_radii(), op.viscosity(), block, matrix));
  stats = kept.get()->build_cost();
  return kept.get();
}

// A = G m G^T on nrhs columns of this rank's share, as rpy::BlockPreconditioner::precondition; the
// exchanges of G^T and G added to `stats`.
detail::ColumnsProduct preconditioned(const detail::GlobalBlocks& blocks, const rpy::LinearOperatorView& m,
                                      BlockPreconditionerStats& stats) {
  return [&blocks, m, &stats](const double* x, double* y, std::size_t k) {
    std::vector<double> t(x, x + k * m.n);
    blocks.apply(rpy::BlockOp::apply_g_transpose, t.data(), k, stats.apply_g_transpose);  // G^T x
    m.apply(t, std::span<double>(y, k * m.n), k);                                         // M G^T x
    blocks.apply(rpy::BlockOp::apply_g, y, k, stats.apply_g);                             // G M G^T x
  };
}

// The Krylov samplers on a distributed operator, DistributedDirectRpy or DistributedFmmRpy (the
// same interface), w_c = m^{1/2} z_c for the nrhs columns of z and w, `m` the product on this
// rank's share: M (3 op.local_size() entries), or with rotation S M S on [x_t; x_r] (twice that;
// `matrix` scaled_grand). With the block preconditioner G = L^{-1} of the serial blocks of the
// whole set (global_blocks.hpp) they run on A = G m G^T and return w = G^{-1} A^{1/2} z, as
// BlockPreconditioner::sample does: each of G's entries is the serial one, so the product, and
// with it every step, is bit for bit the serial preconditioned sampler's where m's is.
template <class Operator>
rpy::SqrtReport sample_across_ranks(const Operator& op, const rpy::LinearOperatorView& m,
                                    rpy::PreconditionedMatrix matrix, std::size_t nrhs, const double* z, double* w,
                                    const rpy::SqrtOptions& r, InnerProductStats* stats) {
  const Communicator& comm = op.communicator();
  const std::size_t segments = matrix == rpy::PreconditionedMatrix::scaled_grand ? 2 : 1;
  BlockPreconditionerStats block_stats;
  std::shared_ptr<const detail::GlobalBlocks> blocks;
  if (r.preconditioner == rpy::SqrtPreconditioner::block) blocks = global_blocks(op, r, matrix, block_stats);
  const detail::ColumnsProduct product =
      blocks ? preconditioned(*blocks, m, block_stats)
             : detail::ColumnsProduct([&m](const double* x, double* y, std::size_t k) {
                 m.apply(std::span<const double>(x, k * m.n), std::span<double>(y, k * m.n), k);
               });
  rpy::SqrtReport report;
  if (r.method == rpy::SqrtMethod::chebyshev) {
    DistributedKrylovSpace space(comm, op.counts(), segments);
    report = chebyshev_across_ranks(space, product, op, segments, nrhs, z, w, r);
    if (stats != nullptr)
      *stats = {.seconds = space.communication_seconds(), .exchanges = space.exchanges(), .blocks = {}};
  } else {
    report = detail::lanczos_columns(comm, op.counts(), segments, product, nrhs, z, w, r, stats);
  }
  if (blocks) {
    blocks->apply(rpy::BlockOp::solve_g, w, nrhs, block_stats.solve_g);  // w = G^{-1} A^{1/2} z
    report.preconditioner_blocks = blocks->blocks();
  }
  if (stats != nullptr) stats->blocks = block_stats;
  return report;
}

// `sample(stats)`, and its inner products' time into `seconds` where not null (the
// inner_products_seconds of the samplers of one right-hand side).
template <class Sample>
rpy::SqrtReport with_seconds(double* seconds, Sample&& sample) {
  InnerProductStats stats;
  const rpy::SqrtReport report = sample(&stats);
  if (seconds != nullptr) *seconds = stats.seconds;
  return report;
}

// sqrt_apply: this rank's shares of w_c = M^{1/2} z_c (or the preconditioned sample) for nrhs
// columns.
template <class Operator>
rpy::SqrtReport translation_sample(const Operator& op, std::span<const double> local_z, std::span<double> local_w,
                                   std::size_t nrhs, const rpy::SqrtOptions& options, InnerProductStats* stats) {
  const rpy::SqrtOptions r =
      checked_call(op, kWhere, {{"local noise", local_z}}, {{"local output", local_w}}, options, nrhs);
  const rpy::LinearOperatorView m{3 * op.local_size(),
                                  [&op](std::span<const double> x, std::span<double> y, std::size_t k) {
                                    if (k == 1) {
                                      op.apply(x, y);
                                    } else {
                                      op.apply_block(x, y, k);
                                    }
                                  }};
  const rpy::SqrtReport report = sample_across_ranks(op, m, rpy::PreconditionedMatrix::translation, nrhs,
                                                     local_z.data(), local_w.data(), r, stats);
  require_finite_outputs(op.communicator(), kWhere, {{"local output", local_w}});
  return report;
}

// S M S on this rank's share of [x_t; x_r] (S = diag(I, a_i I)): rpy::MobilityOperator's scaled
// grand mobility (mobility.hpp, apply_sqrt_rotation) by the distributed product with rotation.
template <class Operator>
rpy::LinearOperatorView scaled_grand(const Operator& op) {
  const std::size_t n = 3 * op.local_size();
  return {2 * n, [&op, n](std::span<const double> x, std::span<double> y, std::size_t) {
            const std::span<const double> a = op.local_radii();
            std::vector<double> torques(n);
            for (std::size_t k = 0; k < n; ++k) torques[k] = a[k / 3] * x[n + k];  // S x
            op.apply(x.first(n), torques, y.first(n), y.subspan(n));               // M S x
            for (std::size_t k = 0; k < n; ++k) y[n + k] *= a[k / 3];              // S M S x
          }};
}

// sqrt_apply_rotation: this rank's shares of [w_t; w_r] = S^{-1} (S M S)^{1/2} [z_t; z_r] (or the
// preconditioned sample), packed into [x_t; x_r] and unpacked as rpy::MobilityOperator's
// do_apply_sqrt_rotation does.
template <class Operator>
rpy::SqrtReport rotation_sample(const Operator& op, std::span<const double> local_z_t,
                                std::span<const double> local_z_r, std::span<double> local_w_t,
                                std::span<double> local_w_r, const rpy::SqrtOptions& options,
                                InnerProductStats* stats) {
  const std::initializer_list<NamedArray> outputs = {{"local translational output", local_w_t},
                                                     {"local rotational output", local_w_r}};
  const rpy::SqrtOptions r =
      checked_call(op, kWhereRotation,
                   {{"local translational noise", local_z_t}, {"local rotational noise", local_z_r}}, outputs, options);
  // w' = (S M S)^{1/2} z on z = [z_t; z_r], then [w_t; w_r] = S^{-1} w', as the serial sampler.
  const std::size_t n = 3 * op.local_size();
  std::vector<double> z(2 * n), w(2 * n);
  std::copy(local_z_t.begin(), local_z_t.end(), z.begin());
  std::copy(local_z_r.begin(), local_z_r.end(), z.begin() + static_cast<std::ptrdiff_t>(n));
  const rpy::SqrtReport report = sample_across_ranks(op, scaled_grand(op), rpy::PreconditionedMatrix::scaled_grand, 1,
                                                     z.data(), w.data(), r, stats);
  const std::span<const double> a = op.local_radii();
  for (std::size_t k = 0; k < n; ++k) {
    local_w_t[k] = w[k];
    local_w_r[k] = w[n + k] / a[k / 3];
  }
  require_finite_outputs(op.communicator(), kWhereRotation, outputs);
  return report;
}

// rotation_sample with the inner products' time only, into `seconds` where not null.
template <class Operator>
rpy::SqrtReport rotation_with_seconds(const Operator& op, std::span<const double> local_z_t,
                                      std::span<const double> local_z_r, std::span<double> local_w_t,
                                      std::span<double> local_w_r, const rpy::SqrtOptions& options, double* seconds) {
  return with_seconds(seconds, [&](InnerProductStats* stats) {
    return rotation_sample(op, local_z_t, local_z_r, local_w_t, local_w_r, options, stats);
  });
}

}  // namespace

rpy::SqrtReport sqrt_apply(const DistributedDirectRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           const rpy::SqrtOptions& options, double* inner_products_seconds) {
  return with_seconds(inner_products_seconds, [&](InnerProductStats* stats) {
    return translation_sample(op, local_z, local_w, 1, options, stats);
  });
}

rpy::SqrtReport sqrt_apply(const DistributedFmmRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           const rpy::SqrtOptions& options, double* inner_products_seconds) {
  return with_seconds(inner_products_seconds, [&](InnerProductStats* stats) {
    return translation_sample(op, local_z, local_w, 1, options, stats);
  });
}

rpy::SqrtReport sqrt_apply(const DistributedDirectRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           std::size_t nrhs, const rpy::SqrtOptions& options, InnerProductStats* stats) {
  return translation_sample(op, local_z, local_w, nrhs, options, stats);
}

rpy::SqrtReport sqrt_apply(const DistributedFmmRpy& op, std::span<const double> local_z, std::span<double> local_w,
                           std::size_t nrhs, const rpy::SqrtOptions& options, InnerProductStats* stats) {
  return translation_sample(op, local_z, local_w, nrhs, options, stats);
}

rpy::SqrtReport sqrt_apply_rotation(const DistributedDirectRpy& op, std::span<const double> local_z_translation,
                                    std::span<const double> local_z_rotation, std::span<double> local_w_translation,
                                    std::span<double> local_w_rotation, const rpy::SqrtOptions& options,
                                    double* inner_products_seconds) {
  return rotation_with_seconds(op, local_z_translation, local_z_rotation, local_w_translation, local_w_rotation,
                               options, inner_products_seconds);
}

rpy::SqrtReport sqrt_apply_rotation(const DistributedDirectRpy& op, std::span<const double> local_z_translation,
                                    std::span<const double> local_z_rotation, std::span<double> local_w_translation,
                                    std::span<double> local_w_rotation, const rpy::SqrtOptions& options,
                                    InnerProductStats& stats) {
  return rotation_sample(op, local_z_translation, local_z_rotation, local_w_translation, local_w_rotation, options,
                         &stats);
}

rpy::SqrtReport sqrt_apply_rotation(const DistributedFmmRpy& op, std::span<const double> local_z_translation,
                                    std::span<const double> local_z_rotation, std::span<double> local_w_translation,
                                    std::span<double> local_w_rotation, const rpy::SqrtOptions& options,
                                    double* inner_products_seconds) {
  return rotation_with_seconds(op, local_z_translation, local_z_rotation, local_w_translation, local_w_rotation,
                               options, inner_products_seconds);
}

rpy::SqrtReport sqrt_apply_rotation(const DistributedFmmRpy& op, std::span<const double> local_z_translation,
                                    std::span<const double> local_z_rotation, std::span<double> local_w_translation,
                                    std::span<double> local_w_rotation, const rpy::SqrtOptions& options,
                                    InnerProductStats& stats) {
  return rotation_sample(op, local_z_translation, local_z_rotation, local_w_translation, local_w_rotation, options,
                         &stats);
}

}  // namespace rpyfmm::mpi
