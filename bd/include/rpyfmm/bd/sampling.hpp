// rpyfmm::bd — Brownian displacements and the combined "drift + noise"
// products of one BD step. The square-root solvers live in rpyfmm::rpy (PSE's
// split sampler needs them); this header re-exports them.
#pragma once

#include <cstdint>
#include <span>

#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::bd {

using rpy::SqrtMethod;
using rpy::SqrtOptions;
using rpy::SqrtReport;

/// Brownian displacement sqrt(2 kT dt) M^{1/2} z with z drawn from the
/// counter-based generator keyed by (seed, step): docs/theory/bd.md; Fiore et al. 2017, eq. 17.
SqrtReport brownian_displacement(const rpy::MobilityOperator& mobility, double kT, double dt, std::uint64_t seed,
                                 std::uint64_t step, std::span<double> displacement, const SqrtOptions& options = {});

struct DriftNoiseReport {
  SqrtReport sqrt;                    ///< the square-root solver's report
  int mobility_products = 0;          ///< products with M, counting a block [F, z] product once
  bool shared_first_product = false;  ///< M F and Lanczos' first product M z came from one block pass
  double seconds_drift = 0.0;         ///< wall time of the M F (or block [F, z]) product
  double seconds_sqrt = 0.0;          ///< wall time of the rest of the square root
};

/// True when `mobility` samples M^{1/2} z by Lanczos on plain products for
/// `options` (explicit lanczos, or automatic on an operator whose native sampler is Lanczos,
/// such as direct and fmm), so that drift_and_noise() can share the first Krylov product.
bool samples_by_lanczos(const rpy::MobilityOperator& mobility, const SqrtOptions& options);

/// u = M F and w = M^{1/2} z for one step (each 3N; `forces` may be all zero,
/// `z` may be empty for a deterministic step, then `w` is untouched). With
/// options.preconditioner block or automatic, w = G^{-1} (G M G^T)^{1/2} z instead
/// (rpy::BlockPreconditioner: the same covariance, fewer products).
///
/// When samples_by_lanczos() holds, one block product M [F, z] (M [F, G^T z])
/// gives u and M z (G M G^T z), which the Lanczos solver takes as its first product
/// (rpy::sqrt_apply's `first_product`), so a step costs (Lanczos iterations + 1) operator
/// applications of which the first is a 2-vector block. Otherwise M F and the operator's own
/// sampler are called.
DriftNoiseReport drift_and_noise(const rpy::MobilityOperator& mobility, std::span<const double> forces,
                                 std::span<const double> z, std::span<double> u, std::span<double> w,
                                 const SqrtOptions& options);

/// True when `mobility` can give v = M F + noise_scale M^{1/2} z(seed, step) in one fused pass
/// for `options` (automatic or split): an operator that answers
/// MobilityOperator::fuses_drift_and_noise(), i.e. PSE, whose deterministic and Brownian
/// wave-space parts then share their FFTs (Fiore et al. 2017, Sec. III; docs/theory/pse.md).
bool fuses_drift_and_noise(const rpy::MobilityOperator& mobility, const SqrtOptions& options);

/// v = M F + noise_scale M^{1/2} z with the operator's own noise keyed by (seed, step) (for PSE:
/// z1 from stream 1 for the real-space part, z2 from the wave-space stream; not the z of
/// fill_normal(seed, step)). Requires fuses_drift_and_noise(); u and w are not separated.
DriftNoiseReport fused_drift_and_noise(const rpy::MobilityOperator& mobility, std::span<const double> forces,
                                       double noise_scale, std::uint64_t seed, std::uint64_t step, std::span<double> v,
                                       const SqrtOptions& options);

}  // namespace rpyfmm::bd
