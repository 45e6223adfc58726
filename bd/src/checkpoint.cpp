#include "rpyfmm/bd/checkpoint.hpp"

#include <cstring>
#include <fstream>
#include <iterator>

#include "rpyfmm/core/atomic_file.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

namespace {
constexpr char kMagic[8] = {'R', 'P', 'Y', 'F', 'M', 'M', 'B', 'D'};
constexpr std::uint32_t kVersion = 2;          // 2: output hashes (version 1 could not identify its files)
constexpr std::uint32_t kRotationVersion = 3;  // 3: version 2 with orientations (runs with rotation)
constexpr std::uint32_t kLangevinVersion = 4;  // 4: version 2 with velocities (runs with Langevin types)

std::uint64_t fnv1a(std::string_view bytes) {
  Fnv1a h;
  h.add(bytes);
  return h.value();
}

// The whole content of the regular file `path`; io_error naming it otherwise.
std::string read_regular_file(const std::filesystem::path& path) {
  const std::string name = file_safety_detail::quoted(path);
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status))
    fail(ErrorCode::io_error, "read_checkpoint", "cannot open " + name + " (does it exist?)");
  if (!std::filesystem::is_regular_file(status))
    fail(ErrorCode::io_error, "read_checkpoint",
         name + " is " + (std::filesystem::is_directory(status) ? "a directory" : "not a regular file") +
             ", not a checkpoint file");
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(ErrorCode::io_error, "read_checkpoint", "cannot open " + name);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) fail(ErrorCode::io_error, "read_checkpoint", "cannot read " + name);
  return bytes;
}

template <class T>
void put(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}
template <class T>
void put_vector(std::string& out, const std::vector<T>& v) {
  out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

class Reader {
 public:
  Reader(const std::string& bytes, std::string name) : bytes_(bytes), name_(std::move(name)) {}
  template <class T>
  T get(const char* what) {
    need(sizeof(T), what);
    T v;
    std::memcpy(&v, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  template <class T>
  std::vector<T> get_vector(std::size_t count, const char* what) {
    need(count * sizeof(T), what);
    std::vector<T> v(count);
    if (count > 0) std::memcpy(v.data(), bytes_.data() + pos_, count * sizeof(T));  // data() may be null at 0
    pos_ += count * sizeof(T);
    return v;
  }
  std::size_t pos() const { return pos_; }

 private:
  void need(std::size_t n, const char* what) {
    if (bytes_.size() - pos_ < n)
      fail(ErrorCode::io_error, "read_checkpoint", "'" + name_ + "' is truncated (reading " + what + ")");
  }
  const std::string& bytes_;
  std::string name_;
  std::size_t pos_ = 0;
};
}  // namespace

void write_checkpoint(const std::filesystem::path& path, const Checkpoint& c) {
  const std::size_t n = c.types.size();
  require(c.positions.size() == 3 * n && c.reference_positions.size() == 3 * n, ErrorCode::invalid_input,
          "write_checkpoint", "positions, reference positions and types disagree on N");
  const bool rotation = !c.orientations.empty();
  require(!rotation || (c.orientations.size() == 4 * n && c.reference_orientations.size() == 4 * n &&
                        c.rotation_vectors.size() == 3 * n),
          ErrorCode::invalid_input, "write_checkpoint",
          "orientations, reference orientations, rotation vectors and types disagree on N");
  const bool inertial = !c.velocities.empty();
  require(!inertial || (c.velocities.size() == 3 * n && !rotation), ErrorCode::invalid_input, "write_checkpoint",
          "velocities and types disagree on N, or come with orientations");
  std::string out(kMagic, sizeof kMagic);
  put(out, rotation ? kRotationVersion : inertial ? kLangevinVersion : kVersion);
  put(out, static_cast<std::uint64_t>(n));
  put(out, c.step);
  put(out, c.seed);
  put(out, c.dt);
  put(out, c.trajectory_bytes);
  put(out, c.trajectory_hash);
  put(out, c.log_bytes);
  put(out, c.log_hash);
  put_vector(out, c.positions);
  put_vector(out, c.reference_positions);
  put_vector(out, c.types);
  if (rotation) {
    put_vector(out, c.orientations);
    put_vector(out, c.reference_orientations);
    put_vector(out, c.rotation_vectors);
  }
  if (inertial) put_vector(out, c.velocities);
  put(out, static_cast<std::uint64_t>(c.config.size()));
  out += c.config;
  put(out, fnv1a(out));
  write_file_atomically(path, [&](std::ostream& s) { s.write(out.data(), static_cast<std::streamsize>(out.size())); });
}

Checkpoint read_checkpoint(const std::filesystem::path& path) {
  const std::string name = path.string();
  const std::string bytes = read_regular_file(path);
  if (bytes.size() < sizeof kMagic + 8 || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
    fail(ErrorCode::io_error, "read_checkpoint", "'" + name + "' is not an rpyfmm BD checkpoint");
  std::uint64_t stored = 0;
  std::memcpy(&stored, bytes.data() + bytes.size() - 8, 8);
  if (stored != fnv1a(std::string_view(bytes).substr(0, bytes.size() - 8)))
    fail(ErrorCode::io_error, "read_checkpoint", "'" + name + "' is corrupt (checksum mismatch)");
  Reader r(bytes, name);
  r.get_vector<char>(sizeof kMagic, "magic");
  const auto version = r.get<std::uint32_t>("version");
  if (version != kVersion && version != kRotationVersion && version != kLangevinVersion)
    fail(ErrorCode::io_error, "read_checkpoint",
         "'" + name + "' has format version " + std::to_string(version) + ", expected " + std::to_string(kVersion) +
             ", " + std::to_string(kRotationVersion) + " or " + std::to_string(kLangevinVersion) +
             (version == 1 ? " (version 1 does not identify its output files; start the run afresh)" : ""));
  Checkpoint c;
  const auto n = r.get<std::uint64_t>("N");
  if (n == 0 || n > (bytes.size() / 28)) fail(ErrorCode::io_error, "read_checkpoint", "'" + name + "' has a bad N");
  c.step = r.get<std::uint64_t>("step");
  c.seed = r.get<std::uint64_t>("seed");
  c.dt = r.get<double>("dt");
  c.trajectory_bytes = r.get<std::uint64_t>("trajectory length");
  c.trajectory_hash = r.get<std::uint64_t>("trajectory hash");
  c.log_bytes = r.get<std::uint64_t>("log length");
  c.log_hash = r.get<std::uint64_t>("log hash");
  c.positions = r.get_vector<double>(3 * n, "positions");
  c.reference_positions = r.get_vector<double>(3 * n, "reference positions");
  c.types = r.get_vector<std::uint32_t>(n, "types");
  if (version == kRotationVersion) {
    c.orientations = r.get_vector<double>(4 * n, "orientations");
    c.reference_orientations = r.get_vector<double>(4 * n, "reference orientations");
    c.rotation_vectors = r.get_vector<double>(3 * n, "rotation vectors");
  }
  if (version == kLangevinVersion) c.velocities = r.get_vector<double>(3 * n, "velocities");
  const auto len = r.get<std::uint64_t>("config length");
  const auto cfg = r.get_vector<char>(len, "config");
  c.config.assign(cfg.begin(), cfg.end());
  if (r.pos() + 8 != bytes.size()) fail(ErrorCode::io_error, "read_checkpoint", "'" + name + "' has trailing bytes");
  return c;
}

}  // namespace rpyfmm::bd
