// rpyfmm CLI — the sampler's report in a command's --json line, shared by `sample` and its
// run across MPI ranks so that both print the same keys in the same order.
#pragma once

#include "cli_common.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::cli {

/// Adds iterations, error_estimate, operator_applications, converged, breakdown and
/// preconditioner_blocks of `report` to `line`.
void add_sqrt_report(JsonLine& line, const rpy::SqrtReport& report);

/// Adds lambda_min and lambda_max of `report` to `line` where the sampler was Chebyshev (the
/// eigenvalue bounds it used).
void add_chebyshev_bounds(JsonLine& line, const rpy::SqrtReport& report);

}  // namespace rpyfmm::cli
