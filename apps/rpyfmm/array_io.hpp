// rpyfmm CLI — reading and writing arrays: NumPy .npy (float64/float32,
// C order) and whitespace-separated text. Errors are rpyfmm::Error with a
// message naming the file and the problem.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
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

/// Reads `.npy` (by magic bytes) or text (one row per line). Throws on
/// missing files, directories, malformed/truncated .npy (the declared shape is checked against
/// the file's size before anything is allocated), unsupported dtype or Fortran order,
/// ragged text rows, non-numeric text, text beyond the limits above, and exhausted memory.
Array read_array(const std::filesystem::path& path);
/// The same reader over bytes in memory; `name` names the input in messages.
Array read_array_bytes(std::string_view bytes, const std::string& name);

/// Writes a float64 .npy with write_file_atomically (rpyfmm/core/atomic_file.hpp): a target
/// that is not a regular file is refused; a new temporary is fsync'ed and renamed over it.
void write_npy(const std::filesystem::path& path, const std::vector<std::size_t>& shape,
               const std::vector<double>& data);

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
