// rpyfmm — the checks of one rank's particles (local_particles.hpp).
#include "local_particles.hpp"

#include <cmath>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi::detail {

void check_local_particles(std::span<const double> positions, std::span<const double> radii, const char* where) {
  require(positions.size() % 3 == 0, ErrorCode::invalid_input, where,
          "local positions have " + std::to_string(positions.size()) + " entries, not a multiple of 3");
  require_size(radii, positions.size() / 3, where, "local radii");
  require_finite(positions, where, "local positions", 3);
  for (std::size_t i = 0; i < radii.size(); ++i) {
    if (!(std::isfinite(radii[i]) && radii[i] > 0.0)) {
      fail(ErrorCode::invalid_argument, where,
           "radius of local particle " + std::to_string(i) + " must be finite and > 0, got " + format_number(radii[i]));
    }
  }
}

}  // namespace rpyfmm::mpi::detail
