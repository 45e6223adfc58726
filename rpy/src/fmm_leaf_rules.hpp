// The leaves of the Laplace FMM under FmmRpy's far field, whose near field is summed as exact RPY
// blocks (fmm_near_field.hpp): the automatic leaf capacity and fitted leaf grid, measured per
// plane-wave table and instruction-set level (bench/rpy/RESULTS.md). Shared by rpy::FmmRpy and each
// owner's serial FMM in mpi::DistributedFmmRpy.
#pragma once

#include <cstddef>

#include "rpyfmm/fmm/leaf_grid.hpp"

namespace rpyfmm::rpy::detail {

/// Points per leaf when the caller leaves the capacity at 0, for a tolerance.
[[nodiscard]] int default_leaf_capacity(double eps);

/// The fitted leaf grid (fmm::FmmOptions::fitted_grid) for a tolerance and n points.
[[nodiscard]] fmm::FittedGridRule fitted_grid_rule(double eps, std::size_t n);

}  // namespace rpyfmm::rpy::detail
