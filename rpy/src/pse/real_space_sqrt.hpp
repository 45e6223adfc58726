// rpyfmm — the options of the split sampler's real-space Lanczos, M_r^{1/2} z1 ([PSE] eq. 18;
// docs/theory/pse.md), shared by the CPU and CUDA back ends. Private.
#pragma once

#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::rpy::pse::detail {

/// Lanczos to the PSE's Lanczos tolerance, without reorthogonalization. M_r is well conditioned
/// (its spectrum is set by each particle's neighbourhood), and Lanczos for a matrix function
/// converges in finite precision as in exact arithmetic up to rounding-level terms (Druskin,
/// Greenbaum & Knizhnerman, SIAM J. Sci. Comput. 19 (1998) 38). Measured on M_r (8000
/// particles, phi = 0.05, tolerances 1e-3 / 1e-6 / 1e-8): the same iteration counts (7 / 27 / 41)
/// and results equal to 1e-15 relative with and without the two Gram-Schmidt passes, whose
/// O(n m) work per step was 22-35% of the Lanczos time. Test:
/// PseSampler.PlainLanczosOnRealPartMatchesDenseSquareRoot.
inline SqrtOptions real_space_sqrt_options(double tolerance) {
  SqrtOptions o;
  o.method = SqrtMethod::lanczos;
  o.tolerance = tolerance;
  o.reorthogonalize = false;
  return o;
}

}  // namespace rpyfmm::rpy::pse::detail
