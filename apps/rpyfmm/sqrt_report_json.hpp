// rpyfmm CLI — the sampler's report in a command's --json line, shared by `sample` and its
// run across MPI ranks so that both print the same keys in the same order.
#pragma once

#include "cli_common.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::cli {

/// Adds iterations, error_estimate, operator_applications, converged, breakdown and
/// preconditioner_blocks of `report` to `line`.
void add_sqrt_report(JsonLine& line, const rpy::SqrtReport& report);

}  // namespace rpyfmm::cli
