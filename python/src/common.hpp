// rpyfmm Python bindings — shared helpers: NumPy array arguments as zero-copy
// views, output arrays (new or caller-given `out=`), geometry and option parsing.
//
// Conventions (docs/python.md):
//  * a float64, C-contiguous, CPU array is used in place (no copy);
//  * anything else NumPy can read as a real array (float32, integers, lists,
//    strided views) is converted once to a float64 C-contiguous copy;
//  * outputs are new float64 arrays in the shape of the input, or `out=`,
//    which must be a writable float64 C-contiguous array of the right size and
//    is returned itself (written in place);
//  * every bad argument throws rpyfmm::Error naming it; errors.cpp maps it to
//    the Python exception class of its ErrorCode with the message unchanged.
#pragma once

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/bd/potentials.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/geometry.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace nb = nanobind;

namespace rpyfmm::bd {
struct RigidDynamicsTotals;
}  // namespace rpyfmm::bd

namespace rpyfmm::python {

// Argument/result wrappers that only give the stubs precise types (the casters
// below accept any object and leave the checks to as_input / make_output).
struct ArrayArg {
  operator nb::handle() const { return h; }                   // NOLINT(google-explicit-constructor)
  [[nodiscard]] bool is_none() const { return h.is_none(); }  ///< anything NumPy reads as a real array
  nb::handle h;
};
struct OutArg {
  operator nb::handle() const { return h; }                   // NOLINT(google-explicit-constructor)
  [[nodiscard]] bool is_none() const { return h.is_none(); }  ///< None or a writable float64 C-contiguous array
  nb::handle h;
};
struct RadiusArg {
  operator nb::handle() const { return h; }                   // NOLINT(google-explicit-constructor)
  [[nodiscard]] bool is_none() const { return h.is_none(); }  ///< a number or an array of radii
  nb::handle h;
};
struct OptArrayArg {                         ///< None or anything NumPy reads as a real array
  operator nb::handle() const { return h; }  // NOLINT(google-explicit-constructor)
  [[nodiscard]] bool is_none() const { return h.is_none(); }
  nb::handle h;
};
struct BoxArg {
  operator nb::handle() const { return h; }                   // NOLINT(google-explicit-constructor)
  [[nodiscard]] bool is_none() const { return h.is_none(); }  ///< None, L or (Lx, Ly, Lz)
  nb::handle h;
};
struct ArrayResult {  ///< a float64 NumPy array
  nb::object o;
};
/// (array, report) pairs returned by the samplers.
template <class Report>
using ArrayAndReport = nb::typed<nb::tuple, ArrayResult, Report>;
template <class Report>
ArrayAndReport<Report> array_and_report(const nb::object& array, const Report& report) {
  return nb::borrow<ArrayAndReport<Report>>(nb::make_tuple(array, report));
}

/// A float64 C-contiguous read-only view of a Python array argument.
struct InArray {
  nb::object owner;  ///< the array read, or its converted copy: keeps the data alive
  const double* data = nullptr;
  std::size_t size = 0;
  std::vector<std::size_t> shape;
  bool copied = false;  ///< true when the argument had to be converted
  [[nodiscard]] std::span<const double> span() const { return {data, size}; }
  [[nodiscard]] std::size_t ndim() const { return shape.size(); }
};

/// Reads `obj` as a float64 C-contiguous array (a view when possible).
InArray as_input(nb::handle obj, const std::string& where, const std::string& name);

/// Shape as text, e.g. "(5, 2)".
std::string shape_string(const std::vector<std::size_t>& shape);

/// True for arrays with at least one dimension, lists and tuples (N radii); false for numbers,
/// NumPy scalars included (one radius).
bool is_array_like(nb::handle h);

/// A `radius` argument: one number (scalar = true, values = {a}) or an array of N radii
/// (scalar = false, values as given, 1-d required). rpyfmm::Error naming `where` otherwise.
struct Radii {
  std::vector<double> values;
  bool scalar = true;
};
Radii radii_from(RadiusArg radius, const std::string& where);

/// Checks that `a` is points data: (N, 3) or (3N,); returns N.
std::size_t require_points(const InArray& a, const std::string& where, const std::string& name);

/// Checks that `a` is a block of right-hand sides: (nrhs, N, 3) or (nrhs, 3N); returns nrhs.
std::size_t block_count(const InArray& a, const std::string& where, const std::string& name);

/// Checks that `a` holds six values per rigid body: (m, 6) or (6m,) (forces and torques, velocities
/// and angular velocities; the solver checks the entry count).
void require_body_rows(const InArray& a, const std::string& where, const std::string& name);

/// An output buffer: a new NumPy array or the caller's `out`.
struct OutArray {
  nb::object object;  ///< what the binding returns (`out` itself when given)
  double* data = nullptr;
  std::size_t size = 0;
  [[nodiscard]] std::span<double> span() const { return {data, size}; }
};

/// New float64 array of `shape`, or `out` checked to be writable, float64, C-contiguous,
/// of the same number of entries and not overlapping `input` (when given).
OutArray make_output(nb::handle out, const std::vector<std::size_t>& shape, const std::string& where,
                     const InArray* input = nullptr);

/// The arrays of a product with rotation: forces and torques of one shape, (N, 3) or (3N,), and new
/// velocities and angular velocities of that shape. `out` must be None (not supported together with
/// torques). MobilityOperator.apply and mpi.DistributedDirectRpy.apply with torques (mobility.cpp).
struct RotationArrays {
  InArray f, t;
  OutArray u, w;
};
RotationArrays rotation_arrays(ArrayArg forces, OptArrayArg torques, OutArg out, const std::string& where);
/// The same for any pair of inputs of one shape named `first_name` and `second_name` (e.g. the
/// noise z_translation, z_rotation of apply_sqrt_rotation), with new outputs of that shape.
RotationArrays paired_arrays(ArrayArg first, ArrayArg second, const std::string& where, const std::string& first_name,
                             const std::string& second_name);

/// (w_t, w_r, report) of apply_sqrt_rotation.
using RotationSample = nb::typed<nb::tuple, ArrayResult, ArrayResult, rpy::SqrtReport>;
/// The outputs u (w_t) and w (w_r) of `arrays` with the sampler's report.
inline RotationSample rotation_sample(const RotationArrays& arrays, const rpy::SqrtReport& report) {
  return nb::borrow<RotationSample>(nb::make_tuple(arrays.u.object, arrays.w.object, report));
}

/// Wraps a vector's storage as a NumPy array without copying (the array owns it).
ArrayResult adopt_vector(std::vector<double>&& values, const std::vector<std::size_t>& shape);

/// A NumPy array (values.size() / columns, columns) that owns a copy of `values`.
ArrayResult copy_rows(std::span<const double> values, std::size_t columns);

/// A read-only NumPy array that owns a copy of `values`: what Python callbacks receive, so that
/// an array they keep stays valid after the C++ buffer behind `values` is gone.
ArrayResult read_only_copy(std::span<const double> values, const std::vector<std::size_t>& shape);

/// None -> open; a number L -> periodic cube; three numbers -> periodic box.
rpy::Geometry geometry_from(nb::handle box, const std::string& where);
/// None for open geometry, else (Lx, Ly, Lz).
nb::object box_tuple(const rpy::Geometry& geometry);

/// "auto" | "automatic" | "lanczos" | "chebyshev" | "cholesky" | "eigen" | "split".
rpy::SqrtMethod sqrt_method_from(const std::string& name);
/// "auto" | "automatic" | "none" | "block".
rpy::SqrtPreconditioner sqrt_preconditioner_from(const std::string& name);

/// Issues a DeprecationWarning (raised as an exception where warnings are errors).
void warn_deprecated(const std::string& message);

/// A keyword of the one name for accuracy (`tolerance`, `sqrt_tolerance`) that replaced an older
/// spelling (`eps`, `tol`, `sqrt_tol`): the new keyword's value, else the old one's (with a
/// DeprecationWarning naming both), else `fallback`. Both given with different values raise an
/// InvalidArgumentError naming `where`.
double renamed_keyword(std::optional<double> value, std::optional<double> old_value, double fallback,
                       const std::string& where, const char* name, const char* old_name);

/// The sqrt solver options shared by every binding that samples.
rpy::SqrtOptions sqrt_options(const std::string& method, double tolerance, int max_iterations, bool reorthogonalize,
                              bool throw_if_not_converged, double lambda_min, double lambda_max,
                              int bound_estimate_iterations, const std::string& preconditioner = "none",
                              int preconditioner_block = 0);

/// A pair potential from Python (not None): a kind name ('wca', 'soft', ...) or a dict of
/// PairPotential fields (bd.cpp); errors name `where`.
bd::PairPotential pair_from(nb::handle pair, const std::string& where);

/// PseOptions from the keyword arguments of PseRpy, OpenPseRpy and mpi.DistributedPseRpy
/// (mobility.cpp); errors name `where`.
rpy::pse::PseOptions pse_options(const char* where, double tolerance, double xi, double r_cut, double window_eta,
                                 int fft_threads, std::size_t max_memory_bytes, bool fft_measure,
                                 const std::string& wave_precision, bool real_space_cache);
/// A PSE plan's parameters (PseRpy.parameters) as a dict (mobility.cpp).
nb::dict pse_parameters(const rpy::pse::PseParameters& p);

/// The `outputs` of LaplaceFmm.evaluate: an int mask, "all", one name, "potential|gradient", or a
/// sequence of names (fmm.cpp).
unsigned outputs_from(nb::handle outputs, const std::string& where);
/// Charges (N,) -> nd = 1; (nd, N) -> nd (fmm.cpp).
std::size_t densities(const InArray& q, const std::string& where);
/// The Laplace results' shape for charges q at m targets: (m, 10) or (nd, m, 10) (fmm.cpp).
std::vector<std::size_t> result_shape(const InArray& q, std::size_t m);

/// LaplaceFmm tree statistics (fmm::TreeStats) as a dict (fmm.cpp).
nb::dict tree_stats_dict(const fmm::TreeStats& s);

/// Rigid-body Brownian dynamics counters and seconds per stage (bd::RigidDynamicsTotals) as a dict
/// (rigid_dynamics.cpp; RigidBodyDynamics.totals, serial and across ranks).
nb::dict rigid_totals_dict(const bd::RigidDynamicsTotals& t);

/// Registers the exception classes and the rpyfmm::Error translator (errors.cpp).
void bind_errors(nb::module_& m);
void bind_fmm(nb::module_& m);
void bind_mobility(nb::module_& m);
void bind_samplers(nb::module_& m);
void bind_bd(nb::module_& m);
void bind_rigid(nb::module_& m);
void bind_rigid_dynamics(nb::module_& m);
/// The submodule `mpi` (mpi.cpp; only in a build with the MPI layer, RPYFMM_PYTHON_MPI).
void bind_mpi(nb::module_& m);

}  // namespace rpyfmm::python

