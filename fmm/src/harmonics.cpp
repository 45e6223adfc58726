// Solid harmonics and normalizers (docs/theory/fmm.md, "Expansions"; Guan, dissertation, §2.2.1).
#include "rpyfmm/fmm/detail/harmonics.hpp"

#include <cmath>
#include <map>
#include <memory>
#include <mutex>

namespace rpyfmm::fmm::detail {

Harmonics::Harmonics(int pmax) : pmax_(pmax) {
  const int nfact = 2 * pmax + 8;
  fact_.assign(nfact + 1, 1.0);
  for (int k = 1; k <= nfact; ++k) fact_[k] = fact_[k - 1] * k;  // exact to ~k ulp; 110! ~ 1.6e178
  c_.resize(ncoef(pmax));
  inv_c_.resize(ncoef(pmax));
  rec_r_.resize(ncoef(pmax + 1));
  for (int n = 0; n <= pmax; ++n) {
    for (int m = 0; m <= n; ++m) {
      const double v = std::sqrt(fact_[n - m]) * std::sqrt(fact_[n + m]);
      c_[idx(n, m)] = v;
      inv_c_[idx(n, m)] = 1.0 / v;
    }
  }
  // 1/((n+1)^2 - m^2) for the R recurrence, stored at idx(n+1, m), m <= n.
  for (int n = 0; n < pmax; ++n)
    for (int m = 0; m <= n; ++m) rec_r_[idx(n + 1, m)] = 1.0 / double((n + 1) * (n + 1) - m * m);
}

const Harmonics& Harmonics::cached(int pmax) {
  static std::mutex mutex;
  static std::map<int, std::unique_ptr<Harmonics>> cache;
  std::lock_guard lock(mutex);
  auto& slot = cache[pmax];
  if (!slot) slot = std::make_unique<Harmonics>(pmax);
  return *slot;
}

double Harmonics::sqrt_binomial(int a, int b) const noexcept {
  return std::sqrt(fact_[a] / (fact_[b] * fact_[a - b]));
}

void Harmonics::regular(int p, double x, double y, double z, cplx* R) const noexcept {
  const double rho2 = x * x + y * y + z * z;
  const cplx w(x, y);
  R[0] = 1.0;
  for (int m = 0; m <= p; ++m) {
    if (m > 0) R[idx(m, m)] = -w / double(2 * m) * R[idx(m - 1, m - 1)];
    if (m + 1 <= p) R[idx(m + 1, m)] = z * R[idx(m, m)];
    for (int n = m + 1; n < p; ++n)
      R[idx(n + 1, m)] = (double(2 * n + 1) * z * R[idx(n, m)] - rho2 * R[idx(n - 1, m)]) * rec_r_[idx(n + 1, m)];
  }
}

void Harmonics::singular(int p, double x, double y, double z, cplx* S) const noexcept {
  const double rho2 = x * x + y * y + z * z;
  const double inv = 1.0 / rho2;
  const cplx w(x, y);
  S[0] = 1.0 / std::sqrt(rho2);
  for (int m = 0; m <= p; ++m) {
    if (m > 0) S[idx(m, m)] = -double(2 * m - 1) * w * S[idx(m - 1, m - 1)] * inv;
    if (m + 1 <= p) S[idx(m + 1, m)] = double(2 * m + 1) * z * S[idx(m, m)] * inv;
    for (int n = m + 1; n < p; ++n)
      S[idx(n + 1, m)] = (double(2 * n + 1) * z * S[idx(n, m)] - double(n * n - m * m) * S[idx(n - 1, m)]) * inv;
  }
}

}  // namespace rpyfmm::fmm::detail
