// rpyfmm — DirectRpy's grand mobility with rotation: [U; W] = M [F; T] over all pairs
// (docs/theory/rpy.md, section 7; Wajnryb, Mizerski, Zuk & Szymczak, J. Fluid Mech. 731, R3 (2013)).
//
// The translational product (DirectRpy::do_apply), then per target the vectorized rotational pair
// sums of rotation_pair_sums.hpp over source blocks of kDirectBlock in increasing order, as the
// translational sums go (add_rotation_block_sums, direct_block_sums.hpp), plus the self term
// T_i / (8 pi eta a_i^3). (One fused pass over both was slower: 0.55 s against 0.37 s for
// N = 4000 at the AVX2 level, 1 thread; ac13890, 2026-12-05, 2-vCPU Intel Xeon with AVX-512.) Each target is summed by
// one thread in a fixed order, so results do not depend on the thread count; and a caller holding the sources in pieces
// that start at multiples of kDirectBlock gets the same bits (rpyfmm::mpi::DistributedDirectRpy, docs/mpi.md).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <vector>

#include "direct_block_sums.hpp"
#include "rotation_pair_sums.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::rpy {
namespace {

// Sources [j0, j0 + nb) of `s`.
detail::GrandSources source_block(const detail::GrandSources& s, std::size_t j0, std::size_t nb) {
  return {nb,        s.x + j0,  s.y + j0,  s.z + j0,  s.a == nullptr ? nullptr : s.a + j0,
          s.id + j0, s.fx + j0, s.fy + j0, s.fz + j0, s.tx + j0,
          s.ty + j0, s.tz + j0};
}

}  // namespace

void detail::add_rotation_block_sums(const DirectParticles& targets, std::size_t first_target, std::size_t n_targets,
                                     const GrandSources& sources, double* acc) {
  const auto n = static_cast<std::int64_t>(n_targets);
#pragma omp parallel for schedule(dynamic, 16)
  for (std::int64_t ii = 0; ii < n; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const GrandTarget target{targets.x[i], targets.y[i], targets.z[i], targets.a[i], first_target + i, {}, {}};
    double* out = acc + 6 * i;
    for (std::size_t j0 = 0; j0 < sources.m; j0 += kDirectBlock) {
      GrandSums sums{};
      rotation_pair_sum(source_block(sources, j0, std::min(kDirectBlock, sources.m - j0)), target, sums);
      for (std::size_t c = 0; c < 3; ++c) {
        out[c] += sums.u[c];
        out[3 + c] += sums.w[c];
      }
    }
  }
}

void DirectRpy::do_apply_rotation(const double* forces, const double* torques, double* velocities,
                                  double* angular_velocities) const {
  do_apply(forces, velocities, 1);
  const std::size_t n = size();
  // Loads in structure-of-arrays form, fx fy fz tx ty tz (n each), the torques scaled by 2^-e for
  // the units 2^e of length_units.hpp: the sums are then 2^e U and 2^(2e) W (rotation_pair_sums.hpp).
  const int e = scale_exponent_;
  std::vector<double> soa(6 * n);
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t c = 0; c < 3; ++c) {
      soa[c * n + j] = forces[3 * j + c];
      soa[(3 + c) * n + j] = std::ldexp(torques[3 * j + c], -e);
    }
  std::vector<std::size_t> id(n);
  std::iota(id.begin(), id.end(), std::size_t{0});
  const double* s = soa.data();
  const detail::GrandSources src{n,         x_.data(), y_.data(), z_.data(), equal_radii() ? nullptr : a_.data(),
                                 id.data(), s,         s + n,     s + 2 * n, s + 3 * n,
                                 s + 4 * n, s + 5 * n};
  std::vector<double> sums(6 * n, 0.0);
  detail::add_rotation_block_sums({x_.data(), y_.data(), z_.data(), a_.data(), inv_a_.data()}, 0, n, src, sums.data());
  const double inv_eta = 1.0 / viscosity();
  for (std::size_t i = 0; i < n; ++i) {
    const double self_r = rpy_rotation_self(a_[i]);
    for (std::size_t c = 0; c < 3; ++c) {
      velocities[3 * i + c] += std::ldexp(inv_eta * sums[6 * i + c], -e);
      angular_velocities[3 * i + c] = std::ldexp(inv_eta * (sums[6 * i + 3 + c] + self_r * s[(3 + c) * n + i]), -2 * e);
    }
  }
}

}  // namespace rpyfmm::rpy
