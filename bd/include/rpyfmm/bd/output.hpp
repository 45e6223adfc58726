// rpyfmm::bd — run output: extended-XYZ trajectories (OVITO, VMD, ASE) and a
// CSV log, both appended and flushed per record.
//
// Crash guarantee: each record is written whole and flushed; every checkpoint
// (written atomically) stores the byte length of both files at that state, and
// a restart truncates them back to it. So after any crash the files plus the
// last checkpoint form a consistent prefix of the run, and a partially written
// last frame is dropped on restart.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::bd {

/// An append-only text file that can be reopened at a given length.
class AppendFile {
 public:
  AppendFile() = default;
  /// Opens `path`; keep_bytes = 0 starts it empty, otherwise it is truncated to
  /// keep_bytes (throws io_error if it is shorter: the file does not match the checkpoint).
  void open(const std::filesystem::path& path, std::uint64_t keep_bytes);
  void write(const std::string& record);  ///< appends and flushes
  [[nodiscard]] std::uint64_t bytes() const { return bytes_; }
  [[nodiscard]] bool is_open() const { return out_.is_open(); }
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  std::ofstream out_;
  std::uint64_t bytes_ = 0;
};

/// One extended-XYZ frame: species = type name, pos, radius; Time and Step in the
/// comment line; periodic boxes give Lattice and wrapped positions.
std::string xyz_frame(std::span<const double> positions, std::span<const std::uint32_t> types,
                      const std::vector<ParticleType>& type_table, const rpy::Geometry& geometry, std::uint64_t step,
                      double time);

/// Columns of the CSV log (header line); with split displacements two more columns:
/// the rms per particle and step of M F dt and of sqrt(2 kT dt) M^{1/2} z over the interval.
std::string csv_log_header(bool split_displacements = false);

}  // namespace rpyfmm::bd
