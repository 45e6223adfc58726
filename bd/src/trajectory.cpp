#include "rpyfmm/bd/trajectory.hpp"

#include "rpyfmm/bd/hoomd_frame.hpp"

namespace rpyfmm::bd {

void TrajectoryFile::create(const std::filesystem::path& path) {
  if (format_ == TrajectoryFormat::gsd)
    gsd_.create(path);
  else
    xyz_.create(path);
}

void TrajectoryFile::reopen(const std::filesystem::path& path, std::uint64_t length, std::uint64_t hash) {
  if (format_ == TrajectoryFormat::gsd)
    gsd_.reopen(path, length, hash);
  else
    xyz_.reopen(path, length, hash);
}

void TrajectoryFile::publish() {
  gsd_.publish();
  xyz_.publish();
}

void TrajectoryFile::flush() {
  gsd_.flush();
}

void TrajectoryFile::write(std::span<const double> positions, std::span<const std::uint32_t> types,
                           const std::vector<ParticleType>& type_table, const rpy::Geometry& geometry,
                           std::uint64_t step, double time, std::span<const double> orientations,
                           std::span<const std::uint32_t> complex_ids) {
  if (format_ == TrajectoryFormat::gsd)
    gsd_.write(hoomd_frame(positions, types, type_table, geometry, step, time, orientations, gsd_.frames() == 0));
  else
    xyz_.write(xyz_frame(positions, types, type_table, geometry, step, time, orientations, complex_ids));
}

std::uint64_t TrajectoryFile::length() const {
  return format_ == TrajectoryFormat::gsd ? gsd_.frames() : xyz_.bytes();
}

std::uint64_t TrajectoryFile::hash() const {
  return format_ == TrajectoryFormat::gsd ? gsd_.hash() : xyz_.hash();
}

}  // namespace rpyfmm::bd
