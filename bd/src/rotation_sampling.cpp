#include "rpyfmm/bd/rotation_sampling.hpp"

#include <algorithm>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

namespace {

bool all_zero(std::span<const double> v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return x == 0.0; });
}

/// [U; W] = M [F; T] by one product, or zeros without one when F and T vanish. Returns the products made.
int grand_drift(const rpy::MobilityOperator& mobility, GrandVector<const double> loads,
                GrandVector<double> velocities) {
  if (all_zero(loads.translation) && all_zero(loads.rotation)) {
    std::fill(velocities.translation.begin(), velocities.translation.end(), 0.0);
    std::fill(velocities.rotation.begin(), velocities.rotation.end(), 0.0);
    return 0;
  }
  mobility.apply(loads.translation, loads.rotation, velocities.translation, velocities.rotation);
  return 1;
}

}  // namespace

DriftNoiseReport rotational_drift_and_noise(const rpy::MobilityOperator& mobility, GrandVector<const double> loads,
                                            GrandVector<const double> z, GrandVector<double> velocities,
                                            GrandVector<double> w, const SqrtOptions& options) {
  require(mobility.supports_rotation(), ErrorCode::not_supported, "rotational_drift_and_noise",
          "mobility '" + mobility.name() + "' does not support rotation (torques and angular velocities)");
  DriftNoiseReport report;
  StopWatch watch;
  report.mobility_products = grand_drift(mobility, loads, velocities);
  report.seconds_drift = watch.seconds();
  if (z.translation.empty()) return report;
  watch.restart();
  report.sqrt = mobility.apply_sqrt_rotation(z.translation, z.rotation, w.translation, w.rotation, options);
  report.mobility_products += report.sqrt.operator_applications;
  report.seconds_sqrt = watch.seconds();
  return report;
}

}  // namespace rpyfmm::bd
