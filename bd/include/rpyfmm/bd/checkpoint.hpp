// rpyfmm::bd — checkpoints: everything needed to continue a run bitwise
// identically (positions as exact binary doubles, step, RNG key, reference
// positions for MSD, output file lengths and content hashes, the run's config text).
//
// File format (little-endian host layout, version 2):
//   "RPYFMMBD" u32 version, u64 N, u64 step, u64 seed, f64 dt,
//   u64 trajectory_bytes, u64 trajectory_hash, u64 log_bytes, u64 log_hash,
//   f64[3N] positions, f64[3N] reference_positions, u32[N] types,
//   u64 len + config bytes, u64 checksum (FNV-1a of everything before it).
// Runs with rotation write version 3: version 2 with, after the types,
//   f64[4N] orientations, f64[4N] reference_orientations, f64[3N] rotation_vectors.
// Runs with Langevin types write version 4: version 2 with, after the types,
//   f64[3N] half-step velocities v_{n-1/2} (0 for Brownian particles).
// Other runs still write version 2, byte for byte as before.
// The hashes (FNV-1a of each output's first *_bytes bytes) identify the files
// this run wrote: a restart refuses any other file instead of cutting it. A GSD
// trajectory (`[output] format = "gsd"`) is counted in frames instead of bytes,
// and hashed over those frames' chunks (gsd_trajectory.hpp).
// Written atomically (rpyfmm/core/atomic_file.hpp): a crash never leaves a
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
  std::vector<double> positions;               ///< 3N, unwrapped
  std::vector<double> reference_positions;     ///< 3N, positions at step 0 (for MSD)
  std::vector<std::uint32_t> types;            ///< N
  std::vector<double> orientations;            ///< rotation: 4N unit quaternions w x y z (else empty)
  std::vector<double> reference_orientations;  ///< rotation: 4N, orientations at step 0
  std::vector<double> rotation_vectors;        ///< rotation: 3N, sum of the steps' rotation vectors
  std::vector<double> velocities;              ///< Langevin types: 3N half-step velocities (else empty)
  std::uint64_t trajectory_bytes = 0;          ///< trajectory length when this state was written (GSD: frames)
  std::uint64_t trajectory_hash = 0;           ///< FNV-1a of those bytes (GSD: of those frames' chunks)
  std::uint64_t log_bytes = 0;                 ///< CSV log length when this state was written
  std::uint64_t log_hash = 0;                  ///< FNV-1a of those log_bytes bytes
  std::string config;                          ///< the run's TOML config text
};

void write_checkpoint(const std::filesystem::path& path, const Checkpoint& checkpoint);
/// Throws rpyfmm::Error(io_error) naming the file and what is wrong with it (missing, not a
/// regular file, not a checkpoint, corrupt, another format version).
Checkpoint read_checkpoint(const std::filesystem::path& path);

}  // namespace rpyfmm::bd
