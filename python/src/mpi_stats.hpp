// rpyfmm Python bindings — what the MPI layer's operators report of their exchanges and work
// (docs/mpi.md, "Python (mpi4py)"): the C++ classes' communication(), exchange_counts(), counts()
// and sizes as properties of the Python classes bound in mpi.cpp, and the inner products of the
// last sampler call. Reading them is not collective.
#pragma once

#include "mpi_common.hpp"
#include "rpyfmm/mpi/direct_operator.hpp"
#include "rpyfmm/mpi/fmm_rpy.hpp"
#include "rpyfmm/mpi/laplace_fmm.hpp"
#include "rpyfmm/mpi/pse_operator.hpp"

namespace rpyfmm::python {

void add_statistics(nb::class_<WithComm<mpi::DistributedDirectRpy>>& cls);
void add_statistics(nb::class_<WithComm<mpi::DistributedFmmRpy>>& cls);
void add_statistics(nb::class_<WithComm<mpi::DistributedPseRpy>>& cls);
void add_statistics(nb::class_<WithComm<mpi::DistributedLaplaceFmm>>& cls);

}  // namespace rpyfmm::python
