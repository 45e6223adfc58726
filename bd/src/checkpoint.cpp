#include "rpyfmm/bd/checkpoint.hpp"

#include <cstring>
#include <fstream>
#include <iterator>

#include "rpyfmm/core/atomic_file.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

namespace {
constexpr char kMagic[8] = {'R', 'P', 'Y', 'F', 'M', 'M', 'B', 'D'};
constexpr std::uint32_t kVersion = 1;

std::uint64_t fnv1a(const std::string& bytes) {
  std::uint64_t h = 1469598103934665603ull;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
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
  std::string out(kMagic, sizeof kMagic);
  put(out, kVersion);
  put(out, static_cast<std::uint64_t>(n));
  put(out, c.step);
  put(out, c.seed);
  put(out, c.dt);
  put(out, c.trajectory_bytes);
  put(out, c.log_bytes);
  put_vector(out, c.positions);
  put_vector(out, c.reference_positions);
  put_vector(out, c.types);
  put(out, static_cast<std::uint64_t>(c.config.size()));
  out += c.config;
  put(out, fnv1a(out));
  write_file_atomically(path, [&](std::ostream& s) { s.write(out.data(), static_cast<std::streamsize>(out.size())); });
}

Checkpoint read_checkpoint(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(ErrorCode::io_error, "read_checkpoint", "cannot open '" + name + "'");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() < sizeof kMagic + 8 || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
    fail(ErrorCode::io_error, "read_checkpoint", "'" + name + "' is not an rpyfmm BD checkpoint");
  std::uint64_t stored = 0;
  std::memcpy(&stored, bytes.data() + bytes.size() - 8, 8);
  if (stored != fnv1a(bytes.substr(0, bytes.size() - 8)))
    fail(ErrorCode::io_error, "read_checkpoint", "'" + name + "' is corrupt (checksum mismatch)");
  Reader r(bytes, name);
  r.get_vector<char>(sizeof kMagic, "magic");
  const auto version = r.get<std::uint32_t>("version");
  if (version != kVersion)
    fail(ErrorCode::io_error, "read_checkpoint",
         "'" + name + "' has format version " + std::to_string(version) + ", expected " + std::to_string(kVersion));
  Checkpoint c;
  const auto n = r.get<std::uint64_t>("N");
  if (n == 0 || n > (bytes.size() / 28)) fail(ErrorCode::io_error, "read_checkpoint", "'" + name + "' has a bad N");
  c.step = r.get<std::uint64_t>("step");
  c.seed = r.get<std::uint64_t>("seed");
  c.dt = r.get<double>("dt");
  c.trajectory_bytes = r.get<std::uint64_t>("trajectory length");
  c.log_bytes = r.get<std::uint64_t>("log length");
  c.positions = r.get_vector<double>(3 * n, "positions");
  c.reference_positions = r.get_vector<double>(3 * n, "reference positions");
  c.types = r.get_vector<std::uint32_t>(n, "types");
  const auto len = r.get<std::uint64_t>("config length");
  const auto cfg = r.get_vector<char>(len, "config");
  c.config.assign(cfg.begin(), cfg.end());
  if (r.pos() + 8 != bytes.size()) fail(ErrorCode::io_error, "read_checkpoint", "'" + name + "' has trailing bytes");
  return c;
}

}  // namespace rpyfmm::bd
