#include "array_io.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <new>
#include <optional>
#include <sstream>
#include <string_view>

#include "rpyfmm/core/atomic_file.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

std::string shape_text(const std::vector<std::size_t>& shape) {
  // Appended piecewise: GCC 12 warns falsely (-Wrestrict) on `const char* + std::string&&`.
  std::string s = "(";
  for (std::size_t i = 0; i < shape.size(); ++i) {
    if (i) s += ',';
    s += std::to_string(shape[i]);
  }
  return s + (shape.size() == 1 ? ",)" : ")");
}

namespace {

[[noreturn]] void bad(const std::string& name, const std::string& what) {
  throw Error(ErrorCode::io_error, "'" + name + "': " + what);
}

// A short excerpt of untrusted bytes for a one-line message: printable ASCII as is, anything
// else (newlines, NUL, binary) as \xNN, at most `max` bytes, with "..." when cut.
std::string excerpt(std::string_view bytes, std::size_t max = 16) {
  std::string out;
  for (std::size_t i = 0; i < bytes.size() && i < max; ++i) {
    const auto c = static_cast<unsigned char>(bytes[i]);
    if (c >= 0x20 && c < 0x7f && c != '\\') {
      out += static_cast<char>(c);
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    }
  }
  if (bytes.size() > max) out += "...";
  return out;
}

// A byte count for messages: "4800 bytes".
std::string bytes_str(std::uint64_t n) {
  return std::to_string(n) + " bytes";
}

// Value of key `key` in the .npy header dict (a Python literal).
std::string header_value(const std::string& header, const std::string& key, const std::string& name) {
  const std::string quoted_a = "'" + key + "'";
  auto pos = header.find(quoted_a);
  if (pos == std::string::npos) bad(name, "malformed .npy header: no '" + key + "'");
  pos = header.find(':', pos + quoted_a.size());
  if (pos == std::string::npos) bad(name, "malformed .npy header near '" + key + "'");
  ++pos;
  while (pos < header.size() && header[pos] == ' ') ++pos;
  if (pos >= header.size()) bad(name, "malformed .npy header near '" + key + "'");
  std::size_t end;
  if (header[pos] == '(') {
    end = header.find(')', pos);
    if (end == std::string::npos) bad(name, "malformed .npy shape");
    return header.substr(pos, end - pos + 1);
  }
  if (header[pos] == '\'' || header[pos] == '"') {
    end = header.find(header[pos], pos + 1);
    if (end == std::string::npos) bad(name, "malformed .npy header string");
    return header.substr(pos + 1, end - pos - 1);
  }
  end = header.find_first_of(",}", pos);
  if (end == std::string::npos) bad(name, "malformed .npy header");
  return header.substr(pos, end - pos);
}

// "(50, 3)" -> {50, 3}: decimal digits only (no sign, which strtoull would wrap), each < 2^63.
std::vector<std::size_t> parse_shape(const std::string& tuple, const std::string& name) {
  std::vector<std::size_t> shape;
  if (tuple.size() < 2 || tuple.front() != '(' || tuple.back() != ')')
    bad(name, "malformed .npy shape '" + excerpt(tuple, 64) + "' (expected a tuple such as (N, 3))");
  std::stringstream ss(tuple.substr(1, tuple.size() - 2));
  std::string item;
  while (std::getline(ss, item, ',')) {
    const auto first = item.find_first_not_of(' ');
    if (first == std::string::npos) continue;
    const auto last = item.find_last_not_of(' ');
    const std::string digits = item.substr(first, last - first + 1);
    std::uint64_t v = 0;
    const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    if (ec != std::errc() || end != digits.data() + digits.size() || digits[0] == '-' ||
        v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()))
      bad(name, "malformed .npy shape " + excerpt(tuple, 64));
    shape.push_back(static_cast<std::size_t>(v));
  }
  return shape;
}

std::string shape_str(const std::vector<std::size_t>& shape) {
  std::string s = "(";
  for (std::size_t i = 0; i < shape.size(); ++i) s += (i ? ", " : "") + std::to_string(shape[i]);
  return s + ")";
}

