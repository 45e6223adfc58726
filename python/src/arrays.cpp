// rpyfmm Python bindings — array conversion helpers (see common.hpp).
#include <algorithm>
#include <cstdint>
#include <functional>
#include <numeric>

#include "common.hpp"
#include "device_arrays.hpp"
#include "rpyfmm/core/ranges.hpp"

namespace rpyfmm::python {
namespace {

using CView = nb::ndarray<const double, nb::c_contig, nb::device::cpu>;
using WView = nb::ndarray<double, nb::c_contig, nb::device::cpu>;

std::string py_type_name(nb::handle obj) {
  return nb::borrow<nb::str>(nb::handle(reinterpret_cast<PyObject*>(Py_TYPE(obj.ptr()))).attr("__name__")).c_str();
}

template <class View>
std::vector<std::size_t> shape_of(const View& v) {
  std::vector<std::size_t> shape(v.ndim());
  for (std::size_t d = 0; d < v.ndim(); ++d) shape[d] = v.shape(d);
  return shape;
}

std::string str_of(nb::handle obj) {
  return nb::steal<nb::str>(PyObject_Str(obj.ptr())).c_str();
}

std::size_t product(const std::vector<std::size_t>& shape) {
  return std::accumulate(shape.begin(), shape.end(), std::size_t{1}, std::multiplies<>());
}

}  // namespace

std::string shape_string(const std::vector<std::size_t>& shape) {
  std::string s = "(";
  for (std::size_t d = 0; d < shape.size(); ++d) s += (d ? ", " : "") + std::to_string(shape[d]);
  return s + (shape.size() == 1 ? ",)" : ")");
}

InArray as_input(nb::handle obj, const std::string& where, const std::string& name) {
  InArray in;
  if (obj.is_none()) fail(ErrorCode::invalid_input, where, name + " is None, expected an array");
  CView view;
  if (!nb::try_cast(obj, view, /*convert=*/false)) {
    // Not a float64 C-contiguous CPU array: one conversion through NumPy (copies), which a device
    // array (CuPy, PyTorch on a GPU) would refuse with its own words or copy implicitly.
    if (const auto device = device_of(obj)) fail(ErrorCode::invalid_input, where, device_array_refusal(name, *device));
    nb::object np = nb::module_::import_("numpy");
    nb::object arr;
    try {
      arr = np.attr("asarray")(obj);
    } catch (nb::python_error& e) {
      fail(ErrorCode::invalid_input, where,
           name + " (" + py_type_name(obj) + ") cannot be read as an array: " + e.what());
    }
    const std::string kind = nb::cast<std::string>(arr.attr("dtype").attr("kind"));
    if (kind != "f" && kind != "i" && kind != "u" && kind != "b") {
      fail(ErrorCode::invalid_input, where,
           name + " has dtype " + str_of(arr.attr("dtype")) + ", expected real numbers (float64, float32 or integers)");
    }
    arr = np.attr("ascontiguousarray")(arr, nb::arg("dtype") = "float64");
    if (!nb::try_cast(arr, view, false)) {
      fail(ErrorCode::invalid_input, where, name + " cannot be converted to a float64 array");
    }
    in.owner = arr;
    in.copied = true;
  } else {
    in.owner = nb::borrow(obj);  // a view: the array stays alive as long as `in` (e.g. a temporary result)
  }
  in.data = view.data();
  in.shape = shape_of(view);
  in.size = product(in.shape);
  return in;
}

std::size_t require_points(const InArray& a, const std::string& where, const std::string& name) {
  if (a.ndim() == 2 && a.shape[1] == 3) return a.shape[0];
  if (a.ndim() == 1 && a.size % 3 == 0) return a.size / 3;
  fail(ErrorCode::invalid_input, where, name + " has shape " + shape_string(a.shape) + ", expected (N, 3) or (3N,)");
}

std::size_t block_count(const InArray& a, const std::string& where, const std::string& name) {
  if ((a.ndim() == 3 && a.shape[2] == 3) || a.ndim() == 2) return a.shape[0];
  fail(ErrorCode::invalid_input, where,
       name + " has shape " + shape_string(a.shape) + ", expected (nrhs, N, 3) or (nrhs, 3N)");
}

void require_body_rows(const InArray& a, const std::string& where, const std::string& name) {
  require((a.ndim() == 2 && a.shape[1] == 6) || a.ndim() == 1, ErrorCode::invalid_input, where,
          name + " has shape " + shape_string(a.shape) + ", expected (m, 6) or (6m,)");
}

OutArray make_output(nb::handle out, const std::vector<std::size_t>& shape, const std::string& where,
                     const InArray* input) {
  OutArray result;
  result.size = product(shape);
  if (out.is_none()) {
    auto* data = new double[std::max<std::size_t>(result.size, 1)];
    nb::capsule owner(data, [](void* p) noexcept { delete[] static_cast<double*>(p); });
    result.object = nb::cast(nb::ndarray<nb::numpy, double>(data, shape.size(), shape.data(), owner));
    result.data = data;
    return result;
  }
  WView view;
  if (!nb::try_cast(out, view, /*convert=*/false)) {
    if (const auto device = device_of(out)) fail(ErrorCode::invalid_input, where, device_array_refusal("out", *device));
    std::string got = py_type_name(out);
    if (nb::hasattr(out, "dtype")) {
      got += " of dtype " + str_of(out.attr("dtype"));
      if (nb::hasattr(out, "flags") && !nb::cast<bool>(out.attr("flags").attr("writeable"))) got += ", read-only";
      if (nb::hasattr(out, "flags") && !nb::cast<bool>(out.attr("flags").attr("c_contiguous")))
        got += ", not C-contiguous";
    }
    fail(ErrorCode::invalid_input, where, "out must be a writable C-contiguous float64 array, got " + got);
  }
  const std::vector<std::size_t> out_shape = shape_of(view);
  if (product(out_shape) != result.size) {
    fail(ErrorCode::invalid_input, where,
         "out has shape " + shape_string(out_shape) + ", expected " + shape_string(shape) + " (" +
             std::to_string(result.size) + " entries)");
  }
  result.data = view.data();
  if (input != nullptr && input->size > 0 && result.size > 0) {
    const auto in_lo = reinterpret_cast<std::uintptr_t>(input->data);
    const auto out_lo = reinterpret_cast<std::uintptr_t>(result.data);
    // Overlap test on the byte ranges [lo, lo + 8 size).
    if (in_lo < out_lo + 8 * result.size && out_lo < in_lo + 8 * input->size) {
      fail(ErrorCode::invalid_input, where, "out must not share memory with the input array");
    }
  }
  result.object = nb::borrow(out);
  return result;
}

bool is_array_like(nb::handle h) {
  if (nb::hasattr(h, "ndim")) return nb::cast<int>(h.attr("ndim")) > 0;
  return nb::isinstance<nb::list>(h) || nb::isinstance<nb::tuple>(h);
}

Radii radii_from(RadiusArg radius, const std::string& where) {
  if (is_array_like(radius)) {  // N radii; a NumPy scalar (ndim 0) is one radius
    const InArray r = as_input(radius, where, "radii");
    require(r.ndim() == 1, ErrorCode::invalid_input, where,
            "radii has shape " + shape_string(r.shape) + ", expected (N,)");
    return {{r.data, r.data + r.size}, false};
  }
  double a = 0.0;
  if (!nb::try_cast(radius.h, a, true)) fail(ErrorCode::invalid_argument, where, "radius must be a number or N radii");
  return {{a}, true};
}

ArrayResult adopt_vector(std::vector<double>&& values, const std::vector<std::size_t>& shape) {
  auto* heap = new std::vector<double>(std::move(values));
  nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<double>*>(p); });
  return {nb::cast(nb::ndarray<nb::numpy, double>(heap->data(), shape.size(), shape.data(), owner))};
}

