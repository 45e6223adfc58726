// rpyfmm CLI — the .npy files of `rigid` and `rigid-bd` across MPI ranks (docs/mpi.md, "The
// command-line tool under mpirun"): each rank's whole bodies (body_shares.hpp) read with --io
// (array_shares.hpp: every rank its rows of a .npy file with MPI-IO, or rank 0 reads and scatters),
// and rows per body or per bead written by every rank (npy_collective_io.hpp) or gathered by rank 0.
// Rank 0 reads --body-sizes whole (every rank holds the m + 1 body offsets), then the per-bead and
// per-body files are read in the bodies' shares, so no body is split between ranks.
#pragma once

#include <cstddef>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "array_shares.hpp"
#include "bead_bodies.hpp"
#include "body_shares.hpp"
#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::cli {

/// This rank's whole bodies (offsets from 0, reference points empty without --reference) and every
/// rank's layout.
struct BodiesShare {
  BodyLayout z;
  BeadBodies local;
  bool reference = false;        // --reference was given
  double scatter_seconds = 0.0;  // rank 0's scatters (--io root, text inputs)
};

/// Collective: read_bead_bodies' files and checks with its messages, in the bodies' shares. The
/// shapes and counts are checked before the values of each file, and --body-sizes before the
/// values of --positions; a failure of any rank fails every rank.
BodiesShare read_bodies_share(const BeadBodyArgs& args, IoMode mode, const mpi::Communicator& comm);

/// Where this rank's rows start in the whole array: the global index of its first value, `per`
/// values per body (by_beads false) or per bead.
std::size_t first_of_rows(const BodyLayout& z, int per, bool by_beads, int rank);

/// Collective: this rank's rows (`per` values per body or per bead) of `path`, after rank 0's
/// `check` of the shape; the values [skip, skip + whole array) of the file (skip: e.g. the frames
/// before a trajectory's last).
ArrayShare read_body_rows(const std::string& path, IoMode mode, int per, bool by_beads,
                          const std::function<void(const std::vector<std::size_t>&)>& check,
                          const std::function<std::size_t(const std::vector<std::size_t>&)>& skip,
                          const BodiesShare& bodies, double& scatter_seconds, const mpi::Communicator& comm);

/// Collective: require_finite_output's check of the whole result that is each rank's `runs`, its
/// message naming `what` and the first non-finite entry by global index.
void require_finite_result(std::span<const NpyRun> runs, const std::string& what, const mpi::Communicator& comm);

/// One output of write_rows_together: the float64 .npy of `shape` whose values are each rank's
/// `runs` (every rank passes as many runs), write_npy's file and rules: with --io collective every
/// rank writes its runs (write_npy_temporary_at_all), with --io root rank 0 after gathering each run
/// (MPI_Gatherv, `shares` the runs' counts and displacements within each run's block of `block`
/// values).
struct RowsFile {
  std::string path;
  std::vector<std::size_t> shape;
  std::span<const NpyRun> runs;
  Shares shares;
  std::size_t block = 0;
};

/// Collective: writes a command's outputs together: every file goes to its
/// temporary first, and only when all are on disk does rank 0 rename them over their targets, so
/// a failure while writing (a missing folder, a full disk) leaves every target as it was
/// (rpyfmm/core/atomic_file.hpp, write_files_atomically).
void write_rows_together(std::span<const RowsFile> files, IoMode mode, const mpi::Communicator& comm);

}  // namespace rpyfmm::cli
