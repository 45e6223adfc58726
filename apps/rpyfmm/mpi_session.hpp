// rpyfmm CLI — running under an MPI launcher (docs/mpi.md, "The command-line tool").
//
// MPI starts only where a launcher (mpirun, mpiexec, srun) started this process, recognised by
// the variables it sets, or where `rpyfmm --mpi ...` asks for it, and only in a build with MPI
// (RPYFMM_USE_MPI). Everywhere else the tool runs exactly as without MPI. A build without MPI
// refuses --mpi and a launch on more than one process, with one line and exit status 2, rather
// than running the same serial command P times over the same output file.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/rpy/sqrt.hpp"

namespace CLI {
class App;
}

namespace rpyfmm::cli {

/// The number of processes a launcher started this one among: OMPI_COMM_WORLD_SIZE (Open MPI),
/// PMI_SIZE (MPICH, Slurm), 1 where only PMIX_RANK says a launcher started it; 0 without one.
int launcher_world_size();

/// Adds the top-level flag --mpi: start MPI without a launcher (a single rank).
void add_mpi_flag(CLI::App& app);
/// True when --mpi was given (after parsing).
bool mpi_flag_given();

/// True when this run is under MPI. The first call starts MPI (MPI_Init_thread at
/// MPI_THREAD_FUNNELED) where a launcher started this process or --mpi was given. Throws
/// rpyfmm::Error (not_supported) in a build without MPI where --mpi was given or a launcher
/// started more than one process.
bool under_mpi();
/// This process's rank in MPI_COMM_WORLD and the number of ranks (0 and 1 unless under_mpi()).
int mpi_rank();
int mpi_size();

/// Called first by the commands that do not run across ranks: throws rpyfmm::Error
/// (not_supported) naming `command` when the run is under MPI on more than one rank.
void require_one_rank(const std::string& command);

/// Ends MPI (MPI_Finalize) when under_mpi() started it: one object in main() outlives the command.
class MpiSessionEnd {
 public:
  MpiSessionEnd() = default;
  ~MpiSessionEnd();
  MpiSessionEnd(const MpiSessionEnd&) = delete;
  MpiSessionEnd& operator=(const MpiSessionEnd&) = delete;
};

/// `rpyfmm mobility --method direct|fmm` or `--method pse --box ...` across the ranks
/// (commands_across_ranks.cpp, builds with MPI): the ranks read the files in contiguous shares of
/// the particles (`io`: every rank its share of a .npy file, or rank 0 all and scatters),
/// rpyfmm::mpi::DistributedDirectRpy, DistributedFmmRpy or DistributedPseRpy applies M, the ranks
/// write U (every rank its rows, or rank 0 after a gather). direct: bit for bit the serial command's output; fmm:
/// within the tolerance of the exact product; pse: the serial output with --wave-precision double to round-off
/// (docs/mpi.md). With --torques or --angular [U; W] = M [F; T], written as the serial command's (N,6) rows Ux Uy Uz Wx
/// Wy Wz; direct: the serial output to round-off (rpyfmm/mpi/direct_operator.hpp), fmm: U and W each within the
/// tolerance of the exact product, pse: U and W each the serial output with --wave-precision double to round-off.
struct RanksMobilityArgs {
  std::string positions, forces, radii, out;
  std::string torques;   // (N,3) torques; empty: none read
  bool angular = false;  // [U; W] with T = 0 unless torques are read
  double radius = 0.0;
  bool radius_given = false;
  double viscosity = 1.0;
  double tolerance = 0.0;
  bool json = false;
  std::string method = "direct";  // direct | fmm | pse
  std::vector<double> box;        // pse: L or Lx Ly Lz
  std::string io = "collective";  // --io: root | collective (array_shares.hpp)
};
void run_mobility_across_ranks(const RanksMobilityArgs& args);

/// `rpyfmm sample --operator direct|fmm` with Lanczos, or `--operator pse --box ...` with the split
/// sampler (DistributedPseRpy::apply_sqrt: the serial output with --wave-precision double to
/// round-off), across the ranks (commands_across_ranks.cpp):
/// the ranks read the files (and --noise) as mobility does, or each rank draws its share's noise
/// (rpyfmm::mpi::fill_normal: the serial noise), rpyfmm::mpi::sqrt_apply samples, the ranks write
/// W as mobility does. With the direct operator bit for bit the serial command's output; with the
/// FMM the square root of the FMM product (docs/mpi.md). With --angular the grand mobility's
/// sampler (rows w_t then w_r), keyed and laid out as the serial command's.
struct RanksSampleArgs {
  std::string positions, radii, noise, out;
  double radius = 0.0;
  bool radius_given = false;
  double viscosity = 1.0;
  std::uint64_t seed = 0, step = 0;
  rpy::SqrtOptions options;
  bool json = false;
  std::string op = "direct";      // direct | fmm | pse (the split sampler)
  std::vector<double> box;        // pse: L or Lx Ly Lz
  double tolerance = 0.0;         // fmm, pse: the operator's tolerance (0: its options' default)
  bool angular = false;           // the grand mobility with rotation: (N,6) noise and output
  std::string io = "collective";  // --io: root | collective (array_shares.hpp)
};
void run_sample_across_ranks(const RanksSampleArgs& args);
/// `rpyfmm bd` across the ranks (commands_across_ranks.cpp): `options` with the engine across the
/// ranks (rpyfmm::mpi::across_ranks: DistributedBd takes the steps, rank 0 writes the files).
bd::RunOptions bd_options_across_ranks(bd::RunOptions options);

}  // namespace rpyfmm::cli
