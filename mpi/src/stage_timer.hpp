// rpyfmm — the wall time of a stage added to a named entry of StageTimes (the per-stage times
// that the MPI layer reports, docs/mpi.md).
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

}  // namespace rpyfmm::mpi::detail
