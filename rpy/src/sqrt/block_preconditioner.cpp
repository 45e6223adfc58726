// rpyfmm — BlockPreconditioner: spatial blocks and their Cholesky factors (see the header).
#include "rpyfmm/rpy/block_preconditioner.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <string>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::rpy {
namespace {

using Matrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor>;

/// Splits order[begin, end) at its median along the axis of widest extent until every part has
/// at most max_block particles; appends the part boundaries to `offsets`.
void bisect(std::span<const double> x, std::vector<std::size_t>& order, std::size_t begin, std::size_t end,
            std::size_t max_block, std::vector<std::size_t>& offsets) {
  if (end - begin <= max_block) {
    offsets.push_back(end);
    return;
  }
  std::array<double, 3> lo{x[3 * order[begin]], x[3 * order[begin] + 1], x[3 * order[begin] + 2]};
  std::array<double, 3> hi = lo;
  for (std::size_t k = begin; k < end; ++k) {
    for (int c = 0; c < 3; ++c) {
      lo[c] = std::min(lo[c], x[3 * order[k] + c]);
      hi[c] = std::max(hi[c], x[3 * order[k] + c]);
    }
  }
  int axis = 0;
  for (int c = 1; c < 3; ++c)
    if (hi[c] - lo[c] > hi[axis] - lo[axis]) axis = c;
  const std::size_t mid = begin + (end - begin) / 2;
  std::nth_element(order.begin() + static_cast<std::ptrdiff_t>(begin), order.begin() + static_cast<std::ptrdiff_t>(mid),
                   order.begin() + static_cast<std::ptrdiff_t>(end),
                   [&](std::size_t i, std::size_t j) { return x[3 * i + axis] < x[3 * j + axis]; });
  bisect(x, order, begin, mid, max_block, offsets);
  bisect(x, order, mid, end, max_block, offsets);
}

/// The 6 x 6 block (row-major) of the scaled grand mobility S M S between spheres i and j at
/// d = x_i - x_j (docs/theory/rpy.md section 7; rpy_rotation_kernel.hpp), S = diag(1, a) per particle:
///     [ M^tt_ij          -c_ut(i, j) [e]_x a_j     ]
///     [ -c_ut(j, i) [e]_x a_i   (h I + k e e^T) a_i a_j ] / eta,
/// where [e]_x v = e x v, since T_j x e = -[e]_x T_j and F_j x e = -[e]_x F_j.
void scaled_grand_pair(const double d[3], double ai, double aj, double viscosity, double out[36]) {
  double tt[9];
  rpy_tensor(d, ai, aj, viscosity, tt);
  const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  const RpyRotationScalars q = rpy_rotation_scalars(r, ai, aj);
  const double e[3] = {r > 0.0 ? d[0] / r : 0.0, r > 0.0 ? d[1] / r : 0.0, r > 0.0 ? d[2] / r : 0.0};
  const double cross[9] = {0.0, -e[2], e[1], e[2], 0.0, -e[0], -e[1], e[0], 0.0};  // [e]_x, row-major
  const double inv_eta = 1.0 / viscosity;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) {
      out[6 * a + b] = tt[3 * a + b];
      out[6 * a + b + 3] = -q.ut * cross[3 * a + b] * aj * inv_eta;
      out[6 * (a + 3) + b] = -q.wf * cross[3 * a + b] * ai * inv_eta;
      out[6 * (a + 3) + b + 3] = ((a == b ? q.h : 0.0) + q.k * e[a] * e[b]) * ai * aj * inv_eta;
    }
  }
}

// The three triangular kernels on one block, L packed by rows (row i: L_i0 .. L_ii, in
// single precision), vectors in double. From ~10^4 particles on they are bound by reading
// the factors (4 bytes per entry; AVX2 / AVX-512 clones measured no faster).
void forward_substitution(const float* l, std::size_t m, const double* in,
                          double* out) {  // L out = in: out = G in
  for (std::size_t i = 0; i < m; ++i) {
    const float* row = l + i * (i + 1) / 2;
    double s = in[i];
#pragma omp simd reduction(- : s)
    for (std::size_t j = 0; j < i; ++j) s -= static_cast<double>(row[j]) * out[j];
    out[i] = s / static_cast<double>(row[i]);
  }
}

void back_substitution(const float* l, std::size_t m, const double* in,
                       double* out) {  // L^T out = in: out = G^T in, row by row
  std::copy(in, in + m, out);
  for (std::size_t i = m; i-- > 0;) {
    const float* row = l + i * (i + 1) / 2;
    const double v = out[i] / static_cast<double>(row[i]);
    out[i] = v;
#pragma omp simd
    for (std::size_t j = 0; j < i; ++j) out[j] -= static_cast<double>(row[j]) * v;
  }
}

