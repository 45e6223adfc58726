// rpyfmm CLI — a build without MPI: no run is under MPI, so `rigid-bd` never runs across ranks
// (rigid_bd_across_ranks.hpp, mpi_session.hpp).
#include "rigid_bd_across_ranks.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

void run_rigid_bd_across_ranks(const RanksRigidBdArgs&) {
  fail(ErrorCode::not_supported, "rigid-bd", "this rpyfmm was built without MPI");
}

}  // namespace rpyfmm::cli
