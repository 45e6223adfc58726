// rpyfmm CLI — one input array's contiguous shares over the ranks (docs/mpi.md, "The command-line
// tool under mpirun"): read by rank 0 and scattered (--io root, and every input that is not a
// regular .npy file), or each rank reading its own share with MPI-IO (--io collective, the default).
// The serial command's checks run on the shape (rank 0) and on every rank's values (agreed), with
// the serial messages naming global indices.
#pragma once

#include <cstddef>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "array_io.hpp"
#include "npy_collective_io.hpp"
#include "rank_shares.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::cli {

/// Who reads and writes the .npy arrays of a command across ranks: rank 0 alone (scatter and
/// gather) or every rank its own share (npy_collective_io.hpp).
enum class IoMode { root, collective };
/// "root" or "collective" (the values of --io); throws rpyfmm::Error (invalid_argument) otherwise.
IoMode io_mode(const std::string& name);

/// One input array: its shape on every rank, this rank's share of its values, and the global index
/// of the share's first value.
struct ArrayShare {
  std::vector<std::size_t> shape;
  std::vector<double> local;
  std::size_t first = 0;
};

/// The number of values of `shape`.
std::size_t values_of(const std::vector<std::size_t>& shape);

/// Collective: reads `path`, checks its shape with `check` on rank 0 (which throws the serial
/// command's message), and hands each rank its share of P contiguous shares of rows of `per` values
/// (rank_shares.hpp's shares_of). Time spent scattering is added to `scatter_seconds`.
ArrayShare read_share(const std::string& path, IoMode mode, int per,
                      const std::function<void(const std::vector<std::size_t>&)>& check, double& scatter_seconds,
                      const mpi::Communicator& comm);

/// read_share with each rank's share given by `shares_for(shape)` (entries of values, as Shares
/// counts them; called on every rank after the check, collective, agreeing its own failures) in
/// place of P balanced shares: e.g. whole bodies (body_shares.hpp).
ArrayShare read_share_in(const std::string& path, IoMode mode,
                         const std::function<void(const std::vector<std::size_t>&)>& check,
                         const std::function<Shares(const std::vector<std::size_t>&)>& shares_for,
                         double& scatter_seconds, const mpi::Communicator& comm);

/// Collective: rank 0 reads `path` whole with read_array into `whole` (untouched elsewhere); returns
/// its shape on every rank. Rank 0's errors fail every rank.
std::vector<std::size_t> read_whole_on_root(const std::string& path, Array& whole, const mpi::Communicator& comm);

/// Collective: N points read into shares of rows of three with as_points' checks and messages
/// naming `name` (the shape on rank 0, the values on every rank's share).
ArrayShare read_points_share(const std::string& path, const std::string& name, IoMode mode, double& scatter_seconds,
                             const mpi::Communicator& comm);

/// Collective: as_points' or as_vector's check of `share`'s values (rows of `stride` values), its
/// message naming `name` and the first non-finite entry by global index.
void require_finite_entries(const ArrayShare& share, const std::string& name, std::size_t stride,
                            const mpi::Communicator& comm);

/// Collective: where any rank's `local` (values first, first + 1, ... of the whole array) holds a
/// value that is not finite, every rank throws rank 0's `error(index, nan)` for the first such
/// value by global index: the serial check's message. One MPI_Allreduce when all are finite.
void require_finite_share(std::span<const double> local, std::size_t first,
                          const std::function<Error(std::size_t index, bool nan)>& error,
                          const mpi::Communicator& comm);

/// Collective: require_finite_share over runs of values (every rank its own runs, any number):
/// the first non-finite value by global index over all of them. One MPI_Allreduce when all are
/// finite.
void require_finite_runs(std::span<const NpyRun> runs, const std::function<Error(std::size_t index, bool nan)>& error,
                         const mpi::Communicator& comm);

}  // namespace rpyfmm::cli
