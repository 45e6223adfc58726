// rpyfmm Python bindings — Brownian samplers (rpy/include/rpyfmm/rpy/sqrt.hpp,
// random.hpp): reports, Philox normal noise, spectrum bounds, and sqrt_apply
// on any symmetric positive definite operator given as a Python callable.
#include <nanobind/stl/string.h>

#include <cstring>

#include "common.hpp"
#include "object_lock.hpp"
#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/random.hpp"

namespace rpyfmm::python {
namespace {

std::string report_repr(const rpy::SqrtReport& r) {
  std::string s = "SqrtReport(method='" + std::string(rpy::to_string(r.method)) +
                  "', iterations=" + std::to_string(r.iterations) +
                  ", error_estimate=" + nb::cast<std::string>(nb::repr(nb::float_(r.error_estimate))) +
                  ", operator_applications=" + std::to_string(r.operator_applications) +
                  ", converged=" + (r.converged ? "True" : "False") + ")";
  return s;
}

/// The binding of sqrt_apply: w = M^{1/2} z for M given by a Python callable; `tol` is the
/// deprecated spelling of `tolerance`.
ArrayAndReport<rpy::SqrtReport> sqrt_apply(nb::callable matvec, ArrayArg z, OutArg out, const std::string& method,
                                           std::optional<double> tolerance, int max_iterations, bool reorthogonalize,
                                           bool throw_if_not_converged, double lambda_min, double lambda_max,
                                           int bound_estimate_iterations, std::optional<double> tol) {
  const std::string where = "sqrt_apply";
  const double t = renamed_keyword(tolerance, tol, rpy::SqrtOptions{}.tolerance, where, "tolerance", "tol");
  const rpy::SqrtOptions o = sqrt_options(method, t, max_iterations, reorthogonalize, throw_if_not_converged,
                                          lambda_min, lambda_max, bound_estimate_iterations);
  const InArray zz = as_input(z, where, "z");
  require(zz.ndim() == 1 && zz.size > 0, ErrorCode::invalid_input, where,
          "z has shape " + shape_string(zz.shape) + ", expected (n,)");
  OutArray w = make_output(out, zz.shape, where, &zz);
  rpy::LinearOperatorView view;
  view.n = zz.size;
  // The solver runs without the GIL; each product takes it to call `matvec` on a
  // read-only copy of x (an array owning its memory: matvec may keep it) and copies the
  // result into y.
  view.apply = [&matvec, n = zz.size](std::span<const double> x, std::span<double> y, std::size_t nrhs) {
    nb::gil_scoped_acquire acquire;
    for (std::size_t k = 0; k < nrhs; ++k) {
      const ArrayResult xv = read_only_copy(x.subspan(k * n, n), {n});
      const InArray r = as_input(matvec(xv.o), "sqrt_apply", "matvec result");
      require(r.size == n, ErrorCode::invalid_input, "sqrt_apply",
              "matvec returned " + std::to_string(r.size) + " entries, expected " + std::to_string(n));
      std::memcpy(y.data() + k * n, r.data, n * sizeof(double));
    }
  };
  rpy::SqrtReport report;
  {
    nb::gil_scoped_release release;
    report = rpy::sqrt_apply(view, zz.span(), w.span(), 1, o);
  }
  return array_and_report(w.object, report);
}

void bind_sqrt_report(nb::module_& m) {
  nb::class_<rpy::SqrtReport>(m, "SqrtReport", "What a square-root solve did (iterations, error estimate).")
      .def_prop_ro(
          "method", [](const rpy::SqrtReport& r) { return std::string(rpy::to_string(r.method)); },
          "Method actually used: 'lanczos', 'chebyshev', 'cholesky', 'eigen' or 'split'.")
      .def_ro("iterations", &rpy::SqrtReport::iterations,
              "Lanczos steps (max over right-hand sides) / Chebyshev degree / 0 for dense methods.")
      .def_ro("error_estimate", &rpy::SqrtReport::error_estimate,
              "Relative error estimate: last relative change (Lanczos) or bound (Chebyshev); dimensionless.")
      .def_ro("operator_applications", &rpy::SqrtReport::operator_applications,
              "Calls of the operator (one call serves all right-hand sides).")
      .def_ro("vector_products", &rpy::SqrtReport::vector_products, "Products M x summed over right-hand sides.")
      .def_ro("converged", &rpy::SqrtReport::converged,
              "False only when throw_if_not_converged=False and the tolerance was not met.")
      .def_ro("breakdown", &rpy::SqrtReport::breakdown,
              "True when Lanczos found an invariant subspace (the result is then exact).")
      .def_ro("lambda_min", &rpy::SqrtReport::lambda_min, "Chebyshev: lower spectrum bound used (mobility units).")
      .def_ro("lambda_max", &rpy::SqrtReport::lambda_max, "Chebyshev: upper spectrum bound used (mobility units).")
      .def_ro("preconditioner_blocks", &rpy::SqrtReport::preconditioner_blocks,
              "Blocks of the block preconditioner (0: the sample is M^{1/2} z, unpreconditioned).")
      .def("__repr__", &report_repr);
}

void bind_spectrum_bounds(nb::module_& m) {
  nb::class_<rpy::SpectrumBounds>(m, "SpectrumBounds", "Padded extreme eigenvalue estimates (mobility units).")
      .def_ro("lambda_min", &rpy::SpectrumBounds::lambda_min, "Padded lower bound (smallest Ritz value / 2).")
      .def_ro("lambda_max", &rpy::SpectrumBounds::lambda_max,
              "Padded upper bound (largest Ritz value + Lanczos residual bound, x 1.01).")
      .def_ro("ritz_min", &rpy::SpectrumBounds::ritz_min, "Smallest Ritz value found.")
      .def_ro("ritz_max", &rpy::SpectrumBounds::ritz_max, "Largest Ritz value found.")
      .def_ro("iterations", &rpy::SpectrumBounds::iterations, "Lanczos steps taken.")
      .def("__repr__", [](const rpy::SpectrumBounds& b) {
        return "SpectrumBounds(lambda_min=" + std::to_string(b.lambda_min) +
               ", lambda_max=" + std::to_string(b.lambda_max) + ")";
      });
  m.def(
      "estimate_spectrum_bounds",
      [](const rpy::MobilityOperator& op, int iterations) {
        const CallGuard hold = guard("estimate_spectrum_bounds", op);
        nb::gil_scoped_release release;
        return rpy::estimate_spectrum_bounds(op.as_linear_operator(), iterations);
      },
      nb::arg("op"), nb::arg("iterations") = 30,
      "Extreme eigenvalues of the operator's current matrix by reorthogonalized Lanczos (for Chebyshev).");
}

void bind_sampler_functions(nb::module_& m) {
  m.def(
      "normal_noise",
      [](std::size_t n, std::uint64_t seed, std::uint64_t step, std::uint32_t stream, OutArg out) {
        OutArray z = make_output(out, {n, 3}, "normal_noise");
        {
          nb::gil_scoped_release release;
          rpy::fill_normal(z.span(), seed, step, stream);
        }
        return ArrayResult{z.object};
      },
      nb::arg("n"), nb::arg("seed"), nb::arg("step") = 0, nb::arg("stream") = 0, nb::arg("out") = nb::none(),
      "(n, 3) standard normal values from Philox4x32-10 keyed by (seed, step, stream, particle): the same\n"
      "stream as the C++ library, the CLI (`rpyfmm sample --seed`) and BD; independent of thread count.");
  m.def("sqrt_apply", &sqrt_apply, nb::arg("matvec"), nb::arg("z"), nb::arg("out") = nb::none(), nb::kw_only(),
        nb::arg("method") = "lanczos", nb::arg("tolerance").sig("0.001") = nb::none(), nb::arg("max_iterations") = 0,
        nb::arg("reorthogonalize") = true, nb::arg("throw_if_not_converged") = true, nb::arg("lambda_min") = 0.0,
        nb::arg("lambda_max") = 0.0, nb::arg("bound_estimate_iterations") = 30, nb::arg("tol") = nb::none(),
        "w = M^{1/2} z for a symmetric positive definite M given by matvec(x) -> M x (x: (n,) read-only, a\n"
        "copy owning its memory).\n"
        "Methods and keywords as MobilityOperator.apply_sqrt except 'auto'/'split' and the preconditioner\n"
        "(tol: the deprecated spelling of tolerance). Returns (w, SqrtReport).");
}

}  // namespace

void bind_samplers(nb::module_& m) {
  bind_sqrt_report(m);
  bind_spectrum_bounds(m);
  bind_sampler_functions(m);
}

}  // namespace rpyfmm::python
