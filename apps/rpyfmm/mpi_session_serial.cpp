// rpyfmm CLI — a build without MPI (RPYFMM_USE_MPI off): no run is under MPI, and a launch on
// several processes or --mpi is refused (mpi_session.hpp).
#include <string>

#include "mpi_session.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

bool under_mpi() {
  require(!mpi_flag_given(), ErrorCode::not_supported, "--mpi",
          "this rpyfmm was built without MPI (configure with -DRPYFMM_USE_MPI=ON and an MPI installation)");
  const int launched = launcher_world_size();
  require(launched <= 1, ErrorCode::not_supported, "mpirun",
          "started this rpyfmm on " + std::to_string(launched) +
              " processes, but it was built without MPI (RPYFMM_USE_MPI=OFF): run it without mpirun, or build it "
              "with MPI");
  return false;
}

int mpi_rank() {
  return 0;
}
int mpi_size() {
  return 1;
}

MpiSessionEnd::~MpiSessionEnd() = default;

void run_mobility_across_ranks(const RanksMobilityArgs&) {
  fail(ErrorCode::not_supported, "mobility", "this rpyfmm was built without MPI");
}

void run_sample_across_ranks(const RanksSampleArgs&) {
  fail(ErrorCode::not_supported, "sample", "this rpyfmm was built without MPI");
}

bd::RunOptions bd_options_across_ranks(bd::RunOptions) {
  fail(ErrorCode::not_supported, "bd", "this rpyfmm was built without MPI");
}

}  // namespace rpyfmm::cli
