// rpyfmm — files written so that a failure never leaves a truncated file in
// place of a good one: data goes to "<path>.tmp.<pid>" and is renamed over
// <path> only after a successful flush and close.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <system_error>
#include <unistd.h>

#include "rpyfmm/core/error.hpp"

namespace rpyfmm {

/// Calls `write(stream)` on a temporary file next to `path`, then renames it
/// to `path`. On any exception or stream failure the temporary is removed,
/// `path` is left untouched, and the error is rethrown (as rpyfmm::Error for
/// stream failures).
inline void write_file_atomically(const std::filesystem::path& path,
                                  const std::function<void(std::ostream&)>& write,
                                  std::ios::openmode mode = std::ios::binary) {
  const std::filesystem::path tmp = path.string() + ".tmp." + std::to_string(::getpid());
  try {
    {
      std::ofstream out(tmp, mode | std::ios::out | std::ios::trunc);
      if (!out) throw Error(ErrorCode::io_error, "cannot open '" + tmp.string() + "' for writing");
      write(out);
      out.flush();
      if (!out) throw Error(ErrorCode::io_error, "writing '" + path.string() + "' failed");
    }
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    if (ec) throw Error(ErrorCode::io_error, "cannot rename '" + tmp.string() + "' to '" + path.string() + "': " + ec.message());
  } catch (...) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    throw;
  }
}

}  // namespace rpyfmm