// Reads `count` items of `item` bytes, growing the array as the data arrives (chunks of at most
// 8 MiB), so that a header that lies about the size costs no more memory than the data present.
void read_npy_data(std::istream& in, std::size_t count, std::size_t item, Array& a, const std::string& name) {
  constexpr std::size_t kChunkItems = std::size_t{1} << 20;
  std::vector<char> raw;
  while (a.data.size() < count) {
    const std::size_t items = std::min(kChunkItems, count - a.data.size());
    raw.resize(items * item);
    in.read(raw.data(), static_cast<std::streamsize>(raw.size()));
    const auto got = static_cast<std::size_t>(in.gcount());
    if (got != raw.size()) {
      bad(name, "truncated .npy data: the header declares shape " + shape_str(a.shape) + ", " +
                    bytes_str(std::uint64_t(count) * item) + ", but the data ends after " +
                    bytes_str(std::uint64_t(a.data.size()) * item + got));
    }
    const std::size_t base = a.data.size();
    a.data.resize(base + items);
    if (item == 8) {
      std::memcpy(a.data.data() + base, raw.data(), raw.size());
    } else {
      for (std::size_t i = 0; i < items; ++i) {
        float f;
        std::memcpy(&f, raw.data() + 4 * i, 4);
        a.data[base + i] = f;
      }
    }
  }
}

// The header of a .npy input, checked: magic, version, dict, dtype, C order, and (with `size`, the
// input's total size in bytes when known: a regular file, bytes in memory) the shape against the
// bytes the input holds, before anything is allocated. Leaves `in` at the first value.
NpyLayout read_npy_header(std::istream& in, const std::string& name, std::optional<std::uint64_t> size) {
  char magic[8];
  in.read(magic, 8);
  if (!in || std::memcmp(magic, "\x93NUMPY", 6) != 0) bad(name, "not a .npy file (bad magic)");
  const int major = static_cast<unsigned char>(magic[6]);
  std::uint32_t header_len = 0;
  NpyLayout layout;
  if (major == 1) {
    unsigned char b[2];
    in.read(reinterpret_cast<char*>(b), 2);
    header_len = b[0] | (b[1] << 8);
    layout.data_offset = 10 + std::uint64_t(header_len);
  } else if (major == 2 || major == 3) {
    unsigned char b[4];
    in.read(reinterpret_cast<char*>(b), 4);
    header_len = b[0] | (b[1] << 8) | (b[2] << 16) | (std::uint32_t(b[3]) << 24);
    layout.data_offset = 12 + std::uint64_t(header_len);
  } else {
    bad(name, "unsupported .npy version " + std::to_string(major));
  }
  if (!in || header_len > (1u << 20)) bad(name, "truncated or malformed .npy header");
  if (size && layout.data_offset > *size) bad(name, "truncated .npy header");
  std::string header(header_len, '\0');
  in.read(header.data(), header_len);
  if (!in) bad(name, "truncated .npy header");

  const std::string descr = header_value(header, "descr", name);
  const std::string fortran = header_value(header, "fortran_order", name);
  layout.shape = parse_shape(header_value(header, "shape", name), name);
  if (fortran.find("True") != std::string::npos) bad(name, "Fortran-order arrays are not supported (use C order)");
  if (descr == "<f8" || descr == "=f8" || descr == "f8")
    layout.item = 8;
  else if (descr == "<f4" || descr == "=f4" || descr == "f4")
    layout.item = 4;
  else
    bad(name, "unsupported dtype '" + excerpt(descr, 32) + "' (need little-endian float64 or float32)");
  // The data's size, overflow-checked, against what the input holds: before allocating anything.
  std::uint64_t count = 1;
  for (std::size_t s : layout.shape) {
    if (s != 0 && count > std::numeric_limits<std::uint64_t>::max() / layout.item / s)
      bad(name, "the .npy shape " + shape_str(layout.shape) + " is too large");
    count *= s;
  }
  const std::uint64_t bytes = count * layout.item;
  if (size && bytes != *size - layout.data_offset) {
    bad(name,
        std::string(bytes > *size - layout.data_offset ? "truncated .npy data" : ".npy data followed by extra bytes") +
            ": the header declares shape " + shape_str(layout.shape) + ", " + bytes_str(bytes) +
            ", but the input holds " + bytes_str(*size - layout.data_offset) + " after the header");
  }
  if (count > std::numeric_limits<std::size_t>::max() / sizeof(double))
    bad(name, "the .npy shape " + shape_str(layout.shape) + " is too large");
  return layout;
}

Array read_npy(std::istream& in, const std::string& name, std::optional<std::uint64_t> size) {
  const NpyLayout layout = read_npy_header(in, name, size);
  Array a;
  a.shape = layout.shape;
  read_npy_data(in, static_cast<std::size_t>(layout.values()), layout.item, a, name);
  return a;
}

