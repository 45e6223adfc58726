// rpyfmm CLI — `mpirun -np P rpyfmm laplace --tolerance E ...` across MPI ranks (docs/mpi.md,
// "The command-line tool under mpirun"). Rank 0 reads the files of the serial command and
// scatters contiguous shares of the sources, the targets and every density's charges;
// rpyfmm::mpi::DistributedLaplaceFmm plans and evaluates on the shares; rank 0 gathers the
// results and writes the serial command's file (write_npy: a temporary file renamed into place).
// The results meet the serial FMM's tolerance contract, not its bits (docs/mpi.md).
#pragma once

#include <string>

namespace rpyfmm::cli {

struct RanksLaplaceArgs {
  std::string sources, targets, charges, out;  // targets empty: at the sources
  double tolerance = 0.0;                      // the FMM's relative tolerance, validated
  bool json = false;
};

/// Collective over MPI_COMM_WORLD; fails on every rank alike (rpyfmm::mpi::Communicator). A build
/// without MPI throws rpyfmm::Error (not_supported).
void run_laplace_across_ranks(const RanksLaplaceArgs& args);

}  // namespace rpyfmm::cli
