// The loops of the direct Ewald references (ewald_reference.hpp, ewald_rotation_reference.hpp):
// every periodic image of every particle pair within a real-space radius, and every nonzero wave
// vector of the box within a radius in k.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <vector>

namespace pse_test {

/// pair(i, j, d, r) for every pair (i, j) and image n: d = x_i - x_j + n L (n integer per axis),
/// r = |d| < r_max; the particle with itself at n = 0 comes with r = 0.
template <class Pair>
void for_each_image_pair(const std::vector<double>& x, const std::array<double, 3>& L, double r_max, Pair&& pair) {
  const std::size_t n = x.size() / 3;
  std::array<int, 3> nim{};
  for (int d = 0; d < 3; ++d) nim[d] = static_cast<int>(std::ceil(r_max / L[d])) + 1;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < n; ++j)
      for (int p = -nim[0]; p <= nim[0]; ++p)
        for (int q = -nim[1]; q <= nim[1]; ++q)
          for (int s = -nim[2]; s <= nim[2]; ++s) {
            const double d[3] = {x[3 * i] - x[3 * j] + p * L[0], x[3 * i + 1] - x[3 * j + 1] + q * L[1],
                                 x[3 * i + 2] - x[3 * j + 2] + s * L[2]};
            const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            if (r < r_max) pair(i, j, d, r);
          }
}

/// mode(k, k2) for every wave vector k = 2 pi (p / L_x, q / L_y, s / L_z) != 0 with |k| <= k_max.
template <class Mode>
void for_each_wave_vector(const std::array<double, 3>& L, double k_max, Mode&& mode) {
  constexpr double pi = std::numbers::pi;
  std::array<int, 3> nk{};
  for (int d = 0; d < 3; ++d) nk[d] = static_cast<int>(std::ceil(k_max * L[d] / (2.0 * pi)));
  for (int p = -nk[0]; p <= nk[0]; ++p)
    for (int q = -nk[1]; q <= nk[1]; ++q)
      for (int s = -nk[2]; s <= nk[2]; ++s) {
        if (p == 0 && q == 0 && s == 0) continue;
        const double k[3] = {2.0 * pi * p / L[0], 2.0 * pi * q / L[1], 2.0 * pi * s / L[2]};
        const double k2 = k[0] * k[0] + k[1] * k[1] + k[2] * k[2];
        if (k2 <= k_max * k_max) mode(k, k2);
      }
}

}  // namespace pse_test
