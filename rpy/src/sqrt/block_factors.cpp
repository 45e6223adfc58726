// rpyfmm — the block preconditioner's pieces one block at a time: spatial blocks, a block's
// Cholesky factor and the triangular kernels with it (block_factors.hpp).
#include "rpyfmm/rpy/block_factors.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <numeric>

#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::rpy {
namespace {

using Matrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor>;

/// Splits order[begin, end) at its median along the axis of widest extent until every part has
/// at most max_block particles; appends the part boundaries to `offsets`. The split is by the
/// strict total order (coordinate along the axis, then index) and each final part is sorted by
/// index: a part's lower half is then the set of its floor(n / 2) smallest members in that order,
/// whatever permutation std::nth_element leaves, and a block's member order is its ascending
/// indices, so the partition (order and offsets) is a function of the positions alone, which a
/// distributed bisection reproduces exactly (mpi/src/distributed_bisection.hpp).
void bisect(std::span<const double> x, std::vector<std::size_t>& order, std::size_t begin, std::size_t end,
            std::size_t max_block, std::vector<std::size_t>& offsets) {
  const auto first = order.begin() + static_cast<std::ptrdiff_t>(begin);
  const auto last = order.begin() + static_cast<std::ptrdiff_t>(end);
  if (end - begin <= max_block) {
    std::sort(first, last);
    offsets.push_back(end);
    return;
  }
  const int axis = widest_axis(x, std::span<const std::size_t>(&*first, end - begin));
  const std::size_t mid = begin + (end - begin) / 2;
  std::nth_element(first, order.begin() + static_cast<std::ptrdiff_t>(mid), last, [&](std::size_t i, std::size_t j) {
    return bisection_less(x[3 * i + axis], i, x[3 * j + axis], j);
  });
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

int widest_axis(std::span<const double> positions, std::span<const std::size_t> members) {
  std::array<double, 3> lo{}, hi{};
  if (!members.empty()) {
    for (int c = 0; c < 3; ++c) lo[c] = hi[c] = positions[3 * members[0] + c];
  }
  for (const std::size_t i : members) {
    for (int c = 0; c < 3; ++c) {
      lo[c] = std::min(lo[c], positions[3 * i + c]);
      hi[c] = std::max(hi[c], positions[3 * i + c]);
    }
  }
  return widest_axis(lo, hi);
}

int widest_axis(const std::array<double, 3>& lo, const std::array<double, 3>& hi) {
  int axis = 0;
  for (int c = 1; c < 3; ++c)
    if (hi[c] - lo[c] > hi[axis] - lo[axis]) axis = c;
  return axis;
}

BlockPartition bisect_blocks(std::span<const double> positions, std::size_t max_block) {
  const std::size_t n = positions.size() / 3;
  BlockPartition partition;
  partition.order.resize(n);
  std::iota(partition.order.begin(), partition.order.end(), std::size_t{0});
  if (n > 0) bisect(positions, partition.order, 0, n, std::max<std::size_t>(max_block, 1), partition.offsets);
  return partition;
}

std::size_t block_dofs(PreconditionedMatrix matrix) {
  return matrix == PreconditionedMatrix::scaled_grand ? 6 : 3;
}

int block_scale_exponent(double min_radius, double max_radius, double viscosity) {
  // The self mobilities 1 / (6 pi eta a) of the radii's ends, largest first (finite: eta and a are
  // normal and positive; their product may be tiny or huge).
  const double largest = 1.0 / (6.0 * std::numbers::pi * viscosity * min_radius);
  const double smallest = 1.0 / (6.0 * std::numbers::pi * viscosity * max_radius);
  const double lo = 0x1p-60, hi = 0x1p60;
  if (smallest >= lo && largest <= hi) return 0;
  // Centre the logarithms of the ends on 0 (each is bounded, so the sum is exact and finite).
  const int centre = (std::ilogb(smallest) + std::ilogb(largest)) / 2;
  return -centre;
}

bool factor_block(std::span<const double> positions, std::span<const double> radii, double viscosity,
                  const Geometry& geometry, std::span<const std::size_t> members, PreconditionedMatrix matrix,
                  float* packed, int scale_exponent) {
  const bool periodic = geometry.is_periodic();
  const auto box = geometry.box();
  const std::size_t count = members.size();
  const auto dofs = static_cast<Eigen::Index>(block_dofs(matrix));
  const auto m = dofs * static_cast<Eigen::Index>(count);
  // The block of M or S M S (docs/theory/rpy.md; the lower triangle is all the factorization reads).
  Matrix block(m, m);
  for (std::size_t q = 0; q < count; ++q) {
    const std::size_t j = members[q];
    for (std::size_t p = q; p < count; ++p) {
      const std::size_t i = members[p];
      double d[3];
      for (int c = 0; c < 3; ++c) {
        d[c] = positions[3 * i + c] - positions[3 * j + c];
        if (periodic) d[c] -= box[c] * std::nearbyint(d[c] / box[c]);  // minimum image
      }
      double t[36];
      if (dofs == 6) {
        scaled_grand_pair(d, radii[i], radii[j], viscosity, t);
      } else {
        rpy_tensor(d, radii[i], radii[j], viscosity, t);
      }
      for (Eigen::Index r = 0; r < dofs; ++r)
        for (Eigen::Index c = 0; c < dofs; ++c)
          block(dofs * static_cast<Eigen::Index>(p) + r, dofs * static_cast<Eigen::Index>(q) + c) =
              static_cast<float>(std::ldexp(t[dofs * r + c], scale_exponent));
    }
  }
  Eigen::LLT<Matrix, Eigen::Lower> llt(block);
  // A singular block (coincident particles) keeps its diagonal: L = diag(sqrt(M_kk)); so does one
  // whose pair entries are not finite (the squared distances of pairs 1e154 apart overflow).
  const bool factored = block.triangularView<Eigen::Lower>().toDenseMatrix().allFinite() &&
                        llt.info() == Eigen::Success && llt.matrixL().toDenseMatrix().allFinite() &&
                        llt.matrixLLT().diagonal().minCoeff() > 0.0f;
  const Matrix& l = llt.matrixLLT();
  for (Eigen::Index i = 0; i < m; ++i) {
    for (Eigen::Index j = 0; j < i; ++j) *packed++ = factored ? l(i, j) : 0.0f;
    *packed++ = factored ? l(i, i) : std::sqrt(block(i, i));
  }
  return factored;
}

void apply_block_factor(BlockOp op, const float* l, std::size_t m, const double* in, double* out) {
  switch (op) {
    case BlockOp::apply_g:
      forward_substitution(l, m, in, out);
      break;
    case BlockOp::apply_g_transpose:
      back_substitution(l, m, in, out);
      break;
    case BlockOp::solve_g:
      lower_product(l, m, in, out);
      break;
  }
}

}  // namespace rpyfmm::rpy