ArrayResult copy_rows(std::span<const double> values, std::size_t columns) {
  return adopt_vector(std::vector<double>(values.begin(), values.end()), {values.size() / columns, columns});
}

ArrayResult read_only_copy(std::span<const double> values, const std::vector<std::size_t>& shape) {
  auto* heap = new std::vector<double>(values.begin(), values.end());
  nb::capsule owner(heap, [](void* p) noexcept { delete static_cast<std::vector<double>*>(p); });
  return {nb::cast(nb::ndarray<nb::numpy, const double>(heap->data(), shape.size(), shape.data(), owner))};
}

rpy::Geometry geometry_from(nb::handle box, const std::string& where) {
  if (box.is_none()) return rpy::Geometry::open();
  double L = 0.0;
  if (nb::try_cast(box, L, true) && !nb::hasattr(box, "__len__")) return rpy::Geometry::periodic(L);
  const InArray b = as_input(box, where, "box");
  if (b.size == 1) return rpy::Geometry::periodic(b.data[0]);
  if (b.size == 3) return rpy::Geometry::periodic(b.data[0], b.data[1], b.data[2]);
  fail(ErrorCode::invalid_argument, where,
       "box must be None (free space), a length L or three lengths (Lx, Ly, Lz), got " + std::to_string(b.size) +
           " values");
}

