#include "rpyfmm/bd/output.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "rpyfmm/bd/quaternion.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

namespace {
// Hash of the first `length` bytes of the open file `fd` (named `path` in errors).
std::uint64_t hash_prefix(int fd, std::uint64_t length, const std::filesystem::path& path) {
  Fnv1a hash;
  std::string buffer(std::size_t{1} << 20, '\0');
  for (std::uint64_t done = 0; done < length;) {
    const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(buffer.size(), length - done));
    const ssize_t n = ::pread(fd, buffer.data(), want, static_cast<off_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail(ErrorCode::io_error, "restart", "cannot read '" + path.string() + "'");
    hash.add(std::string_view(buffer.data(), static_cast<std::size_t>(n)));
    done += static_cast<std::uint64_t>(n);
  }
  return hash.value();
}
}  // namespace

AppendFile::~AppendFile() {
  if (fd_ >= 0) ::close(fd_);
  if (!temporary_.empty()) ::unlink(temporary_.c_str());
}

void AppendFile::create(const std::filesystem::path& path) {
  path_ = path;
  require_regular_or_absent(path);
  fd_ = create_temporary_next_to(path, temporary_);
}

void AppendFile::reopen(const std::filesystem::path& path, std::uint64_t keep_bytes, std::uint64_t expected_hash) {
  path_ = path;
  const std::string name = file_safety_detail::quoted(path);
  require_regular_or_absent(path);
  fd_ = ::open(path.c_str(), O_RDWR | O_APPEND | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) fail(ErrorCode::io_error, "restart", "cannot open " + name + " to continue it: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode))
    fail(ErrorCode::io_error, "restart", name + " is not a regular file");
  if (static_cast<std::uint64_t>(st.st_size) < keep_bytes)
    fail(ErrorCode::io_error, "restart",
         name + " is shorter than recorded in the checkpoint (" + std::to_string(keep_bytes) +
             " bytes): it does not belong to this checkpoint");
  if (hash_prefix(fd_, keep_bytes, path) != expected_hash)
    fail(ErrorCode::io_error, "restart",
         name + " does not match the checkpoint (its first " + std::to_string(keep_bytes) +
             " bytes differ from what the checkpointed run wrote): it belongs to another run; left untouched");
  cut_pending_ = true;  // the tail written after the checkpoint goes in publish()
  bytes_ = keep_bytes;
  hash_ = Fnv1a(expected_hash);  // the running hash continues from the verified prefix
}

void AppendFile::publish() {
  if (cut_pending_) {  // drop records written after the checkpoint
    if (::ftruncate(fd_, static_cast<off_t>(bytes_)) != 0)
      fail(ErrorCode::io_error, "restart", "cannot truncate '" + path_.string() + "': " + std::strerror(errno));
    cut_pending_ = false;
  }
  if (temporary_.empty()) return;
  replace_with(temporary_, path_);
  temporary_.clear();
}

void AppendFile::write(const std::string& record) {
  if (cut_pending_) publish();  // never append behind a tail that is still to be cut
  write_all(fd_, record, path_);
  hash_.add(record);
  bytes_ += record.size();
}

std::string xyz_frame(std::span<const double> x, std::span<const std::uint32_t> types,
                      const std::vector<ParticleType>& table, const rpy::Geometry& g, std::uint64_t step, double time,
                      std::span<const double> orientations, std::span<const std::uint32_t> complex_ids) {
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
  s += "Properties=species:S:1:pos:R:3:radius:R:1";
  if (!orientations.empty()) s += ":orientation:R:4";
  if (!complex_ids.empty()) s += ":complex:I:1";
  s += " Time=";
  s.append(tbuf, res.ptr);
  s += " Step=" + std::to_string(step) + "\n";
  for (std::size_t i = 0; i < types.size(); ++i) {
    double p[3] = {x[3 * i], x[3 * i + 1], x[3 * i + 2]};
    if (g.is_periodic())
      for (int c = 0; c < 3; ++c) p[c] -= g.box()[c] * std::floor(p[c] / g.box()[c]);
    const ParticleType& t = table[types[i]];
    std::snprintf(buf, sizeof buf, "%s %.10g %.10g %.10g %.10g", t.name.c_str(), p[0], p[1], p[2], t.radius);
    s += buf;
    if (!orientations.empty()) {  // x y z w (OVITO's component order)
      const double* q = orientations.data() + 4 * i;
      std::snprintf(buf, sizeof buf, " %.10g %.10g %.10g %.10g", q[1], q[2], q[3], q[0]);
      s += buf;
    }
    if (!complex_ids.empty()) {
      s += ' ';
      s += complex_ids[i] == std::numeric_limits<std::uint32_t>::max() ? "-1" : std::to_string(complex_ids[i]);
    }
    s += '\n';
  }
  return s;
}

std::string csv_log_header(bool split_displacements, bool rotation, bool langevin, bool sac) {
  std::string h =
      "step,time,mean_displacement,msd,mean_vx,mean_vy,mean_vz,potential_energy,sqrt_iterations,"
      "mobility_products,neighbour_rebuilds,wall_neighbours,wall_forces,wall_plan,wall_drift,wall_sqrt,"
      "wall_update,wall_output";
  if (split_displacements) h += ",deterministic_rms,brownian_rms";
  if (rotation) h += ",rotational_msd,orientation_correlation";
  if (langevin) h += ",langevin_kT";
  if (sac) h += ",complexes,mean_adsorbed";
  return h + "\n";
}

std::array<double, 2> rotation_moment_sums(std::span<const double> orientations, std::span<const double> reference,
                                           std::span<const double> rotation_vectors) {
  double msd = 0, correlation = 0;
  for (std::size_t i = 0; 3 * i < rotation_vectors.size(); ++i) {
    const auto u = quaternion::body_axis(std::span<const double, 4>(orientations.data() + 4 * i, 4));
    const auto u0 = quaternion::body_axis(std::span<const double, 4>(reference.data() + 4 * i, 4));
    for (int c = 0; c < 3; ++c) {
      msd += rotation_vectors[3 * i + c] * rotation_vectors[3 * i + c];
      correlation += u[c] * u0[c];
    }
  }
  return {msd, correlation};
}

}  // namespace rpyfmm::bd
