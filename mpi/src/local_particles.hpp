// rpyfmm — the checks of one rank's particles that the distributed operators' set_positions make
// before anything is exchanged (the message names no rank: Communicator::agree adds it).
#pragma once

#include <span>

namespace rpyfmm::mpi::detail {

/// Throws rpyfmm::Error naming `where` when the positions are not 3 per radius, a coordinate is
/// NaN or infinite, or a radius is not finite and > 0.
void check_local_particles(std::span<const double> positions, std::span<const double> radii, const char* where);

}  // namespace rpyfmm::mpi::detail
