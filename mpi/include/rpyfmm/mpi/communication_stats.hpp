// rpyfmm — what an operator across ranks reports of its exchanges (docs/mpi.md): the statistics of
// DistributedDirectRpy and DistributedPseRpy (DistributedFmmRpy's FmmRpyCommunication has the same
// fields and more).
#pragma once

#include <cstdint>

namespace rpyfmm::mpi {

/// This rank's time in the operator's exchanges (waits included) during the last set_positions and
/// the last product, and the bytes it received from other ranks in that product; applies_seconds
/// sums apply_seconds over every product since the last set_positions (a sampler's many products).
/// What counts as an exchange and as a product is the operator's (its header and docs/mpi.md).
struct CommunicationStats {
  double set_positions_seconds = 0.0;
  double apply_seconds = 0.0;
  std::uint64_t apply_bytes_received = 0;
  double applies_seconds = 0.0;
};

}  // namespace rpyfmm::mpi
