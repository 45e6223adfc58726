// rpyfmm fuzzing — the array reader of the CLI (apps/rpyfmm/array_io.cpp) on arbitrary bytes,
// shared by the .npy and the text target. Invariants checked on every input the reader accepts:
// the data has exactly prod(shape) entries, and as_points / as_vector either accept it or throw
// rpyfmm::Error. Anything else (a crash, a sanitizer report, another exception, an allocation
// above libFuzzer's -malloc_limit_mb) is a finding.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "array_io.hpp"
#include "rpyfmm/core/error.hpp"

namespace rpyfmm::fuzz {

inline void read_array_checked(std::string_view bytes) {
  try {
    const cli::Array a = cli::read_array_bytes(bytes, "fuzz-input");
    std::size_t count = 1;
    for (std::size_t s : a.shape) count *= s;
    if (a.data.size() != count) std::abort();  // the shape must describe the data
    try {
      (void)cli::as_points(a, "points");
    } catch (const Error&) {
    }
    try {
      (void)cli::as_vector(a, a.rows(), "values");
    } catch (const Error&) {
    }
  } catch (const Error&) {
    // Refused with a message: the expected outcome for malformed input.
  }
}

}  // namespace rpyfmm::fuzz
