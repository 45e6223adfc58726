#include "array_io.hpp"

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "rpyfmm/core/atomic_file.hpp"
#include "rpyfmm/core/error.hpp"

namespace rpyfmm::cli {
namespace {

[[noreturn]] void bad(const std::filesystem::path& path, const std::string& what) {
  throw Error(ErrorCode::io_error, "'" + path.string() + "': " + what);
}

// Value of key `key` in the .npy header dict (a Python literal).
std::string header_value(const std::string& header, const std::string& key, const std::filesystem::path& path) {
  const std::string quoted_a = "'" + key + "'";
  auto pos = header.find(quoted_a);
  if (pos == std::string::npos) bad(path, "malformed .npy header: no '" + key + "'");
  pos = header.find(':', pos + quoted_a.size());
  if (pos == std::string::npos) bad(path, "malformed .npy header near '" + key + "'");
  ++pos;
  while (pos < header.size() && header[pos] == ' ') ++pos;
  if (pos >= header.size()) bad(path, "malformed .npy header near '" + key + "'");
  std::size_t end;
  if (header[pos] == '(') {
    end = header.find(')', pos);
    if (end == std::string::npos) bad(path, "malformed .npy shape");
    return header.substr(pos, end - pos + 1);
  }
  if (header[pos] == '\'' || header[pos] == '"') {
    end = header.find(header[pos], pos + 1);
    if (end == std::string::npos) bad(path, "malformed .npy header string");
    return header.substr(pos + 1, end - pos - 1);
  }
  end = header.find_first_of(",}", pos);
  if (end == std::string::npos) bad(path, "malformed .npy header");
  return header.substr(pos, end - pos);
}

std::vector<std::size_t> parse_shape(const std::string& tuple, const std::filesystem::path& path) {
  std::vector<std::size_t> shape;
  std::string inner = tuple.substr(1, tuple.size() - 2);
  std::stringstream ss(inner);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const auto first = item.find_first_not_of(' ');
    if (first == std::string::npos) continue;
    char* end = nullptr;
    errno = 0;
    const unsigned long long v = std::strtoull(item.c_str() + first, &end, 10);
    if (errno != 0 || end == item.c_str() + first) bad(path, "malformed .npy shape " + tuple);
    shape.push_back(static_cast<std::size_t>(v));
  }
  return shape;
}

Array read_npy(const std::filesystem::path& path, std::ifstream& in) {
  char magic[8];
  in.read(magic, 8);
  if (!in || std::memcmp(magic, "\x93NUMPY", 6) != 0) bad(path, "not a .npy file (bad magic)");
  const int major = static_cast<unsigned char>(magic[6]);
  std::uint32_t header_len = 0;
  if (major == 1) {
    unsigned char b[2];
    in.read(reinterpret_cast<char*>(b), 2);
    header_len = b[0] | (b[1] << 8);
  } else if (major == 2 || major == 3) {
    unsigned char b[4];
    in.read(reinterpret_cast<char*>(b), 4);
    header_len = b[0] | (b[1] << 8) | (b[2] << 16) | (std::uint32_t(b[3]) << 24);
  } else {
    bad(path, "unsupported .npy version " + std::to_string(major));
  }
  if (!in || header_len > (1u << 20)) bad(path, "truncated or malformed .npy header");
  std::string header(header_len, '\0');
  in.read(header.data(), header_len);
  if (!in) bad(path, "truncated .npy header");

  const std::string descr = header_value(header, "descr", path);
  const std::string fortran = header_value(header, "fortran_order", path);
  Array a;
  a.shape = parse_shape(header_value(header, "shape", path), path);
  if (fortran.find("True") != std::string::npos) bad(path, "Fortran-order arrays are not supported (use C order)");
  std::size_t count = 1;
  for (std::size_t s : a.shape) {
    if (s != 0 && count > std::numeric_limits<std::size_t>::max() / s) bad(path, "shape too large");
    count *= s;
  }
  std::size_t item = 0;
  if (descr == "<f8" || descr == "=f8" || descr == "f8") item = 8;
  else if (descr == "<f4" || descr == "=f4" || descr == "f4") item = 4;
  else bad(path, "unsupported dtype '" + descr + "' (need little-endian float64 or float32)");

  a.data.resize(count);
  if (item == 8) {
    in.read(reinterpret_cast<char*>(a.data.data()), static_cast<std::streamsize>(count * 8));
  } else {
    std::vector<float> f(count);
    in.read(reinterpret_cast<char*>(f.data()), static_cast<std::streamsize>(count * 4));
    for (std::size_t i = 0; i < count; ++i) a.data[i] = f[i];
  }
  if (static_cast<std::size_t>(in.gcount()) != count * item && count > 0) {
    bad(path, "truncated .npy data: expected " + std::to_string(count * item) + " bytes, got " +
                  std::to_string(in.gcount()));
  }
  return a;
}

Array read_text(const std::filesystem::path& path, std::ifstream& in) {
  Array a;
  std::string line;
  std::size_t cols = 0, rows = 0, lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::size_t n = 0;
    const char* p = line.c_str();
    while (true) {
      while (*p == ' ' || *p == '\t' || *p == ',' || *p == '\r') ++p;
      if (*p == '\0') break;
      char* end = nullptr;
      const double v = std::strtod(p, &end);
      if (end == p) bad(path, "line " + std::to_string(lineno) + ": not a number near '" + std::string(p).substr(0, 16) + "'");
      a.data.push_back(v);
      ++n;
      p = end;
    }
    if (n == 0) continue;
    if (rows == 0) cols = n;
    else if (n != cols) bad(path, "line " + std::to_string(lineno) + " has " + std::to_string(n) + " values, expected " + std::to_string(cols));
    ++rows;
  }
  if (rows == 0) a.shape = {0};
  else if (cols == 1) a.shape = {rows};
  else a.shape = {rows, cols};
  return a;
}

}  // namespace

