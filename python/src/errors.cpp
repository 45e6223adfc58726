// rpyfmm Python bindings — rpyfmm::Error -> Python exceptions.
//
// rpyfmm.Error (a RuntimeError) is the base of one class per rpyfmm::ErrorCode
// (core/include/rpyfmm/core/error.hpp); the message is the C++ what() unchanged.
// Argument errors are also ValueErrors, so `except ValueError` works as usual:
//   invalid_argument  -> InvalidArgumentError(Error, ValueError)
//   invalid_input     -> InvalidInputError(Error, ValueError)
//   not_supported     -> NotSupportedError(Error, NotImplementedError)
//   numerical_failure -> NumericalFailureError(Error, ArithmeticError)
//   io_error          -> FileError(Error)    (OSError's layout cannot be combined with RuntimeError)
//   out_of_memory     -> OutOfMemoryError(Error, MemoryError)
// Standard C++ exceptions escaping the library map onto the same classes (message = what()),
// so that every failure from C++ is an rpyfmm.Error:
//   std::bad_alloc, std::length_error            -> OutOfMemoryError
//   std::filesystem::filesystem_error, std::ios_base::failure -> FileError
//   std::invalid_argument, std::domain_error      -> InvalidArgumentError
//   std::out_of_range                             -> InvalidInputError
//   std::overflow_error, underflow_error, range_error -> NumericalFailureError
//   any other std::exception                      -> Error
// nanobind's own exceptions (argument conversion: std::bad_cast -> TypeError) and Python
// exceptions raised by callbacks pass through unchanged.
#include <array>
#include <exception>
#include <filesystem>
#include <ios>
#include <new>
#include <stdexcept>
#include <typeinfo>

#include "common.hpp"
#include "rpyfmm/core/error.hpp"

namespace rpyfmm::python {
namespace {

constexpr std::size_t kCodes = 6;
std::array<PyObject*, kCodes> g_classes{};  // indexed by ErrorCode; kept alive by the module

PyObject* g_base = nullptr;  // rpyfmm.Error

PyObject* class_of(ErrorCode code) {
  const auto index = static_cast<std::size_t>(code);
  return index < kCodes && g_classes[index] ? g_classes[index] : g_base;
}

/// The rpyfmm.Error subclass of a standard exception (rethrows `p` to inspect it).
PyObject* class_of_std(const std::exception_ptr& p) {
  try {
    std::rethrow_exception(p);
  } catch (const std::bad_alloc&) {
    return class_of(ErrorCode::out_of_memory);
  } catch (const std::length_error&) {
    return class_of(ErrorCode::out_of_memory);
  } catch (const std::filesystem::filesystem_error&) {
    return class_of(ErrorCode::io_error);
  } catch (const std::ios_base::failure&) {
    return class_of(ErrorCode::io_error);
  } catch (const std::invalid_argument&) {
    return class_of(ErrorCode::invalid_argument);
  } catch (const std::domain_error&) {
    return class_of(ErrorCode::invalid_argument);
  } catch (const std::out_of_range&) {
    return class_of(ErrorCode::invalid_input);
  } catch (const std::overflow_error&) {
    return class_of(ErrorCode::numerical_failure);
  } catch (const std::underflow_error&) {
    return class_of(ErrorCode::numerical_failure);
  } catch (const std::range_error&) {
    return class_of(ErrorCode::numerical_failure);
  } catch (...) {
    return g_base;
  }
}

struct ClassSpec {
  ErrorCode code;
  const char* name;
  const char* code_name;
  PyObject* extra_base;
  const char* doc;
};

}  // namespace

void bind_errors(nb::module_& m) {
  PyObject* base =
      PyErr_NewExceptionWithDoc("rpyfmm.Error",
                                "Base of every rpyfmm exception (a RuntimeError). The message is the C++ library's, "
                                "of the form '<where>: <what>', naming the offending argument.",
                                PyExc_RuntimeError, nullptr);
  if (base == nullptr) throw nb::python_error();
  PyObject_SetAttrString(base, "code", Py_None);
  m.attr("Error") = nb::steal(base);
  g_base = base;

  const ClassSpec specs[] = {
      {ErrorCode::invalid_argument, "InvalidArgumentError", "invalid_argument", PyExc_ValueError,
       "A parameter is out of range (tolerance, radius, viscosity, ...)."},
      {ErrorCode::invalid_input, "InvalidInputError", "invalid_input", PyExc_ValueError,
       "Data is malformed: wrong shape or size, NaN/Inf, wrong dtype."},
      {ErrorCode::not_supported, "NotSupportedError", "not_supported", PyExc_NotImplementedError,
       "A combination the solver does not offer (e.g. a periodic box for the FMM operator)."},
      {ErrorCode::numerical_failure, "NumericalFailureError", "numerical_failure", PyExc_ArithmeticError,
       "An algorithm detected a breakdown (operator not positive definite, BD blow-up)."},
      {ErrorCode::io_error, "FileError", "io_error", nullptr, "Reading or writing a file failed."},
      {ErrorCode::out_of_memory, "OutOfMemoryError", "out_of_memory", PyExc_MemoryError,
       "A request would exceed the memory the solver may allocate."},
  };
  for (const ClassSpec& s : specs) {
    nb::object bases =
        s.extra_base ? nb::make_tuple(nb::handle(base), nb::handle(s.extra_base)) : nb::make_tuple(nb::handle(base));
    const std::string qualified = std::string("rpyfmm.") + s.name;
    PyObject* cls = PyErr_NewExceptionWithDoc(qualified.c_str(), s.doc, bases.ptr(), nullptr);
    if (cls == nullptr) throw nb::python_error();
    PyObject_SetAttrString(cls, "code", nb::str(s.code_name).ptr());
    m.attr(s.name) = nb::steal(cls);
    g_classes[static_cast<std::size_t>(s.code)] = cls;
  }

  nb::register_exception_translator([](const std::exception_ptr& p, void*) {
    try {
      std::rethrow_exception(p);
    } catch (const rpyfmm::Error& e) {
      PyErr_SetString(class_of(e.code()), e.what());
    } catch (const std::bad_cast&) {
      throw;  // nanobind's cast_error: its own translator raises TypeError
    } catch (const std::exception& e) {
      PyErr_SetString(class_of_std(p), e.what());
    }
  });
}

}  // namespace rpyfmm::python
