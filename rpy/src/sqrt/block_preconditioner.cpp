// rpyfmm — BlockPreconditioner: spatial blocks and their Cholesky factors (see the header).
#include "rpyfmm/rpy/block_preconditioner.hpp"

#include <algorithm>
#include <string>
#include <utility>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/block_factors.hpp"
#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::rpy {
BlockPreconditioner::BlockPreconditioner(std::span<const double> positions, std::span<const double> radii,
                                         double viscosity, const Geometry& geometry, std::size_t max_block,
                                         PreconditionedMatrix matrix)
    : n_(radii.size()), dofs_(matrix == PreconditionedMatrix::scaled_grand ? 6 : 3) {
  constexpr const char* where = "BlockPreconditioner";
  require(positions.size() == 3 * n_, ErrorCode::invalid_input, where,
          "positions has " + std::to_string(positions.size()) + " entries for " + std::to_string(n_) + " radii");
  // The blocks of M are formed from these: NaN positions, a zero radius or a NaN viscosity made
  // every factor NaN, and G x with it.
  require_finite(positions, where, "positions", 3);
  require_positive(viscosity, where, "viscosity");
  double min_radius = 1.0, max_radius = 1.0;
  for (std::size_t i = 0; i < n_; ++i) {
    require_positive(radii[i], where, "radius of particle " + std::to_string(i));
    min_radius = i == 0 ? radii[i] : std::min(min_radius, radii[i]);
    max_radius = i == 0 ? radii[i] : std::max(max_radius, radii[i]);
  }
  const int scale_exponent = block_scale_exponent(min_radius, max_radius, viscosity);
  BlockPartition partition = bisect_blocks(positions, max_block);
  order_ = std::move(partition.order);
  offsets_ = std::move(partition.offsets);

  const std::size_t nb = blocks();
  factor_offset_.resize(nb + 1, 0);
  for (std::size_t b = 0; b < nb; ++b)
    factor_offset_[b + 1] = factor_offset_[b] + packed_entries(dofs_ * (offsets_[b + 1] - offsets_[b]));
  factors_.assign(factor_offset_[nb], 0.0f);
  std::size_t diagonal = 0;

#pragma omp parallel for schedule(dynamic) reduction(+ : diagonal)
  for (std::size_t b = 0; b < nb; ++b) {
    const std::span<const std::size_t> members(order_.data() + offsets_[b], offsets_[b + 1] - offsets_[b]);
    if (!factor_block(positions, radii, viscosity, geometry, members, matrix, factors_.data() + factor_offset_[b],
                      scale_exponent))
      ++diagonal;
  }
  diagonal_blocks_ = diagonal;
}

BlockPreconditioner::BlockPreconditioner(const MobilityOperator& mobility, std::size_t max_block,
                                         PreconditionedMatrix matrix)
    : BlockPreconditioner(mobility.positions(), mobility.radii(), mobility.viscosity(), mobility.geometry(),
                          max_block == 0 ? automatic_block(mobility.size()) : max_block, matrix) {}

namespace {
std::size_t checked_block(const SqrtOptions& options) {
  require(options.preconditioner_block >= 0, ErrorCode::invalid_argument, "BlockPreconditioner",
          "preconditioner_block must be >= 0 (0 = automatic), got " + std::to_string(options.preconditioner_block));
  return static_cast<std::size_t>(options.preconditioner_block);
}
}  // namespace

BlockPreconditioner::BlockPreconditioner(const MobilityOperator& mobility, const SqrtOptions& options,
                                         PreconditionedMatrix matrix)
    : BlockPreconditioner(mobility, checked_block(options), matrix) {}

void BlockPreconditioner::apply(BlockOp op, double* x) const {
  const std::size_t nb = blocks();
#pragma omp parallel
  {
    std::vector<double> in, out;
#pragma omp for schedule(static)
    for (std::size_t b = 0; b < nb; ++b) {
      const std::size_t first = offsets_[b];
      const std::size_t count = offsets_[b + 1] - first;
      const std::size_t m = dofs_ * count;
      const float* l = factors_.data() + factor_offset_[b];
      in.resize(m);
      out.resize(m);
      for (std::size_t p = 0; p < count; ++p)
        for (std::size_t c = 0; c < dofs_; ++c) in[dofs_ * p + c] = x[entry(order_[first + p], c)];
      apply_block_factor(op, l, m, in.data(), out.data());
      for (std::size_t p = 0; p < count; ++p)
        for (std::size_t c = 0; c < dofs_; ++c) x[entry(order_[first + p], c)] = out[dofs_ * p + c];
    }
  }
}

void BlockPreconditioner::apply_g(double* x) const {
  apply(BlockOp::apply_g, x);
}
void BlockPreconditioner::apply_g_transpose(double* x) const {
  apply(BlockOp::apply_g_transpose, x);
}
void BlockPreconditioner::solve_g(double* x) const {
  apply(BlockOp::solve_g, x);
}

LinearOperatorView BlockPreconditioner::precondition(const LinearOperatorView& m) const {
  require(m.n == rows(), ErrorCode::invalid_input, "BlockPreconditioner",
          "operator of size " + std::to_string(m.n) + " for " + std::to_string(n_) + " particles (" +
              std::to_string(rows()) + " rows)");
  LinearOperatorView a;
  a.n = m.n;
  a.apply = [this, m](std::span<const double> x, std::span<double> y, std::size_t nrhs) {
    std::vector<double> t(x.begin(), x.end());
    for (std::size_t r = 0; r < nrhs; ++r) apply_g_transpose(t.data() + r * m.n);  // G^T x
    m.apply(t, y, nrhs);                                                           // M G^T x
    for (std::size_t r = 0; r < nrhs; ++r) apply_g(y.data() + r * m.n);            // G M G^T x
  };
  return a;
}

SqrtReport BlockPreconditioner::sample(const LinearOperatorView& m, std::span<const double> z, std::span<double> w,
                                       std::size_t nrhs, const SqrtOptions& options) const {
  SqrtOptions plain = options;
  plain.preconditioner = SqrtPreconditioner::none;
  SqrtReport report = sqrt_apply(precondition(m), z, w, nrhs, plain);  // (G M G^T)^{1/2} z
  for (std::size_t r = 0; r < nrhs; ++r) solve_g(w.data() + r * m.n);  // G^{-1} (G M G^T)^{1/2} z
  report.preconditioner_blocks = blocks();
  return report;
}

}  // namespace rpyfmm::rpy
