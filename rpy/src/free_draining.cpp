#include "rpyfmm/rpy/free_draining.hpp"

#include <cmath>
#include <numbers>

namespace rpyfmm::rpy {

FreeDrainingMobility::FreeDrainingMobility(Geometry geometry, double viscosity)
    : MobilityOperator(geometry, viscosity, "FreeDrainingMobility") {}

void FreeDrainingMobility::on_positions_set() {
  const auto a = radii();
  mobility_.resize(a.size());
  sqrt_mobility_.resize(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    mobility_[i] = 1.0 / (6.0 * std::numbers::pi * viscosity() * a[i]);  // Stokes drag
    sqrt_mobility_[i] = std::sqrt(mobility_[i]);
  }
}

void FreeDrainingMobility::do_apply(const double* forces, double* velocities, std::size_t nrhs) const {
  const std::size_t n = size();
  for (std::size_t k = 0; k < nrhs; ++k) {
    const double* f = forces + 3 * n * k;
    double* u = velocities + 3 * n * k;
#pragma omp parallel for schedule(static) if (n >= 4096)
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) u[3 * i + c] = mobility_[i] * f[3 * i + c];
  }
}

SqrtReport FreeDrainingMobility::do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                               const SqrtOptions&) const {
  const std::size_t n = size();
  for (std::size_t k = 0; k < nrhs; ++k) {
#pragma omp parallel for schedule(static) if (n >= 4096)
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) w[3 * n * k + 3 * i + c] = sqrt_mobility_[i] * z[3 * n * k + 3 * i + c];
  }
  SqrtReport report;
  report.method = SqrtMethod::cholesky;  // a diagonal matrix's exact factor
  return report;
}

}  // namespace rpyfmm::rpy
