// rpyfmm — input validation helpers shared by every module.
//
// They throw rpyfmm::Error with messages of the form
// "<where>: <what> ..." so that a user sees which call and which value failed.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdio>
#include <span>
#include <string>
#include <string_view>

#include "rpyfmm/core/error.hpp"

namespace rpyfmm {

/// A number as printf's "%.6g" prints it ("1e-12", "0.5", "4.94066e-324"): the form every
/// message uses, so that tiny and huge values stay readable (std::to_string(double) prints
/// fixed-point with six decimals, which shows 1e-12 as "0.000000").
inline std::string format_number(double value) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", value);
  return buf;
}

[[noreturn]] inline void fail(ErrorCode code, std::string_view where, std::string_view what) {
  throw Error(code, std::string(where) + ": " + std::string(what));
}

inline void require(bool condition, ErrorCode code, std::string_view where, std::string_view what) {
  if (!condition) fail(code, where, what);
}

/// Checks that `values.size() == expected`, naming the array in the message.
inline void require_size(std::span<const double> values, std::size_t expected, std::string_view where,
                         std::string_view name) {
  if (values.size() != expected) {
    fail(
        ErrorCode::invalid_input, where,
        std::string(name) + " has " + std::to_string(values.size()) + " entries, expected " + std::to_string(expected));
  }
}

/// Checks that every entry is finite; the message names the first bad entry.
/// `stride` > 1 reports (row, column) — e.g. particle and coordinate for (N,3) data.
inline void require_finite(std::span<const double> values, std::string_view where, std::string_view name,
                           std::size_t stride = 1) {
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      std::string what = std::string(name) + " ";
      if (stride > 1) {
        what += "entry (" + std::to_string(i / stride) + ", " + std::to_string(i % stride) + ")";
      } else {
        what += "entry " + std::to_string(i);
      }
      what += std::isnan(values[i]) ? " is NaN" : " is infinite";
      fail(ErrorCode::invalid_input, where, what);
    }
  }
}

/// Checks a scalar parameter is finite, strictly positive and not subnormal (below
/// DBL_MIN ~ 2.2e-308 its reciprocal overflows and the products of the kernels lose all digits).
inline void require_positive(double value, std::string_view where, std::string_view name) {
  if (!(std::isfinite(value) && value > 0.0)) {
    fail(ErrorCode::invalid_argument, where,
         std::string(name) + " must be finite and > 0, got " + format_number(value));
  }
  if (!std::isnormal(value)) {
    fail(ErrorCode::invalid_argument, where,
         std::string(name) + " must be a normal number (>= 2.2e-308), got the subnormal " + format_number(value));
  }
}

/// Checks `lo <= value <= hi` (and finiteness).
inline void require_in_range(double value, double lo, double hi, std::string_view where, std::string_view name) {
  if (!(std::isfinite(value) && value >= lo && value <= hi)) {
    fail(ErrorCode::invalid_argument, where,
         std::string(name) + " must lie in [" + format_number(lo) + ", " + format_number(hi) + "], got " +
             format_number(value));
  }
}

}  // namespace rpyfmm
