// rpyfmm Python bindings — the extension module `rpyfmm._rpyfmm`.
//
// One file per area: arrays.cpp (conversions), errors.cpp, fmm.cpp (Laplace
// FMM and direct sums), mobility.cpp (the mobility operators), samplers.cpp
// (square roots, noise, reports), bd.cpp (Brownian dynamics), rigid.cpp (rigid
// bodies of beads), rigid_dynamics.cpp (their Brownian dynamics). The package `rpyfmm` (python/rpyfmm/__init__.py)
// re-exports everything.
#include <omp.h>

#include <cstdint>

#include "common.hpp"

namespace rpyfmm::python {
namespace {

void set_num_threads(int n) {
  require(n >= 1, ErrorCode::invalid_argument, "set_num_threads", "n must be >= 1, got " + std::to_string(n));
  omp_set_num_threads(n);
}

}  // namespace
}  // namespace rpyfmm::python

NB_MODULE(_rpyfmm, m) {
  using namespace rpyfmm::python;
  m.doc() =
      "rpyfmm: Laplace FMM, Rotne-Prager-Yamakawa mobility operators, Brownian samplers and "
      "Brownian dynamics (C++ extension; use the `rpyfmm` package).";
  m.attr("__version__") = RPYFMM_VERSION_STRING;
  bind_errors(m);
  m.def("set_num_threads", &set_num_threads, nb::arg("n"),
        "Sets the number of OpenMP threads used by later calls from this thread (omp_set_num_threads).\n\n"
        "Results do not depend on the thread count.");
  m.def("get_num_threads", &omp_get_max_threads, "Number of OpenMP threads the next parallel region uses.");
  // Test helper: the address of the float64 buffer the C++ side reads for an array argument
  // (equal to arr.ctypes.data exactly when no copy was made).
  m.def(
      "_input_address",
      [](ArrayArg a) {
        const InArray in = as_input(a, "_input_address", "array");
        return reinterpret_cast<std::uintptr_t>(in.data);
      },
      nb::arg("array"));
  bind_fmm(m);
  bind_mobility(m);
  bind_samplers(m);
  bind_bd(m);
  bind_rigid(m);
  bind_rigid_dynamics(m);
}
