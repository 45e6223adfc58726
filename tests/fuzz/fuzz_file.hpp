// rpyfmm fuzzing — readers that take a path get the input through one scratch file per process
// (in $TMPDIR), rewritten for every input; their parsing is what is fuzzed, not the file system.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace rpyfmm::fuzz {

inline const std::filesystem::path& scratch_file(const std::string& stem) {
  static const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("rpyfmm_fuzz_" + stem + "_" + std::to_string(::getpid()));
  return path;
}

inline const std::filesystem::path& write_scratch(const std::string& stem, const std::uint8_t* data, std::size_t size) {
  const auto& path = scratch_file(stem);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

}  // namespace rpyfmm::fuzz
