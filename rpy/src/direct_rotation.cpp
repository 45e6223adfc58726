// rpyfmm — DirectRpy's grand mobility with rotation: [U; W] = M [F; T] over all pairs
// (docs/theory/rpy.md, "Rotation"; Wajnryb, Mizerski, Zuk & Szymczak 2013).
//
// U_i gets the translational product (DirectRpy::do_apply) plus c_ut (T_j x e); W_i gets
// c_wf (F_j x e) + (h I + k e e^T) T_j, summed over all sources by the vectorized pair loops of
// rotation_pair_sums.hpp, plus the self term T_i / (8 pi eta a_i^3). Each target is summed by one
// thread in a fixed order, so results do not depend on the thread count.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <vector>

#include "rotation_pair_sums.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::rpy {

void DirectRpy::do_apply_rotation(const double* forces, const double* torques, double* velocities,
                                  double* angular_velocities) const {
  do_apply(forces, velocities, 1);
  const std::size_t n = size();
  // Loads in structure-of-arrays form: fx fy fz tx ty tz, n each.
  std::vector<double> soa(6 * n);
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t c = 0; c < 3; ++c) {
      soa[c * n + j] = forces[3 * j + c];
      soa[(3 + c) * n + j] = torques[3 * j + c];
    }
  std::vector<std::size_t> id(n);
  std::iota(id.begin(), id.end(), std::size_t{0});
  const double* s = soa.data();
  const detail::RotationSources src{n,         x_.data(), y_.data(), z_.data(), equal_radii() ? nullptr : a_.data(),
                                    id.data(), s,         s + n,     s + 2 * n, s + 3 * n,
                                    s + 4 * n, s + 5 * n};
  // The sums carry 1/L^2 (ut, wf) and 1/L^3 (rr) in the units of length_units.hpp.
  const double inv_eta = 1.0 / viscosity();
  const int e2 = -2 * scale_exponent_, e3 = -3 * scale_exponent_;
  const auto nn = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(dynamic, 16)
  for (std::int64_t ii = 0; ii < nn; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const double* ti = torques + 3 * i;
    detail::RotationSums sums{};
    detail::near_rotation_sum(src, {x_[i], y_[i], z_[i], a_[i], i, {}, {}}, sums);
    const double self = rpy_rotation_self(a_[i]);
    for (std::size_t c = 0; c < 3; ++c) {
      velocities[3 * i + c] += inv_eta * std::ldexp(sums.ut[c], e2);
      angular_velocities[3 * i + c] =
          inv_eta * (std::ldexp(sums.wf[c], e2) + std::ldexp(sums.rr[c] + self * ti[c], e3));
    }
  }
}

}  // namespace rpyfmm::rpy
