#include "rpyfmm/rpy/free_draining.hpp"

#include <cmath>
#include <numbers>

namespace rpyfmm::rpy {

SphereMobility sphere_mobility(double radius, double viscosity) {
  SphereMobility m;
  m.translation = 1.0 / (6.0 * std::numbers::pi * viscosity * radius);  // Stokes drag
  m.sqrt_translation = std::sqrt(m.translation);
  m.rotation = 1.0 / (8.0 * std::numbers::pi * viscosity * radius * radius * radius);  // Stokes torque
  m.sqrt_rotation = std::sqrt(m.rotation);
  return m;
}

FreeDrainingMobility::FreeDrainingMobility(Geometry geometry, double viscosity)
    : MobilityOperator(geometry, viscosity, "FreeDrainingMobility") {}

void FreeDrainingMobility::on_positions_set() {
  const auto a = radii();
  mobility_.resize(a.size());
  sqrt_mobility_.resize(a.size());
  rotation_mobility_.resize(a.size());
  sqrt_rotation_mobility_.resize(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    const SphereMobility m = sphere_mobility(a[i], viscosity());
    mobility_[i] = m.translation;
    sqrt_mobility_[i] = m.sqrt_translation;
    rotation_mobility_[i] = m.rotation;
    sqrt_rotation_mobility_[i] = m.sqrt_rotation;
  }
}

namespace {
/// out_i = d_i in_i per particle (3 entries each) for N particles.
void scale_particles(const std::vector<double>& d, const double* in, double* out) {
  const std::size_t n = d.size();
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (std::size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) out[3 * i + c] = d[i] * in[3 * i + c];
}
}  // namespace

void FreeDrainingMobility::do_apply(const double* forces, double* velocities, std::size_t nrhs) const {
  const std::size_t n = size();
  for (std::size_t k = 0; k < nrhs; ++k) scale_particles(mobility_, forces + 3 * n * k, velocities + 3 * n * k);
}

void FreeDrainingMobility::do_apply_rotation(const double* forces, const double* torques, double* velocities,
                                             double* angular_velocities) const {
  scale_particles(mobility_, forces, velocities);
  scale_particles(rotation_mobility_, torques, angular_velocities);
}

SqrtReport FreeDrainingMobility::do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                               const SqrtOptions&) const {
  const std::size_t n = size();
  for (std::size_t k = 0; k < nrhs; ++k) scale_particles(sqrt_mobility_, z.data() + 3 * n * k, w.data() + 3 * n * k);
  SqrtReport report;
  report.method = SqrtMethod::cholesky;  // a diagonal matrix's exact factor
  return report;
}

SqrtReport FreeDrainingMobility::do_apply_sqrt_rotation(std::span<const double> z_translation,
                                                        std::span<const double> z_rotation,
                                                        std::span<double> w_translation, std::span<double> w_rotation,
                                                        const SqrtOptions&) const {
  scale_particles(sqrt_mobility_, z_translation.data(), w_translation.data());
  scale_particles(sqrt_rotation_mobility_, z_rotation.data(), w_rotation.data());
  SqrtReport report;
  report.method = SqrtMethod::cholesky;  // a diagonal matrix's exact factor
  return report;
}

}  // namespace rpyfmm::rpy
