#include "rpyfmm/bd/output.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

void AppendFile::open(const std::filesystem::path& path, std::uint64_t keep_bytes) {
  path_ = path;
  std::error_code ec;
  if (keep_bytes == 0) {
    out_.open(path, std::ios::binary | std::ios::trunc | std::ios::out);
  } else {
    const auto size = std::filesystem::file_size(path, ec);
    if (ec || size < keep_bytes)
      fail(ErrorCode::io_error, "restart",
           "'" + path.string() + "' is shorter than recorded in the checkpoint (" + std::to_string(keep_bytes) +
               " bytes): it does not belong to this checkpoint");
    std::filesystem::resize_file(path, keep_bytes, ec);  // drop records written after the checkpoint
    if (ec) fail(ErrorCode::io_error, "restart", "cannot truncate '" + path.string() + "': " + ec.message());
    out_.open(path, std::ios::binary | std::ios::app | std::ios::out);
  }
  if (!out_) fail(ErrorCode::io_error, "output", "cannot open '" + path.string() + "' for writing");
  bytes_ = keep_bytes;
}

void AppendFile::write(const std::string& record) {
  out_.write(record.data(), static_cast<std::streamsize>(record.size()));
  out_.flush();
  if (!out_) fail(ErrorCode::io_error, "output", "writing '" + path_.string() + "' failed (disk full?)");
  bytes_ += record.size();
}

std::string xyz_frame(std::span<const double> x, std::span<const std::uint32_t> types,
                      const std::vector<ParticleType>& table, const rpy::Geometry& g, std::uint64_t step, double time) {
  std::string s;
  s.reserve(types.size() * 64 + 256);
  char buf[256];
  std::snprintf(buf, sizeof buf, "%zu\n", types.size());
  s += buf;
  if (g.is_periodic()) {
    const auto& L = g.box();
    std::snprintf(buf, sizeof buf, "Lattice=\"%.17g 0 0 0 %.17g 0 0 0 %.17g\" pbc=\"T T T\" ", L[0], L[1], L[2]);
  } else {
    std::snprintf(buf, sizeof buf, "pbc=\"F F F\" ");
  }
  s += buf;
  // Shortest decimal that round-trips (Time=0.04, not 0.040000000000000001).
  char tbuf[64];
  const auto res = std::to_chars(tbuf, tbuf + sizeof tbuf, time);
  s += "Properties=species:S:1:pos:R:3:radius:R:1 Time=";
  s.append(tbuf, res.ptr);
  s += " Step=" + std::to_string(step) + "\n";
  for (std::size_t i = 0; i < types.size(); ++i) {
    double p[3] = {x[3 * i], x[3 * i + 1], x[3 * i + 2]};
    if (g.is_periodic())
      for (int c = 0; c < 3; ++c) p[c] -= g.box()[c] * std::floor(p[c] / g.box()[c]);
    const ParticleType& t = table[types[i]];
    std::snprintf(buf, sizeof buf, "%s %.10g %.10g %.10g %.10g\n", t.name.c_str(), p[0], p[1], p[2], t.radius);
    s += buf;
  }
  return s;
}

std::string csv_log_header(bool split_displacements) {
  std::string h =
      "step,time,mean_displacement,msd,mean_vx,mean_vy,mean_vz,potential_energy,sqrt_iterations,"
      "mobility_products,neighbour_rebuilds,wall_neighbours,wall_forces,wall_plan,wall_drift,wall_sqrt,"
      "wall_update,wall_output";
  if (split_displacements) h += ",deterministic_rms,brownian_rms";
  return h + "\n";
}

}  // namespace rpyfmm::bd
