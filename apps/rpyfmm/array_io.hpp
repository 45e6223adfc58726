// rpyfmm CLI — reading and writing arrays: NumPy .npy (float64/float32,
// C order) and whitespace-separated text. Errors are rpyfmm::Error with a
// message naming the file and the problem.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rpyfmm::cli {

struct Array {
  std::vector<std::size_t> shape;  // e.g. {N, 3}
  std::vector<double> data;        // row-major (C order), converted to double
  [[nodiscard]] std::size_t rows() const { return shape.empty() ? 1 : shape[0]; }
};

/// Text arrays: a line may hold at most kMaxTextLineBytes and the input at most kMaxTextBytes
/// (larger data belongs in .npy); beyond either the reader stops with an error, so an endless or
/// binary input (/dev/zero) fails at once instead of filling memory.
inline constexpr std::size_t kMaxTextLineBytes = std::size_t{1} << 20;  // 1 MiB
inline constexpr std::uint64_t kMaxTextBytes = std::uint64_t{1} << 30;  // 1 GiB

/// Where a .npy file's values lie: its shape, the bytes per value (8: float64, 4: float32, both
/// little-endian as the reader requires) and the offset of the first value (C order).
struct NpyLayout {
  std::vector<std::size_t> shape;
  std::size_t item = 8;
  std::uint64_t data_offset = 0;
  /// The number of values: the product of the shape.
  [[nodiscard]] std::uint64_t values() const;
};

/// Reads `.npy` (by magic bytes) or text (one row per line). Throws on
/// missing files, directories, malformed/truncated .npy (the declared shape is checked against
/// the file's size before anything is allocated), unsupported dtype or Fortran order,
/// ragged text rows, non-numeric text, text beyond the limits above, and exhausted memory.
Array read_array(const std::filesystem::path& path);
/// The layout of a regular .npy file (first byte 0x93), with read_array's checks and messages on
/// its header and size; nullopt for any other input (text, a pipe, a directory, a missing file),
/// which read_array reads or refuses. A regular file that cannot be opened throws as in read_array.
std::optional<NpyLayout> npy_file_layout(const std::filesystem::path& path);
/// The same reader over bytes in memory; `name` names the input in messages.
Array read_array_bytes(std::string_view bytes, const std::string& name);

/// The bytes of a float64 .npy of `shape` holding `data` (`data` must outlive the writer).
std::function<void(std::ostream&)> npy_writer(const std::vector<std::size_t>& shape, const std::vector<double>& data);

/// Writes a float64 .npy with write_file_atomically (rpyfmm/core/atomic_file.hpp): a target
/// that is not a regular file is refused; a new temporary is fsync'ed and renamed over it.
void write_npy(const std::filesystem::path& path, const std::vector<std::size_t>& shape,
               const std::vector<double>& data);

/// "(d0,d1,...)", as NumPy prints a shape without spaces: "(4,)" for one dimension, "()" for none.
std::string shape_text(const std::vector<std::size_t>& shape);

/// One output of write_npys: an empty `path` means "not asked for" and is skipped.
struct NpyOutput {
  std::filesystem::path path;
  std::vector<std::size_t> shape;
  const std::vector<double>* data = nullptr;
};
/// Writes the outputs of one command together (write_files_atomically): all go to temporaries
/// first and replace their targets only when every one is on disk, so a second output that
/// cannot be written (missing folder, full disk) leaves no first output behind.
void write_npys(const std::vector<NpyOutput>& outputs);

/// write_npy's bytes before the values: the float64 C-order header of `shape` (version 1.0, padded
/// to a multiple of 64 bytes).
std::string npy_header(const std::vector<std::size_t>& shape);

/// The index of the first value that is not finite, if any.
std::optional<std::size_t> first_nonfinite(std::span<const double> values);
/// The checks' words for the non-finite value at flat index `index`: "entry (i, c) is NaN" with
/// `stride` > 1 values per row, "entry i is infinite" with one (`nan` says which).
std::string nonfinite_entry(std::size_t index, std::size_t stride, bool nan);

/// as_points' check of the shape ((N,3) or (3N,), N > 0), its message naming `what`.
void require_points_shape(const std::vector<std::size_t>& shape, const std::string& what);
/// as_vector's check of the shape ((n,) or (n,1)).
void require_vector_shape(const std::vector<std::size_t>& shape, std::size_t n, const std::string& what);
/// as_split_rows6's check of the shape ((n,6)).
void require_rows6_shape(const std::vector<std::size_t>& shape, std::size_t n, const std::string& what);
/// Rows of six values split into their first and their second triples.
std::pair<std::vector<double>, std::vector<double>> split_rows6(std::span<const double> rows);

/// Interprets `a` as N x 3 points: shape (N,3) or (3N,). Throws naming `what`.
std::vector<double> as_points(const Array& a, const std::string& what);
/// Interprets `a` as N rows of six values, each a translational then a rotational triple (shape
/// (N,6)), with every entry finite: returns {first triples, second triples}, 3N values each. Throws
/// naming `what`.
std::pair<std::vector<double>, std::vector<double>> as_split_rows6(const Array& a, std::size_t n,
                                                                   const std::string& what);
/// Interprets `a` as a vector of N values: shape (N,) or (N,1).
std::vector<double> as_vector(const Array& a, std::size_t n, const std::string& what);

}  // namespace rpyfmm::cli
