#include "rpyfmm/bd/rotation_sampling.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/free_draining.hpp"

namespace rpyfmm::bd {

namespace {

bool is_free_draining(const rpy::MobilityOperator& mobility) {
  return dynamic_cast<const rpy::FreeDrainingMobility*>(&mobility) != nullptr;
}

/// Free draining: the translational half exactly as a step without rotation (drift_and_noise),
/// the rotational half W_i = T_i / (8 pi eta a_i^3), w_r,i = z_r,i / sqrt(8 pi eta a_i^3)
/// (docs/theory/rpy.md Sec. 7, the self block; no translation-rotation coupling).
DriftNoiseReport free_draining_rotation(const rpy::MobilityOperator& mobility, GrandVector<const double> loads,
                                        GrandVector<const double> z, GrandVector<double> velocities,
                                        GrandVector<double> w, const SqrtOptions& options) {
  DriftNoiseReport report =
      drift_and_noise(mobility, loads.translation, z.translation, velocities.translation, w.translation, options);
  StopWatch watch;
  const auto a = mobility.radii();
  const double eta = mobility.viscosity();
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double mobility_rr = 1.0 / (8.0 * std::numbers::pi * eta * a[i] * a[i] * a[i]);
    const double root = std::sqrt(mobility_rr);
    for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
      velocities.rotation[k] = mobility_rr * loads.rotation[k];
      if (!z.rotation.empty()) w.rotation[k] = root * z.rotation[k];
    }
  }
  report.seconds_sqrt += watch.seconds();
  return report;
}

bool all_zero(std::span<const double> v) {
  for (double x : v)
    if (x != 0.0) return false;
  return true;
}

/// An operator with the grand mobility: [U; W] = M [F; T] by one product (none when F and T
/// vanish), then its rotational sampler.
DriftNoiseReport grand_mobility_step(const rpy::MobilityOperator& mobility, GrandVector<const double> loads,
                                     GrandVector<const double> z, GrandVector<double> velocities, GrandVector<double> w,
                                     const SqrtOptions& /*options*/) {
  DriftNoiseReport report;
  StopWatch watch;
  if (all_zero(loads.translation) && all_zero(loads.rotation)) {
    std::fill(velocities.translation.begin(), velocities.translation.end(), 0.0);
    std::fill(velocities.rotation.begin(), velocities.rotation.end(), 0.0);
  } else {
    mobility.apply(loads.translation, loads.rotation, velocities.translation, velocities.rotation);
    report.mobility_products = 1;
  }
  report.seconds_drift = watch.seconds();
  if (z.translation.empty()) return report;
  (void)w;
  fail(ErrorCode::not_supported, "rotational_drift_and_noise",
       "mobility '" + mobility.name() + "': the Brownian sample of the grand mobility is not available yet");
}

}  // namespace

bool supports_rotational_dynamics(const rpy::MobilityOperator& mobility) {
  return mobility.supports_rotation() || is_free_draining(mobility);
}

DriftNoiseReport rotational_drift_and_noise(const rpy::MobilityOperator& mobility, GrandVector<const double> loads,
                                            GrandVector<const double> z, GrandVector<double> velocities,
                                            GrandVector<double> w, const SqrtOptions& options) {
  require(supports_rotational_dynamics(mobility), ErrorCode::not_supported, "rotational_drift_and_noise",
          "mobility '" + mobility.name() + "' does not support rotation (torques and angular velocities)");
  const std::size_t n3 = 3 * mobility.size();
  const bool sizes = loads.translation.size() == n3 && loads.rotation.size() == n3 &&
                     velocities.translation.size() == n3 && velocities.rotation.size() == n3 &&
                     (z.translation.empty() || (z.translation.size() == n3 && z.rotation.size() == n3 &&
                                                w.translation.size() == n3 && w.rotation.size() == n3));
  require(sizes, ErrorCode::invalid_input, "rotational_drift_and_noise",
          "forces, torques, noise and outputs must have 3N entries each");
  if (is_free_draining(mobility)) return free_draining_rotation(mobility, loads, z, velocities, w, options);
  return grand_mobility_step(mobility, loads, z, velocities, w, options);
}

}  // namespace rpyfmm::bd
