// rpyfmm CLI — a build without MPI: no run is under MPI, so `rigid` never runs across ranks
// (rigid_across_ranks.hpp, mpi_session.hpp).
#include "rigid_across_ranks.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

void run_rigid_across_ranks(const RanksRigidArgs&) {
  fail(ErrorCode::not_supported, "rigid", "this rpyfmm was built without MPI");
}

}  // namespace rpyfmm::cli
