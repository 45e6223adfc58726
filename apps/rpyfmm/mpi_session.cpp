// rpyfmm CLI — a build with MPI: MPI starts where a launcher started the process or --mpi asks
// for it (mpi_session.hpp).
#include "mpi_session.hpp"

#include <mpi.h>

#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {
namespace {

bool started = false;  // by under_mpi(), so ended by MpiSessionEnd

}  // namespace

bool under_mpi() {
  int initialized = 0;
  MPI_Initialized(&initialized);
  if (initialized != 0) return true;
  if (launcher_world_size() == 0 && !mpi_flag_given()) return false;
  // Every MPI call of rpyfmm comes from this thread, outside OpenMP regions (docs/mpi.md).
  int provided = 0;
  require(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided) == MPI_SUCCESS, ErrorCode::io_error,
          "MPI_Init_thread", "failed");
  started = true;
  require(provided >= MPI_THREAD_FUNNELED, ErrorCode::not_supported, "MPI_Init_thread",
          "the MPI library offers no MPI_THREAD_FUNNELED (OpenMP threads inside each rank need it)");
  return true;
}

int mpi_rank() {
  int initialized = 0, rank = 0;
  MPI_Initialized(&initialized);
  if (initialized != 0) MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  return rank;
}

int mpi_size() {
  int initialized = 0, size = 1;
  MPI_Initialized(&initialized);
  if (initialized != 0) MPI_Comm_size(MPI_COMM_WORLD, &size);
  return size;
}

MpiSessionEnd::~MpiSessionEnd() {
  int finalized = 0;
  MPI_Finalized(&finalized);
  if (started && finalized == 0) MPI_Finalize();
}

}  // namespace rpyfmm::cli
