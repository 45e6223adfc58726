// rpyfmm CLI — a build without MPI: no run is under MPI, so `laplace` never runs across ranks
// (laplace_across_ranks.hpp, mpi_session.hpp).
#include "laplace_across_ranks.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {

void run_laplace_across_ranks(const RanksLaplaceArgs&) {
  fail(ErrorCode::not_supported, "laplace", "this rpyfmm was built without MPI");
}

}  // namespace rpyfmm::cli
