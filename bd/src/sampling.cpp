#include "rpyfmm/bd/sampling.hpp"

#include <cmath>
#include <vector>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

SqrtReport brownian_displacement(const rpy::MobilityOperator& mobility, double kT, double dt, std::uint64_t seed,
                                 std::uint64_t step, std::span<double> displacement, const SqrtOptions& options) {
  require_positive(kT, "brownian_displacement", "kT");
  require_positive(dt, "brownian_displacement", "dt");
  std::vector<double> z(3 * mobility.size());
  rpy::fill_normal(z, seed, step);
  const SqrtReport report = mobility.apply_sqrt(z, displacement, options);
  const double scale = std::sqrt(2.0 * kT * dt);
  for (double& d : displacement) d *= scale;
  return report;
}

}  // namespace rpyfmm::bd
