// Placeholder dispatcher until the square-root solvers land (issue 4).
#include <string>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace rpyfmm::rpy {

const char* to_string(SqrtMethod method) {
  switch (method) {
    case SqrtMethod::automatic: return "automatic";
    case SqrtMethod::lanczos: return "lanczos";
    case SqrtMethod::chebyshev: return "chebyshev";
    case SqrtMethod::cholesky: return "cholesky";
    case SqrtMethod::eigen: return "eigen";
    case SqrtMethod::split: return "split";
  }
  return "unknown";
}

SqrtMethod sqrt_method_from_string(const std::string& name) {
  for (auto m : {SqrtMethod::automatic, SqrtMethod::lanczos, SqrtMethod::chebyshev, SqrtMethod::cholesky,
                 SqrtMethod::eigen, SqrtMethod::split}) {
    if (name == to_string(m)) return m;
  }
  fail(ErrorCode::invalid_argument, "sqrt method", "unknown method '" + name + "'");
}

SqrtReport sqrt_apply(const LinearOperatorView&, std::span<const double>, std::span<double>, std::size_t,
                      const SqrtOptions&) {
  fail(ErrorCode::not_supported, "apply_sqrt", "square-root solvers are not available yet");
}

}  // namespace rpyfmm::rpy