Array read_array(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) bad(path, "cannot open file (does it exist?)");
  char first = 0;
  in.get(first);
  in.seekg(0);
  if (static_cast<unsigned char>(first) == 0x93) return read_npy(path, in);
  return read_text(path, in);
}

void write_npy(const std::filesystem::path& path, const std::vector<std::size_t>& shape,
               const std::vector<double>& data) {
  std::string dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (";
  for (std::size_t i = 0; i < shape.size(); ++i) dict += std::to_string(shape[i]) + (shape.size() == 1 ? "," : (i + 1 < shape.size() ? ", " : ""));
  dict += "), }";
  const std::size_t unpadded = 10 + dict.size() + 1;
  dict.append((64 - unpadded % 64) % 64, ' ');
  dict += '\n';
  write_file_atomically(path, [&](std::ostream& out) {
    out.write("\x93NUMPY\x01\x00", 8);
    const auto len = static_cast<std::uint16_t>(dict.size());
    const char lb[2] = {static_cast<char>(len & 0xff), static_cast<char>(len >> 8)};
    out.write(lb, 2);
    out.write(dict.data(), static_cast<std::streamsize>(dict.size()));
    out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size() * sizeof(double)));
  });
}

std::vector<double> as_points(const Array& a, const std::string& what) {
  const bool n3 = a.shape.size() == 2 && a.shape[1] == 3;
  const bool flat = a.shape.size() == 1 && a.shape[0] % 3 == 0;
  if (!n3 && !flat) {
    std::string s = "(";
    for (std::size_t i = 0; i < a.shape.size(); ++i) s += (i ? "," : "") + std::to_string(a.shape[i]);
    throw Error(ErrorCode::invalid_input, what + " must have shape (N,3) or (3N,), got " + s + ")");
  }
  if (a.data.empty()) throw Error(ErrorCode::invalid_input, what + " is empty (N = 0)");
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    if (!std::isfinite(a.data[i])) {
      throw Error(ErrorCode::invalid_input, what + " entry (" + std::to_string(i / 3) + ", " + std::to_string(i % 3) +
                                                ") is " + (std::isnan(a.data[i]) ? "NaN" : "infinite"));
    }
  }
  return a.data;
}

std::vector<double> as_vector(const Array& a, std::size_t n, const std::string& what) {
  const bool ok = (a.shape.size() == 1 && a.shape[0] == n) || (a.shape.size() == 2 && a.shape[0] == n && a.shape[1] == 1);
  if (!ok) {
    std::string s = "(";
    for (std::size_t i = 0; i < a.shape.size(); ++i) s += (i ? "," : "") + std::to_string(a.shape[i]);
    throw Error(ErrorCode::invalid_input, what + " must have shape (" + std::to_string(n) + ",), got " + s + ")");
  }
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    if (!std::isfinite(a.data[i])) {
      throw Error(ErrorCode::invalid_input, what + " entry " + std::to_string(i) + " is " + (std::isnan(a.data[i]) ? "NaN" : "infinite"));
    }
  }
  return a.data;
}

}  // namespace rpyfmm::cli