void lower_product(const float* l, std::size_t m, const double* in,
                   double* out) {  // out = L in = G^{-1} in
  for (std::size_t i = 0; i < m; ++i) {
    const float* row = l + i * (i + 1) / 2;
    double s = 0.0;
#pragma omp simd reduction(+ : s)
    for (std::size_t j = 0; j <= i; ++j) s += static_cast<double>(row[j]) * in[j];
    out[i] = s;
  }
}

}  // namespace

BlockPreconditioner::BlockPreconditioner(std::span<const double> positions, std::span<const double> radii,
                                         double viscosity, const Geometry& geometry, std::size_t max_block,
                                         PreconditionedMatrix matrix)
    : n_(radii.size()), dofs_(matrix == PreconditionedMatrix::scaled_grand ? 6 : 3) {
  require(positions.size() == 3 * n_, ErrorCode::invalid_input, "BlockPreconditioner",
          "positions has " + std::to_string(positions.size()) + " entries for " + std::to_string(n_) + " radii");
  order_.resize(n_);
  std::iota(order_.begin(), order_.end(), std::size_t{0});
  offsets_.push_back(0);
  if (n_ > 0) bisect(positions, order_, 0, n_, std::max<std::size_t>(max_block, 1), offsets_);

  const std::size_t nb = blocks();
  factor_offset_.resize(nb + 1, 0);
  for (std::size_t b = 0; b < nb; ++b) {
    const std::size_t m = dofs_ * (offsets_[b + 1] - offsets_[b]);
    factor_offset_[b + 1] = factor_offset_[b] + m * (m + 1) / 2;
  }
  factors_.assign(factor_offset_[nb], 0.0f);
  const bool periodic = geometry.is_periodic();
  const auto box = geometry.box();
  std::size_t diagonal = 0;

#pragma omp parallel for schedule(dynamic) reduction(+ : diagonal)
  for (std::size_t b = 0; b < nb; ++b) {
    const std::size_t first = offsets_[b];
    const std::size_t count = offsets_[b + 1] - first;
    const auto dofs = static_cast<Eigen::Index>(dofs_);
    const auto m = dofs * static_cast<Eigen::Index>(count);
    // The block of M or S M S (docs/theory/rpy.md; the lower triangle is all the factorization reads).
    Matrix block(m, m);
    for (std::size_t q = 0; q < count; ++q) {
      const std::size_t j = order_[first + q];
      for (std::size_t p = q; p < count; ++p) {
        const std::size_t i = order_[first + p];
        double d[3];
        for (int c = 0; c < 3; ++c) {
          d[c] = positions[3 * i + c] - positions[3 * j + c];
          if (periodic) d[c] -= box[c] * std::nearbyint(d[c] / box[c]);  // minimum image
        }
        double t[36];
        if (dofs_ == 6) {
          scaled_grand_pair(d, radii[i], radii[j], viscosity, t);
        } else {
          rpy_tensor(d, radii[i], radii[j], viscosity, t);
        }
        for (Eigen::Index r = 0; r < dofs; ++r)
          for (Eigen::Index c = 0; c < dofs; ++c)
            block(dofs * static_cast<Eigen::Index>(p) + r, dofs * static_cast<Eigen::Index>(q) + c) =
                static_cast<float>(t[dofs * r + c]);
      }
    }
    Eigen::LLT<Matrix, Eigen::Lower> llt(block);
    const bool factored = llt.info() == Eigen::Success && llt.matrixLLT().diagonal().minCoeff() > 0.0f;
    if (!factored) ++diagonal;  // singular block (coincident particles): L = diag(sqrt(M_kk))
    const Matrix& l = llt.matrixLLT();
    float* packed = factors_.data() + factor_offset_[b];
    for (Eigen::Index i = 0; i < m; ++i) {
      for (Eigen::Index j = 0; j < i; ++j) *packed++ = factored ? l(i, j) : 0.0f;
      *packed++ = factored ? l(i, i) : std::sqrt(block(i, i));
    }
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

void BlockPreconditioner::apply(Op op, double* x) const {
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
      switch (op) {
        case Op::apply_g:
          forward_substitution(l, m, in.data(), out.data());
          break;
        case Op::apply_g_transpose:
          back_substitution(l, m, in.data(), out.data());
          break;
        case Op::solve_g:
          lower_product(l, m, in.data(), out.data());
          break;
      }
      for (std::size_t p = 0; p < count; ++p)
        for (std::size_t c = 0; c < dofs_; ++c) x[entry(order_[first + p], c)] = out[dofs_ * p + c];
    }
  }
}

void BlockPreconditioner::apply_g(double* x) const {
  apply(Op::apply_g, x);
}
void BlockPreconditioner::apply_g_transpose(double* x) const {
  apply(Op::apply_g_transpose, x);
}
void BlockPreconditioner::solve_g(double* x) const {
  apply(Op::solve_g, x);
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
