// rpyfmm — the wall time of a stage added to a named entry of StageTimes or to a sum of seconds
// (the per-stage times and the communication statistics that the MPI layer reports, docs/mpi.md).
#pragma once

#include "rpyfmm/core/timer.hpp"

namespace rpyfmm::mpi::detail {

/// Runs `body` and adds its wall time to times[name].
template <class Body>
void timed(StageTimes& times, const char* name, Body&& body) {
  const StopWatch sw;
  body();
  times[name] += sw.seconds();
}

/// Runs `body` and adds its wall time to `seconds`.
template <class Body>
void timed(double& seconds, Body&& body) {
  const StopWatch sw;
  body();
  seconds += sw.seconds();
}

/// The sum of every stage's seconds.
[[nodiscard]] inline double total_seconds(const StageTimes& times) {
  double total = 0.0;
  for (const auto& [stage, seconds] : times) total += seconds;
  return total;
}

}  // namespace rpyfmm::mpi::detail
