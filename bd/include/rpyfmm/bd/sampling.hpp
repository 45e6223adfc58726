// rpyfmm::bd — Brownian displacements. The square-root solvers live in
// rpyfmm::rpy (PSE's split sampler needs them); this header re-exports them.
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
/// counter-based generator keyed by (seed, step): MATH.md §4, PSE paper eq. 17.
SqrtReport brownian_displacement(const rpy::MobilityOperator& mobility, double kT, double dt, std::uint64_t seed,
                                 std::uint64_t step, std::span<double> displacement,
                                 const SqrtOptions& options = {});

}  // namespace rpyfmm::bd