// Reads one line of at most kMaxTextLineBytes (without the '\n'); false at the end of input.
// `total` counts the bytes read so far, bounded by kMaxTextBytes.
bool read_line(std::istream& in, std::string& line, std::uint64_t& total, std::size_t lineno, const std::string& name) {
  line.clear();
  std::streambuf* buf = in.rdbuf();
  for (;;) {
    const int c = buf->sbumpc();
    if (c == std::char_traits<char>::eof()) return !line.empty();
    if (++total > kMaxTextBytes)
      bad(name, "text input larger than " + bytes_str(kMaxTextBytes) + " (the limit for text arrays; use .npy)");
    if (c == '\n') return true;
    if (line.size() == kMaxTextLineBytes)
      bad(name, "line " + std::to_string(lineno) + " is longer than " + bytes_str(kMaxTextLineBytes) +
                    " (binary data? text arrays hold one row per line)");
    line += static_cast<char>(c);
  }
}

Array read_text(std::istream& in, const std::string& name, std::optional<std::uint64_t> size) {
  if (size && *size > kMaxTextBytes)
    bad(name, "text input of " + bytes_str(*size) + " is larger than " + bytes_str(kMaxTextBytes) +
                  " (the limit for text arrays; use .npy)");
  Array a;
  std::string line;
  std::size_t cols = 0, rows = 0, lineno = 0;
  std::uint64_t total = 0;
  while (read_line(in, line, total, lineno + 1, name)) {
    ++lineno;
    const auto hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::size_t n = 0;
    const char* p = line.c_str();
    const char* const end_of_line = p + line.size();
    while (true) {
      while (p < end_of_line && (*p == ' ' || *p == '\t' || *p == ',' || *p == '\r')) ++p;
      if (p == end_of_line) break;
      char* end = nullptr;
      const double v = std::strtod(p, &end);
      if (end == p || end > end_of_line) {
        bad(name, "line " + std::to_string(lineno) + ": not a number near '" +
                      excerpt(std::string_view(p, static_cast<std::size_t>(end_of_line - p))) + "'");
      }
      a.data.push_back(v);
      ++n;
      p = end;
    }
    if (n == 0) continue;
    if (rows == 0)
      cols = n;
    else if (n != cols)
      bad(name,
          "line " + std::to_string(lineno) + " has " + std::to_string(n) + " values, expected " + std::to_string(cols));
    ++rows;
  }
  if (rows == 0)
    a.shape = {0};
  else if (cols == 1)
    a.shape = {rows};
  else
    a.shape = {rows, cols};
  return a;
}

// .npy (by the magic byte 0x93) or text; std::bad_alloc becomes an error naming the input.
Array read_stream(std::istream& in, const std::string& name, std::optional<std::uint64_t> size) {
  try {
    const int first = in.rdbuf()->sgetc();
    if (first == 0x93) return read_npy(in, name, size);
    return read_text(in, name, size);
  } catch (const std::bad_alloc&) {
    bad(name, "not enough memory to read it" + (size ? " (" + bytes_str(*size) + ")" : std::string()));
  }
}

}  // namespace

namespace {

// An input file opened for reading, with its size where it is a regular file; a directory or a
// file that cannot be opened throws.
struct OpenedInput {
  std::ifstream in;
  std::optional<std::uint64_t> size;
};

OpenedInput open_input(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (std::filesystem::is_directory(status)) bad(name, "is a directory, not an array file");
  OpenedInput opened{std::ifstream(path, std::ios::binary), std::nullopt};
  if (!opened.in) bad(name, "cannot open file (does it exist?)");
  if (std::filesystem::is_regular_file(status)) {
    const auto bytes = std::filesystem::file_size(path, ec);
    if (!ec) opened.size = bytes;
  }
  return opened;
}

}  // namespace

std::uint64_t NpyLayout::values() const {
  std::uint64_t count = 1;
  for (std::size_t s : shape) count *= s;
  return count;
}

Array read_array(const std::filesystem::path& path) {
  OpenedInput opened = open_input(path);
  return read_stream(opened.in, path.string(), opened.size);
}

std::optional<NpyLayout> npy_file_layout(const std::filesystem::path& path) {
  // Anything but a regular file (a pipe read once, a missing file) is left to read_array.
  std::error_code ec;
  if (!std::filesystem::is_regular_file(std::filesystem::status(path, ec))) return std::nullopt;
  OpenedInput opened = open_input(path);
  if (!opened.size || opened.in.rdbuf()->sgetc() != 0x93) return std::nullopt;
  return read_npy_header(opened.in, path.string(), opened.size);
}

Array read_array_bytes(std::string_view bytes, const std::string& name) {
  std::istringstream in{std::string(bytes)};
  return read_stream(in, name, bytes.size());
}

