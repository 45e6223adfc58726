// Sources of FmmRpy's near field gathered leaf by leaf into structure-of-arrays buffers, so that
// the pair loops vectorize (fmm_operator.cpp, fmm_rotation.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "rpyfmm/fmm/laplace_fmm.hpp"

namespace rpyfmm::rpy::detail {

// Sources of one or more leaves gathered into structure-of-arrays buffers (so that the pair
// loops vectorize), with their forces for every right-hand side (rhs k, component c at
// f[(3 k + c) m + q]) and, for symmetric blocks, velocity accumulators in the same layout.
struct GatheredSources {
  std::vector<double> x, y, z, a, f, u;
  std::vector<std::size_t> id;

  void gather(const fmm::NearField& near, std::span<const std::uint32_t> leaves, std::span<const double> pos,
              std::span<const double> radii, const double* forces, std::size_t n, std::size_t nrhs) {
    x.clear();
    y.clear();
    z.clear();
    a.clear();
    id.clear();
    for (std::uint32_t leaf : leaves)
      for (std::size_t j : near.sources(leaf)) {
        x.push_back(pos[3 * j]);
        y.push_back(pos[3 * j + 1]);
        z.push_back(pos[3 * j + 2]);
        a.push_back(radii[j]);
        id.push_back(j);
      }
    const std::size_t m = id.size();
    f.resize(3 * m * nrhs);
    for (std::size_t k = 0; k < nrhs; ++k) {
      const double* fk = forces + 3 * n * k;
      double* sk = f.data() + 3 * m * k;
      for (std::size_t q = 0; q < m; ++q)
        for (int c = 0; c < 3; ++c) sk[c * m + q] = fk[3 * id[q] + c];
    }
  }
  [[nodiscard]] std::size_t size() const noexcept { return id.size(); }
  [[nodiscard]] const double* forces(std::size_t k, int c) const noexcept { return f.data() + (3 * k + c) * size(); }
  [[nodiscard]] double* velocities(std::size_t k, int c) noexcept { return u.data() + (3 * k + c) * size(); }
};

}  // namespace rpyfmm::rpy::detail