nb::object box_tuple(const rpy::Geometry& geometry) {
  if (geometry.is_open()) return nb::none();
  const auto& b = geometry.box();
  return nb::make_tuple(b[0], b[1], b[2]);
}

rpy::SqrtMethod sqrt_method_from(const std::string& name) {
  if (name == "auto") return rpy::SqrtMethod::automatic;
  return rpy::sqrt_method_from_string(name);
}

rpy::SqrtPreconditioner sqrt_preconditioner_from(const std::string& name) {
  if (name == "auto") return rpy::SqrtPreconditioner::automatic;
  return rpy::sqrt_preconditioner_from_string(name);
}

void warn_deprecated(const std::string& message) {
  if (PyErr_WarnEx(PyExc_DeprecationWarning, message.c_str(), 1) != 0) throw nb::python_error();
}

double renamed_keyword(std::optional<double> value, std::optional<double> old_value, double fallback,
                       const std::string& where, const char* name, const char* old_name) {
  if (!old_value) return value.value_or(fallback);
  warn_deprecated(where + ": " + old_name + "= is deprecated; use " + name + "=");
  require(!value || *value == *old_value, ErrorCode::invalid_argument, where,
          std::string(name) + " and its deprecated spelling " + old_name + " were given different values");
  return *old_value;
}

rpy::SqrtOptions sqrt_options(const std::string& method, double tolerance, int max_iterations, bool reorthogonalize,
                              bool throw_if_not_converged, double lambda_min, double lambda_max,
                              int bound_estimate_iterations, const std::string& preconditioner,
                              int preconditioner_block) {
  // Checked here, in sqrt_apply's words (rpy/src/sqrt/sqrt_apply.cpp), for every operator: those
  // whose own sampler ignores them (PSE's split sampler, free draining's exact root) would
  // otherwise accept NaN or a negative count without a word.
  ranges::require_in(ranges::kSolverTolerance, tolerance, "sqrt_apply", "tolerance");
  require(max_iterations >= 0, ErrorCode::invalid_argument, "sqrt_apply",
          "max_iterations must be >= 0 (0 = automatic), got " + std::to_string(max_iterations));
  require(preconditioner_block >= 0, ErrorCode::invalid_argument, "sqrt_apply",
          "preconditioner_block must be >= 0 (0 = automatic), got " + std::to_string(preconditioner_block));
  rpy::SqrtOptions o;
  o.preconditioner = sqrt_preconditioner_from(preconditioner);
  o.preconditioner_block = preconditioner_block;
  o.method = sqrt_method_from(method);
  o.tolerance = tolerance;
  o.max_iterations = max_iterations;
  o.reorthogonalize = reorthogonalize;
  o.throw_if_not_converged = throw_if_not_converged;
  o.lambda_min = lambda_min;
  o.lambda_max = lambda_max;
  o.bound_estimate_iterations = bound_estimate_iterations;
  return o;
}

}  // namespace rpyfmm::python
