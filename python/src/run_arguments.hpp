// rpyfmm Python module — the arguments and results of whole BD runs (rpyfmm.run_bd,
// rpyfmm.mpi.run_bd; docs/python.md): a config given as a RunConfig, a path or TOML text, the run
// options, and the summary as a dict.
#pragma once

#include <nanobind/stl/filesystem.h>
#include <nanobind/stl/map.h>

#include <cstdint>
#include <filesystem>
#include <ios>
#include <optional>
#include <string>
#include <system_error>

#include "common.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/core/file_safety.hpp"

namespace rpyfmm::python {

/// Runs fn() reading the file `path`: a directory, device or FIFO (/dev/zero would be read without
/// end), or a stream failure (whose message does not name the file), raises FileError naming
/// `where` and the path.
template <class Fn>
auto reading_file(const char* where, const std::filesystem::path& path, Fn&& fn) {
  require_regular_input(path, where);
  try {
    return fn();
  } catch (const std::ios_base::failure& e) {
    fail(ErrorCode::io_error, where, "reading '" + path.string() + "' failed: " + e.what());
  }
}

/// A config argument: a bd::RunConfig, a path (str or os.PathLike) to a TOML file,
/// or TOML text (a str containing a newline or '=').
bd::RunConfig config_from(nb::handle config);
/// The run summary as a dict (particles, mobility, engine, steps, timings, files).
nb::dict summary_dict(const bd::RunSummary& s);
/// Run options: steps (None: the config's), out_dir (None: the config's), progress on stderr.
bd::RunOptions run_options(std::optional<std::uint64_t> steps, std::optional<std::string> out_dir, bool progress);

}  // namespace rpyfmm::python
