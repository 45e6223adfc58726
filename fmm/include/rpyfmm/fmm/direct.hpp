// rpyfmm — direct O(N^2) sums of the Laplace kernel G(r) = 1/r (no 1/(4 pi)).
//
// For charge vectors q^(d), d = 0..nd-1, at sources y_j, and targets x,
//   phi(x)        = sum_j q_j / |x - y_j|                              potential
//   grad phi(x)   = -sum_j q_j (x - y_j) / |x - y_j|^3                 gradient of the potential
//   hess phi(x)   =  sum_j q_j (3 r r^T / |r|^5 - I / |r|^3), r = x - y_j   Hessian of the potential
// (The RPY operator uses E = -grad phi and T = -hess phi, docs/theory/rpy.md.) Pairs at distance 0 are
// skipped (the self pair when targets are the sources, and any target that
// coincides with a source): they contribute nothing, silently. Pairs so far
// apart that r^2 overflows contribute their limit 0; pairs closer than about
// 1e-60 overflow the Hessian's 1/r^5 (doubles, like any direct sum).
//
// Results: nd x M x 10 doubles, per target
//   [pot, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz];
// columns of outputs not requested are set to 0 and cost nothing.
//
// The same loops are the FMM's near-field (P2P) kernel: laplace_p2p_add()
// is the unchecked, serial, accumulating form for box-to-box interactions.
#pragma once

#include <cstddef>
#include <span>

namespace rpyfmm::fmm {

/// Output selection (bit mask; combine with |).
enum Output : unsigned { potential = 1u, gradient = 2u, hessian = 4u };
inline constexpr unsigned all_outputs = potential | gradient | hessian;

/// Doubles per target in the results: [pot, gx, gy, gz, hxx, hyy, hzz, hxy, hxz, hyz].
inline constexpr std::size_t result_width = 10;
/// Column indices into one result row.
enum Column : std::size_t { col_pot = 0, col_gx, col_gy, col_gz, col_hxx, col_hyy, col_hzz, col_hxy, col_hxz, col_hyz };

/// Direct Laplace sums, OpenMP-parallel over targets (each target summed by
/// one thread in a fixed order: results do not depend on the thread count).
///
/// sources: 3N (x0, y0, z0, x1, ...), N >= 1.
/// charges: nd x N (density d at charges[d*N + j]), nd >= 1.
/// targets: 3M, or empty to evaluate at the sources (M = N, self pair skipped).
/// outputs: non-empty subset of all_outputs.
/// results: nd x M x 10, overwritten.
/// Throws rpyfmm::Error naming the problem on wrong sizes, N = 0, nd = 0,
/// NaN/Inf coordinates or charges, or a bad output mask.
void laplace_direct(std::span<const double> sources, std::span<const double> charges, std::size_t nd,
                    std::span<const double> targets, unsigned outputs, std::span<double> results);

/// Structure-of-arrays view of points for the P2P kernel.
struct PointsSoA {
  const double* x = nullptr;
  const double* y = nullptr;
  const double* z = nullptr;
  std::size_t n = 0;
};

/// P2P: adds the contributions of `sources` (charges q[d*ldq + j], j < sources.n,
/// d < nd) at `targets` to out[d*ldo + t*10 + column] (+=, only the requested
/// columns are touched). Serial, no validation (the caller has validated);
/// pairs at distance 0 contribute nothing. Vectorized (see direct_simd.hpp).
void laplace_p2p_add(const PointsSoA& sources, const double* q, std::size_t ldq, std::size_t nd,
                     const PointsSoA& targets, unsigned outputs, double* out, std::size_t ldo);

}  // namespace rpyfmm::fmm
