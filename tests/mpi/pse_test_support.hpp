// The PSE of the MPI layer's periodic rigid-body tests (test_distributed_rigid_periodic.cpp,
// test_distributed_rigid_bd.cpp): the serial PseRpy and DistributedPseRpy built with the same
// options, so that their products agree to round-off (docs/mpi.md "Distributed PSE").
#pragma once

#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace rpyfmm_mpi_test {

/// PSE at 1e-6 with double-precision wave grids, as DistributedPseRpy's grids are.
inline rpyfmm::rpy::pse::PseOptions double_grid_pse_options() {
  rpyfmm::rpy::pse::PseOptions o;
  o.tolerance = 1e-6;
  o.wave_precision = rpyfmm::rpy::pse::WavePrecision::double_precision;
  return o;
}

}  // namespace rpyfmm_mpi_test
