// rpyfmm::bd — checkpoints: everything needed to continue a run bitwise
// identically (positions as exact binary doubles, step, RNG key, reference
// positions for MSD, output file lengths, the run's config text).
//
// File format (little-endian host layout, version 1):
//   "RPYFMMBD" u32 version, u64 N, u64 step, u64 seed, f64 dt,
//   u64 trajectory_bytes, u64 log_bytes, f64[3N] positions,
//   f64[3N] reference_positions, u32[N] types, u64 len + config bytes,
//   u64 checksum (FNV-1a of everything before it).
// Written atomically (temporary file + rename): a crash never leaves a
// truncated checkpoint in place of the previous good one.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace rpyfmm::bd {

struct Checkpoint {
  std::uint64_t step = 0;
  std::uint64_t seed = 0;
  double dt = 0.0;
  std::vector<double> positions;            ///< 3N, unwrapped
  std::vector<double> reference_positions;  ///< 3N, positions at step 0 (for MSD)
  std::vector<std::uint32_t> types;         ///< N
  std::uint64_t trajectory_bytes = 0;       ///< trajectory length when this state was written
  std::uint64_t log_bytes = 0;              ///< CSV log length when this state was written
  std::string config;                       ///< the run's TOML config text
};

void write_checkpoint(const std::filesystem::path& path, const Checkpoint& checkpoint);
/// Throws rpyfmm::Error(io_error) naming the file and what is wrong with it.
Checkpoint read_checkpoint(const std::filesystem::path& path);

}  // namespace rpyfmm::bd
