// rpyfmm::bd — the drift and the Brownian displacements of one step with rotation
// (docs/theory/bd.md Sec. 7):
//
//     [U; W] = M [F; T],   [w_t; w_r] = B [z_t; z_r],   B B^T = M  (the 6N x 6N grand mobility)
//
// by the operator's grand mobility (MobilityOperator::apply(F, T, U, W)) and its rotational
// sampler (apply_sqrt_rotation). z_t is the translational noise of a step without rotation,
// fill_normal(seed, step) (stream 0); z_r comes from its own stream, kRotationNoiseStream, so that
// turning rotation on draws the same z_t. With free draining M is diagonal, w_t = z_t /
// sqrt(6 pi eta a) is then bitwise the displacement of a step without rotation, and the rotations
// are independent of it.
#pragma once

#include <cstdint>
#include <span>

#include "rpyfmm/bd/sampling.hpp"
#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::bd {

/// Philox stream of the rotational noise z_r (normal3(seed, step, stream, particle)): apart from
/// stream 0 (the translational z_t) and from the streams the operators draw themselves with the
/// same (seed, step) key (PSE: 1 and 2), so that no two noises of a step are correlated.
inline constexpr std::uint32_t kRotationNoiseStream = 3;

/// A 6N vector as its translational and rotational halves (3N each).
template <class T>
struct GrandVector {
  std::span<T> translation, rotation;
};

/// velocities = M loads ([U; W] = M [F; T]) and, unless z.translation is empty (kT = 0), the
/// Brownian sample w = B z with B B^T = M. Products are skipped (zeros) when every force and
/// torque is zero. The sampler follows `options` (apply_sqrt_rotation: the exact root for free
/// draining, Lanczos with the block preconditioner by default otherwise). Throws not_supported
/// unless mobility.supports_rotation().
DriftNoiseReport rotational_drift_and_noise(const rpy::MobilityOperator& mobility, GrandVector<const double> loads,
                                            GrandVector<const double> z, GrandVector<double> velocities,
                                            GrandVector<double> w, const SqrtOptions& options);

}  // namespace rpyfmm::bd
