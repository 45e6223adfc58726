// rpyfmm::bd — a run's trajectory file in the format of `[output] format`: extended XYZ
// (AppendFile and xyz_frame, output.hpp) or GSD (GsdTrajectory and hoomd_frame,
// gsd_trajectory.hpp). A checkpoint records its length (XYZ: bytes, GSD: frames) and hash
// (XYZ: of those bytes, GSD: of those frames' chunks); a restart hands both back to reopen().
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/gsd_trajectory.hpp"
#include "rpyfmm/bd/output.hpp"

namespace rpyfmm::bd {

class TrajectoryFile {
 public:
  explicit TrajectoryFile(TrajectoryFormat format) : format_(format) {}

  /// A new trajectory for `path`, published by publish() (AppendFile::create, GsdTrajectory::create).
  void create(const std::filesystem::path& path);
  /// Continues the trajectory of a checkpoint: its first `length` bytes or frames must hash to
  /// `hash` (AppendFile::reopen, GsdTrajectory::reopen).
  void reopen(const std::filesystem::path& path, std::uint64_t length, std::uint64_t hash);
  /// Makes the file the run's output; later calls do nothing.
  void publish();
  /// Commits what was written to the file (GSD's write buffer; XYZ records are written through).
  void flush();
  /// Appends the frame of one step (`orientations`: 4N quaternions w x y z, or empty;
  /// `complex_ids`: N SAC complex ids, or empty, written by the XYZ format only).
  void write(std::span<const double> positions, std::span<const std::uint32_t> types,
             const std::vector<ParticleType>& type_table, const rpy::Geometry& geometry, std::uint64_t step,
             double time, std::span<const double> orientations, std::span<const std::uint32_t> complex_ids = {});

  [[nodiscard]] std::uint64_t length() const;  ///< XYZ: bytes, GSD: frames
  [[nodiscard]] std::uint64_t hash() const;

 private:
  TrajectoryFormat format_;
  AppendFile xyz_;
  GsdTrajectory gsd_;
};

}  // namespace rpyfmm::bd
