// rpyfmm — the one exception type of the library.
//
// Every public entry point validates its input once (constructors, setters)
// and throws rpyfmm::Error with a code and a message that names the offending
// argument, e.g. "set_positions: coordinate 5 of particle 17 is NaN".
#pragma once

#include <stdexcept>
#include <string>

namespace rpyfmm {

enum class ErrorCode {
  invalid_argument,   // a parameter is out of range (tolerance, radius, viscosity, ...)
  invalid_input,      // data is malformed: wrong size, NaN/Inf, coincident where forbidden
  not_supported,      // a combination the solver does not offer (e.g. periodic FMM)
  numerical_failure,  // an algorithm detected a breakdown (e.g. operator not positive definite)
  io_error,           // reading or writing a file failed
  out_of_memory,      // a request would exceed the memory the solver may allocate
};

inline const char* to_string(ErrorCode code) noexcept {
  switch (code) {
    case ErrorCode::invalid_argument:
      return "invalid argument";
    case ErrorCode::invalid_input:
      return "invalid input";
    case ErrorCode::not_supported:
      return "not supported";
    case ErrorCode::numerical_failure:
      return "numerical failure";
    case ErrorCode::io_error:
      return "I/O error";
    case ErrorCode::out_of_memory:
      return "out of memory";
  }
  return "error";
}

class Error : public std::runtime_error {
 public:
  Error(ErrorCode code, const std::string& message) : std::runtime_error(message), code_(code) {}
  [[nodiscard]] ErrorCode code() const noexcept { return code_; }

 private:
  ErrorCode code_;
};

}  // namespace rpyfmm
