// rpyfmm::bd — GSD trajectory files (HOOMD-blue's binary format), written through the C library
// of the gsd package (gsd_create_and_open, gsd_write_chunk, gsd_end_frame, gsd_flush,
// gsd_close; the "C API" page of the gsd docs). Frames hold the chunks of hoomd_frame.hpp.
//
// The same rules as the XYZ trajectory (output.hpp, docs/safety-files.md), for a file that is not
// append-only (gsd rewrites its index in place as it grows):
//  * a new run writes to a temporary next to the target, created exclusively under an
//    unpredictable name, and renames it over the target once the run has started;
//  * a target that exists and is not a regular file (link, device, FIFO) is refused;
//  * each checkpoint records the number of frames and an FNV-1a hash of their chunks (names,
//    types, shapes, bytes), and gsd_flush commits those frames (data, then index, each synced)
//    before the checkpoint is written;
//  * a restart reads the file's first `frames` frames, checks their hash, and copies them into a
//    new temporary that the continued run appends to; the temporary replaces the file only when
//    the restarted run has started. The old file is never modified: a refusal or a crash before
//    that leaves it as it was, a file another run wrote is refused and left untouched.
//
// Between checkpoints frames stay in gsd's write buffer (64 MiB by default) until it fills; a
// crash can lose those, which a restart drops anyway.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>

#include "rpyfmm/bd/hoomd_frame.hpp"
#include "rpyfmm/core/file_safety.hpp"

namespace rpyfmm::bd {

/// Whether this build writes GSD: the gsd C library was found when it was configured
/// (cmake/RpyfmmGsd.cmake).
bool gsd_supported();
/// Why a build without GSD support cannot write it, and how to enable it ("" with support).
std::string gsd_unsupported_reason();

class GsdTrajectory {
 public:
  GsdTrajectory();
  GsdTrajectory(const GsdTrajectory&) = delete;
  GsdTrajectory& operator=(const GsdTrajectory&) = delete;
  ~GsdTrajectory();  ///< closes the file (committing its frames); removes an unpublished temporary

  /// Starts a new, empty trajectory for `path` (schema "hoomd" 1.4) in a temporary next to it.
  /// Throws io_error if `path` exists and is not a regular file.
  void create(const std::filesystem::path& path);
  /// Continues the regular GSD file `path` of an earlier run: its first `keep_frames` frames must
  /// hash to `expected_hash` (else io_error naming the file: it belongs to another run); they are
  /// copied into a temporary, which publish() renames over `path`.
  void reopen(const std::filesystem::path& path, std::uint64_t keep_frames, std::uint64_t expected_hash);
  /// Commits the frames written so far and makes the temporary the run's output (renames it over
  /// the path). Nothing on disk at `path` changes before; later calls only commit.
  void publish();
  /// Appends one frame of `chunks`.
  void write(std::span<const GsdChunk> chunks);
  /// Commits the frames written so far to the file (gsd_flush).
  void flush();

  [[nodiscard]] std::uint64_t frames() const { return frames_; }
  [[nodiscard]] std::uint64_t hash() const { return hash_.value(); }
  [[nodiscard]] bool is_open() const;
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  struct Handle;  // the gsd_handle (gsd.h stays out of the installed headers)
  void open_temporary();

  std::unique_ptr<Handle> file_;
  std::filesystem::path path_, temporary_;  // temporary_: empty once published
  std::uint64_t frames_ = 0;
  Fnv1a hash_;
};

}  // namespace rpyfmm::bd
