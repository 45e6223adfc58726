// rpyfmm — what the PSE operators share beyond MobilityOperator, whatever computes them (the
// CPU's PseRpy, the GPU's PseRpyCuda): the split sampler keyed by (seed, step), the fused
// drift-and-noise pass, the parameters chosen and the stage times. Code that uses these (the
// BD engine) depends on this interface, not on a back end.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace rpyfmm::rpy::pse {

class PseOperator : public MobilityOperator {
 public:
  /// The choices made for the current radius/box/N (throws before set_positions).
  [[nodiscard]] virtual const PseParameters& parameters() const = 0;
  /// w = M^{1/2} z by the split sampler, z1 and z2 keyed by (seed, step) (pse_rpy.hpp).
  virtual SqrtReport sample(std::uint64_t seed, std::uint64_t step, std::span<double> w) const = 0;
  /// U = M F + noise_scale M^{1/2} z in one pass whose deterministic and Brownian wave parts
  /// share their FFTs ([PSE] Sec. III). For BD: noise_scale = sqrt(2 kT / dt).
  virtual SqrtReport apply_with_noise(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                                      std::uint64_t step, std::span<double> velocities) const = 0;
  /// Accumulated seconds per stage (the back end's list) and their reset.
  [[nodiscard]] virtual StageTimes stage_times() const = 0;
  virtual void reset_stage_times() const = 0;
  [[nodiscard]] SqrtMethod native_sampler() const override { return SqrtMethod::split; }
  [[nodiscard]] bool fuses_drift_and_noise() const override { return true; }

 protected:
  /// The PSE operators evaluate in the caller's units (no rescaling, unlike DirectRpy and FmmRpy):
  /// the viscosity must lie in ranges::kViscosity, whose bounds keep 1 / (eta V) and the wave
  /// space's products finite (a viscosity of 1e-300 gave NaN velocities).
  PseOperator(Geometry geometry, double viscosity, const char* where) : MobilityOperator(geometry, viscosity, where) {
    ranges::require_in(ranges::kViscosity, viscosity, where, "viscosity");
  }
  /// Throws unless the (common) radius lies in ranges::kRadius: a radius of 1e-300 made the
  /// volume a^3 of the cost model underflow to 0, one of 1e300 overflowed the wave space to NaN.
  void require_radius_in_range(const char* where) const {
    ranges::require_in(ranges::kRadius, radii().front(), where, "radius");
  }
};

}  // namespace rpyfmm::rpy::pse
