// rpyfmm CLI — `mpirun -np P rpyfmm laplace (--tolerance E | --direct) ...` across MPI ranks
// (docs/mpi.md, "The command-line tool under mpirun"). With --tolerance the ranks read contiguous
// shares of the sources, the targets and every density's charges (array_shares.hpp: every rank its
// shares of a .npy file with --io collective, rank 0 reads and scatters with --io root);
// rpyfmm::mpi::DistributedLaplaceFmm plans and evaluates on the shares. The results meet the serial
// FMM's tolerance contract, not its bits. With --direct every rank needs every source and charge:
// with --io collective every rank reads its shares as above and gathers the sources and charges
// (MPI_Allgatherv), with --io root rank 0 reads the files of the serial command, broadcasts the
// sources and charges and scatters the targets; each rank keeps its share of the targets (of the
// sources when there are no targets) and sums fmm::laplace_direct over all sources at its targets, each target in the
// serial order, so the file is the serial command's byte for byte. Either way the ranks write the serial command's file
// (a temporary file renamed into place): with --io collective every rank its rows of each density
// (npy_collective_io.hpp), with --io root rank 0 after a gather (write_npy).
#pragma once

#include <string>

namespace rpyfmm::cli {

struct RanksLaplaceArgs {
  std::string sources, targets, charges, out;  // targets empty: at the sources
  double tolerance = 0.0;                      // the FMM's relative tolerance, validated (not with direct)
  bool direct = false;                         // exact direct sums instead of the FMM
  bool json = false;
  std::string io = "collective";  // --io: who reads the inputs and writes the result (array_shares.hpp)
};

/// Collective over MPI_COMM_WORLD; fails on every rank alike (rpyfmm::mpi::Communicator). A build
/// without MPI throws rpyfmm::Error (not_supported).
void run_laplace_across_ranks(const RanksLaplaceArgs& args);

}  // namespace rpyfmm::cli
