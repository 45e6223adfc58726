// rpyfmm — the rotational blocks of the PSE real-space part on the CPU (rotation_real_space_sum.hpp).
#include "rotation_real_space_sum.hpp"

#include <cmath>
#include <cstdint>

#include "kernels_common.hpp"

namespace rpyfmm::rpy::pse::detail {

namespace {

/// Loops below this many list entries run serially.
constexpr std::size_t kParallelPairs = 16384;

/// a x b.
inline void cross(const double* a, const double* b, double* out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}

}  // namespace

RotationRealSpaceSum::RotationRealSpaceSum(const PseParameters& p, const std::array<double, 3>& box, double viscosity)
    : box_(box), inv_mu_(1.0 / viscosity), table_(p.xi, p.radius, p.r_cut, p.tolerance / 10.0) {}

void RotationRealSpaceSum::apply(const RealSpaceSum::SlotLists& lists, std::span<const double> x, const double* forces,
                                 const double* torques, double* velocities, double* angular) const {
  const auto slots = static_cast<std::int64_t>(lists.order.size());
  const double inv_L[3] = {1.0 / box_[0], 1.0 / box_[1], 1.0 / box_[2]};
  const double self = table_.self();
#pragma omp parallel for schedule(dynamic, 64) if (lists.list.size() >= kParallelPairs)
  for (std::int64_t s = 0; s < slots; ++s) {
    const std::size_t i = lists.order[static_cast<std::size_t>(s)];
    double u[3] = {0.0, 0.0, 0.0};
    double w[3] = {self * torques[3 * i], self * torques[3 * i + 1], self * torques[3 * i + 2]};
    for (std::size_t e = lists.begin[static_cast<std::size_t>(s)]; e < lists.begin[static_cast<std::size_t>(s) + 1];
         ++e) {
      const std::size_t j = lists.order[static_cast<std::size_t>(lists.list[e])];
      double d[3];
      for (int c = 0; c < 3; ++c) d[c] = minimum_image(x[3 * i + c] - x[3 * j + c], box_[c], inv_L[c]);
      const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      const double* f = forces + 3 * j;
      const double* t = torques + 3 * j;
      if (r == 0.0) {  // coincident: the self block's form (c = k = 0 at r = 0)
        for (int c = 0; c < 3; ++c) w[c] += self * t[c];
        continue;
      }
      const RotationCoefficients k = table_(r);
      const double inv_r = 1.0 / r;
      const double e_ij[3] = {d[0] * inv_r, d[1] * inv_r, d[2] * inv_r};
      double txe[3], fxe[3];
      cross(t, e_ij, txe);
      cross(f, e_ij, fxe);
      const double et = e_ij[0] * t[0] + e_ij[1] * t[1] + e_ij[2] * t[2];
      for (int c = 0; c < 3; ++c) {
        u[c] += k.c * txe[c];
        w[c] += k.c * fxe[c] + k.h * t[c] + k.k * et * e_ij[c];
      }
    }
    for (int c = 0; c < 3; ++c) {
      velocities[3 * i + c] += inv_mu_ * u[c];
      angular[3 * i + c] += inv_mu_ * w[c];
    }
  }
}

}  // namespace rpyfmm::rpy::pse::detail