namespace nanobind::detail {

#define RPYFMM_PASSTHROUGH_CASTER(Type, PyName)                                                                        \
  template <>                                                                                                          \
  struct type_caster<rpyfmm::python::Type> {                                                                           \
    NB_TYPE_CASTER(rpyfmm::python::Type, const_name(PyName))                                                           \
    bool from_python(handle src, uint8_t, cleanup_list*) noexcept {                                                    \
      value.h = src;                                                                                                   \
      return true;                                                                                                     \
    }                                                                                                                  \
    static handle from_cpp(const rpyfmm::python::Type& v, rv_policy, cleanup_list*) noexcept { return v.h.inc_ref(); } \
  };
RPYFMM_PASSTHROUGH_CASTER(ArrayArg, "numpy.typing.ArrayLike")
RPYFMM_PASSTHROUGH_CASTER(OptArrayArg, "numpy.typing.ArrayLike")
RPYFMM_PASSTHROUGH_CASTER(OutArg, "numpy.typing.NDArray[numpy.float64]")
RPYFMM_PASSTHROUGH_CASTER(RadiusArg, "float | numpy.typing.ArrayLike")
RPYFMM_PASSTHROUGH_CASTER(BoxArg, "float | tuple[float, float, float]")
#undef RPYFMM_PASSTHROUGH_CASTER

template <>
struct type_caster<rpyfmm::python::ArrayResult> {
  NB_TYPE_CASTER(rpyfmm::python::ArrayResult, const_name("numpy.typing.NDArray[numpy.float64]"))
  bool from_python(handle src, uint8_t, cleanup_list*) noexcept {
    value.o = borrow(src);
    return true;
  }
  static handle from_cpp(const rpyfmm::python::ArrayResult& v, rv_policy, cleanup_list*) noexcept {
    return v.o.inc_ref();
  }
};

}  // namespace nanobind::detail