std::string npy_header(const std::vector<std::size_t>& shape) {
  std::string dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (";
  for (std::size_t i = 0; i < shape.size(); ++i)
    dict += std::to_string(shape[i]) + (shape.size() == 1 ? "," : (i + 1 < shape.size() ? ", " : ""));
  dict += "), }";
  const std::size_t unpadded = 10 + dict.size() + 1;
  dict.append((64 - unpadded % 64) % 64, ' ');
  dict += '\n';
  const auto len = static_cast<std::uint16_t>(dict.size());
  return std::string("\x93NUMPY\x01\x00", 8) + static_cast<char>(len & 0xff) + static_cast<char>(len >> 8) + dict;
}

std::function<void(std::ostream&)> npy_writer(const std::vector<std::size_t>& shape, const std::vector<double>& data) {
  return [header = npy_header(shape), &data](std::ostream& out) {
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    out.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size() * sizeof(double)));
  };
}

void write_npy(const std::filesystem::path& path, const std::vector<std::size_t>& shape,
               const std::vector<double>& data) {
  write_file_atomically(path, npy_writer(shape, data));
}

void write_npys(const std::vector<NpyOutput>& outputs) {
  std::vector<FileWrite> files;
  for (const NpyOutput& o : outputs)
    if (!o.path.empty()) files.push_back({o.path, npy_writer(o.shape, *o.data)});
  write_files_atomically(files);
}

std::string nonfinite_entry(std::size_t index, std::size_t stride, bool nan) {
  // Appended piecewise: GCC 12 warns falsely (-Wrestrict) on `const char* + std::string&&`.
  std::string entry = "entry ";
  if (stride > 1) {
    entry += '(';
    entry += std::to_string(index / stride);
    entry += ", ";
    entry += std::to_string(index % stride);
    entry += ')';
  } else {
    entry += std::to_string(index);
  }
  return entry + (nan ? " is NaN" : " is infinite");
}

std::optional<std::size_t> first_nonfinite(std::span<const double> values) {
  for (std::size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i])) return i;
  return std::nullopt;
}

void require_rows6_shape(const std::vector<std::size_t>& shape, std::size_t n, const std::string& what) {
  const bool rows6 = shape.size() == 2 && shape[1] == 6;
  require(rows6 && shape[0] == n, ErrorCode::invalid_input, what,
          "with --angular must have shape (" + std::to_string(n) + ",6), one row z_t then z_r per particle, got " +
              (rows6 ? std::to_string(shape[0]) + " rows" : std::to_string(shape.size()) + " dimensions") +
              (shape.size() == 2 ? " of " + std::to_string(shape[1]) + " columns" : ""));
}

std::pair<std::vector<double>, std::vector<double>> split_rows6(std::span<const double> rows) {
  const std::size_t n = rows.size() / 6;
  std::pair<std::vector<double>, std::vector<double>> split{std::vector<double>(3 * n), std::vector<double>(3 * n)};
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t c = 0; c < 3; ++c) {
      split.first[3 * i + c] = rows[6 * i + c];
      split.second[3 * i + c] = rows[6 * i + 3 + c];
    }
  return split;
}

std::pair<std::vector<double>, std::vector<double>> as_split_rows6(const Array& a, std::size_t n,
                                                                   const std::string& what) {
  require_rows6_shape(a.shape, n, what);
  require_finite(a.data, what, what, 6);
  return split_rows6(a.data);
}

void require_points_shape(const std::vector<std::size_t>& shape, const std::string& what) {
  const bool n3 = shape.size() == 2 && shape[1] == 3;
  const bool flat = shape.size() == 1 && shape[0] % 3 == 0;
  if (!n3 && !flat) {
    throw Error(ErrorCode::invalid_input, what + " must have shape (N,3) or (3N,), got " + shape_text(shape));
  }
  if (shape[0] == 0) throw Error(ErrorCode::invalid_input, what + " is empty (N = 0)");
}

std::vector<double> as_points(const Array& a, const std::string& what) {
  require_points_shape(a.shape, what);
  if (const auto i = first_nonfinite(a.data))
    throw Error(ErrorCode::invalid_input, what + " " + nonfinite_entry(*i, 3, std::isnan(a.data[*i])));
  return a.data;
}

void require_vector_shape(const std::vector<std::size_t>& shape, std::size_t n, const std::string& what) {
  const bool ok = (shape.size() == 1 && shape[0] == n) || (shape.size() == 2 && shape[0] == n && shape[1] == 1);
  if (!ok) {
    throw Error(ErrorCode::invalid_input,
                what + " must have shape (" + std::to_string(n) + ",), got " + shape_text(shape));
  }
}

std::vector<double> as_vector(const Array& a, std::size_t n, const std::string& what) {
  require_vector_shape(a.shape, n, what);
  if (const auto i = first_nonfinite(a.data))
    throw Error(ErrorCode::invalid_input, what + " " + nonfinite_entry(*i, 1, std::isnan(a.data[*i])));
  return a.data;
}

}  // namespace rpyfmm::cli
