// rpyfmm Python bindings — the extension module `rpyfmm._rpyfmm`.
//
// One file per area: arrays.cpp (conversions), errors.cpp, fmm.cpp (Laplace
// FMM and direct sums), mobility.cpp (the mobility operators), samplers.cpp
// (square roots, noise, reports), bd.cpp (Brownian dynamics), rigid.cpp (rigid
// bodies of beads), rigid_dynamics.cpp (their Brownian dynamics), mpi.cpp (the MPI layer's operators,
// in a build with it). The package `rpyfmm` (python/rpyfmm/__init__.py)
// re-exports everything.
#include <omp.h>

#include <cstdint>
#include <filesystem>
#include <ios>
#include <new>
#include <stdexcept>
#include <system_error>

#include "common.hpp"
#include "device_arrays.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/threads.hpp"

namespace rpyfmm::python {
namespace {

void set_num_threads(long long n) {
  require_thread_count(n, "set_num_threads", false);
  omp_set_num_threads(static_cast<int>(n));
}

/// Test helper: throws the standard C++ exception named `kind` (errors.cpp maps each onto an
/// rpyfmm.Error subclass).
void throw_std(const std::string& kind) {
  const std::string what = "thrown " + kind;
  if (kind == "bad_alloc") throw std::bad_alloc();
  if (kind == "length_error") throw std::length_error(what);
  if (kind == "filesystem_error")
    throw std::filesystem::filesystem_error(what, "some/path", std::make_error_code(std::errc::is_a_directory));
  if (kind == "ios_base_failure") throw std::ios_base::failure(what);
  if (kind == "invalid_argument") throw std::invalid_argument(what);
  if (kind == "domain_error") throw std::domain_error(what);
  if (kind == "out_of_range") throw std::out_of_range(what);
  if (kind == "overflow_error") throw std::overflow_error(what);
  if (kind == "runtime_error") throw std::runtime_error(what);
  if (kind == "logic_error") throw std::logic_error(what);
  struct Plain : std::exception {
    std::string text;
    explicit Plain(std::string t) : text(std::move(t)) {}
    [[nodiscard]] const char* what() const noexcept override { return text.c_str(); }
  };
  throw Plain(what);
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
        "n must lie in [1, 4 x the hardware threads] (at most 1024), else InvalidArgumentError.\n"
        "Results do not depend on the thread count.");
  m.def("get_num_threads", &omp_get_max_threads, "Number of OpenMP threads the next parallel region uses.");
  m.def(
      "simd_level", [] { return std::string(rpyfmm::simd_level_name(rpyfmm::simd_level())); },
      "The instruction-set level the kernels run at: 'scalar', 'avx2' or 'avx512' (the widest the build\n"
      "and CPU support, lowered by the environment variable RPYFMM_SIMD; docs/reproducibility.md).");
  // Test helper: the address of the float64 buffer the C++ side reads for an array argument
  // (equal to arr.ctypes.data exactly when no copy was made).
  m.def(
      "_input_address",
      [](ArrayArg a) {
        const InArray in = as_input(a, "_input_address", "array");
        return reinterpret_cast<std::uintptr_t>(in.data);
      },
      nb::arg("array"));
  m.def("_throw", &throw_std, nb::arg("kind"));
  bind_fmm(m);
  bind_mobility(m);
  bind_pse_cuda(m);
  bind_device_arrays(m);
  bind_samplers(m);
  bind_bd(m);
  bind_rigid(m);
  bind_rigid_dynamics(m);
#ifdef RPYFMM_PYTHON_MPI
  bind_mpi(m);
#endif
}
