// rpyfmm Python bindings — what the bindings of the MPI layer share (mpi.cpp, mpi_bd.cpp): the
// MPI_Comm of an mpi4py communicator, and the argument checks of a collective call agreed over the
// ranks (docs/mpi.md, "Python (mpi4py)").
#pragma once

#include <mpi.h>

#include <exception>
#include <optional>
#include <utility>

#include "common.hpp"
#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::python {

/// The MPI_Comm of an mpi4py communicator, through its Fortran handle (comm.py2f(), then
/// MPI_Comm_f2c): needs neither mpi4py's C headers at build time nor its C API at run time.
/// Raises InvalidArgumentError naming `where` for anything else.
MPI_Comm comm_from(nb::handle comm, const char* where);

/// Runs `prepare` (argument checks and conversions, GIL held) on this rank and agrees on its
/// outcome over the ranks: returns its value when every rank succeeded, else every rank throws the
/// first failing rank's error (Communicator::agree).
template <class Prepare>
auto agreed(const mpi::Communicator& comm, Prepare&& prepare) {
  std::optional<decltype(prepare())> value;
  std::optional<Error> problem;
  try {
    value.emplace(prepare());
  } catch (const Error& e) {
    problem = e;
  } catch (const std::exception& e) {  // a failed conversion (nanobind, NumPy)
    problem = Error(ErrorCode::invalid_input, e.what());
  }
  {
    nb::gil_scoped_release release;
    comm.agree(problem);
  }
  return std::move(*value);
}

void bind_mpi_bd(nb::module_& m);

}  // namespace rpyfmm::python
