// rpyfmm — the open-boundary factor of the PSE wave-space multiplier (docs/theory/pse.md,
// "Open boundaries"). Private; shared by the CPU and CUDA scaling tables.
//
// The Stokeslet is (I lap - grad grad) B / eta with the biharmonic kernel B = r / (8 pi). Replacing
// B by -psi / (8 pi) with Askey's function psi(r) = (R/2) (1 - r/R)^2 for r < R, 0 beyond, which is
// positive definite in three dimensions (Askey 1973: (1 - r)_+^nu for nu >= 2), keeps the Fourier
// multiplier positive semi-definite and makes the kernel vanish beyond R. For r < R,
// -psi / (8 pi) = (r - R/2 - r^2 / (2R)) / (8 pi), and the quadratic term only shifts the
// Stokeslet by the constant -I / (4 pi eta R). In Fourier space 1/k^2 becomes q(kR) / k^2 with
//   q(t) = 1 + cos(t)/2 - 3 sin(t) / (2t) = sum_{n>=2} (-1)^n (n - 1) t^(2n) / (2n + 1)!,
// which is >= 0, ~ t^4/120 near 0 (so the k = 0 mode carries nothing) and oscillates about 1.
#pragma once

#include <cmath>

#include "rpyfmm/rpy/rpy_kernel.hpp"  // RPYFMM_HOST_DEVICE

namespace rpyfmm::rpy::pse::detail {

/// q(t) above: the series below t = 1 (the closed form cancels ~t^4 there), else the closed form.
RPYFMM_HOST_DEVICE inline double open_truncation_factor(double t) {
  if (t < 1.0) {
    // sum_{n>=2} (-1)^n (n-1) t^(2n) / (2n+1)!; terms fall by t^2 / ((2n+2)(2n+3)) <= 1/30, so
    // ten terms reach round-off.
    const double t2 = t * t;
    double term = t2 * t2 / 120.0;  // n = 2: (n-1) t^4 / 5!, without the (n-1) factor
    double sum = 0.0;
    for (int n = 2; n < 12; ++n) {
      sum += (n % 2 == 0 ? 1.0 : -1.0) * (n - 1) * term;
      term *= t2 / ((2.0 * n + 2.0) * (2.0 * n + 3.0));
    }
    return sum;
  }
  return 1.0 + 0.5 * std::cos(t) - 1.5 * std::sin(t) / t;
}

}  // namespace rpyfmm::rpy::pse::detail
