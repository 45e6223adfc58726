// rpyfmm CLI — .npy files read and written by every rank with MPI-IO (docs/mpi.md, "The
// command-line tool under mpirun"): rank 0 parses or writes the header, every rank reads or
// writes its own contiguous run of values with MPI_File_read_at_all / MPI_File_write_at_all.
// Every function is collective over `comm` and fails on every rank alike (Communicator::run), with
// a message naming the file and, for a failed MPI-IO call, the call and MPI's error string.
#pragma once

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::cli {

/// Rank 0's npy_file_layout of `path` on every rank (one broadcast): nullopt where the input is not
/// a regular .npy file (text, a pipe: read by rank 0 with read_array). Rank 0's errors (a missing
/// file, a bad header, a size that does not match the shape) fail every rank with its message.
std::optional<NpyLayout> shared_npy_layout(const std::string& path, const mpi::Communicator& comm);

/// The values [first, first + count) of the .npy file laid out as `layout`, as doubles (float32
/// widened as read_array does), read by every rank at once with MPI_File_read_at_all.
std::vector<double> read_values_at_all(const std::string& path, const NpyLayout& layout, std::size_t first,
                                       std::size_t count, const mpi::Communicator& comm);

/// Writes the float64 .npy of `shape` whose values [first, first + local.size()) are each rank's
/// `local`, byte for byte write_npy's file, under write_npy's rules (rpyfmm/core/atomic_file.hpp):
/// a target that exists and is not a regular file is refused; rank 0 creates a new temporary next
/// to it and writes the header, every rank writes its values with MPI_File_write_at_all, the file
/// is synced, and rank 0 renames it over the target once every rank succeeded. On any failure the
/// temporary is removed and the target is left as it was.
void write_npy_at_all(const std::string& path, const std::vector<std::size_t>& shape, std::span<const double> local,
                      std::size_t first, const mpi::Communicator& comm);

/// A run of a rank's values in the whole array: values [first, first + values.size()).
struct NpyRun {
  std::size_t first = 0;
  std::span<const double> values;
};
/// write_npy_at_all with each rank's values in several runs (every rank passes as many runs, as
/// each run is one MPI_File_write_at_all): e.g. one run per density of an (nd, M, 10) result.
void write_npy_at_all(const std::string& path, const std::vector<std::size_t>& shape, std::span<const NpyRun> runs,
                      const mpi::Communicator& comm);

/// write_npy_at_all's file without its last step: the temporary next to `path`, written and synced,
/// whose name it returns on every rank; the caller renames it (rank 0, replace_with) or removes it.
/// On any failure the temporary is removed first.
std::string write_npy_temporary_at_all(const std::string& path, const std::vector<std::size_t>& shape,
                                       std::span<const NpyRun> runs, const mpi::Communicator& comm);

}  // namespace rpyfmm::cli
