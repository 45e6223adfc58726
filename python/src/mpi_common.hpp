// rpyfmm Python bindings — what the bindings of the MPI layer share (mpi.cpp, mpi_bd.cpp, mpi_rigid*.cpp): the
// MPI_Comm of an mpi4py communicator, the bound operators, the argument checks of a collective call
// agreed over the ranks (docs/mpi.md, "Python (mpi4py)"), and integer arrays (global indices,
// types, keys).
#pragma once

#include <mpi.h>

#include <exception>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "common.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/partition.hpp"
#include "rpyfmm/mpi/sqrt.hpp"

namespace rpyfmm::python {

/// The MPI_Comm of an mpi4py communicator, through its Fortran handle (comm.py2f(), then
/// MPI_Comm_f2c): needs neither mpi4py's C headers at build time nor its C API at run time.
/// Raises InvalidArgumentError naming `where` for anything else.
MPI_Comm comm_from(nb::handle comm, const char* where);

/// What the last sampler call on an operator reported on this rank (mpi::InnerProductStats: its
/// inner products' seconds and exchanges, and the block preconditioner's build and exchanges).
/// `recorded` is false before any sampler call. The Python property inner_products (mpi_stats.cpp).
struct InnerProductRecord {
  bool recorded = false;
  mpi::InnerProductStats stats;
};

/// A distributed operator and the mpi4py communicator its MPI_Comm belongs to (declared first:
/// released after the operator). The Python classes DistributedDirectRpy, DistributedFmmRpy, ...
/// (mpi.cpp) bind WithComm<Op>; mpi_rigid.cpp takes them as bead operators. `inner_products` is
/// written by the samplers under the object's lock.
template <class Op>
struct WithComm {
  nb::object comm;
  Op op;
  mutable InnerProductRecord inner_products{};
};

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

/// A NumPy array of integers that owns `values`.
template <class T>
nb::object adopt_integers(std::vector<T>&& values) {
  auto* heap = new std::vector<T>(std::move(values));
  nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<T>*>(p); });
  const std::size_t shape[1] = {heap->size()};
  return nb::cast(nb::ndarray<nb::numpy, T>(heap->data(), 1, shape, owner));
}

/// A NumPy copy of integers that owns its memory.
template <class T>
nb::object copy_integers(std::span<const T> values) {
  return adopt_integers(std::vector<T>(values.begin(), values.end()));
}

/// The space-filling curve named `name`: "morton" or "hilbert" (mpi::SfcCurve); else
/// InvalidArgumentError naming `where` and the choices. Not collective: callers agree on it.
mpi::SfcCurve curve_from(const std::string& name, const std::string& where);
/// The Python name of `curve`.
const char* curve_name(mpi::SfcCurve curve);

void bind_mpi_bd(nb::module_& m);
void bind_mpi_partition(nb::module_& m);
/// body_offsets as indices (a sequence of non-negative integers, as RigidBodies takes them); not
/// collective (mpi_rigid.cpp, mpi_rigid_dynamics.cpp call it inside `agreed`).
std::vector<std::size_t> offsets_of(nb::handle body_offsets, const std::string& where);

void bind_mpi_rigid(nb::module_& m);
/// rpyfmm.mpi.RigidBodyDynamics (mpi_rigid_dynamics.cpp); bind_mpi_rigid calls it.
void bind_mpi_rigid_dynamics(nb::module_& m);

}  // namespace rpyfmm::python
