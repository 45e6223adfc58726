// rpyfmm CLI — what every build knows of MPI launchers (mpi_session.hpp).
#include <CLI/CLI.hpp>
#include <cstdlib>
#include <string>

#include "mpi_session.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::cli {
namespace {

// A positive count from the environment variable `name`, or 0.
int count_from(const char* name) {
  const char* value = std::getenv(name);
  if (value == nullptr || *value == '\0') return 0;
  char* end = nullptr;
  const long n = std::strtol(value, &end, 10);
  return *end == '\0' && n > 0 && n < (1L << 30) ? static_cast<int>(n) : 0;
}

bool flag_given = false;  // --mpi

}  // namespace

bool mpi_flag_given() {
  return flag_given;
}

int launcher_world_size() {
  if (const int n = count_from("OMPI_COMM_WORLD_SIZE"); n > 0) return n;
  if (const int n = count_from("PMI_SIZE"); n > 0) return n;
  return std::getenv("PMIX_RANK") != nullptr ? 1 : 0;
}

void add_mpi_flag(CLI::App& app) {
  app.add_flag("--mpi", flag_given,
               "start MPI without a launcher (one rank); under mpirun/mpiexec MPI starts by itself (builds with MPI; "
               "laplace, mobility, sample, bd and rigid run across the ranks with the methods docs/mpi.md lists, other "
               "commands on one rank only)");
}

void require_one_rank(const std::string& command) {
  if (!under_mpi() || mpi_size() == 1) return;
  fail(ErrorCode::not_supported, command,
       "does not run across MPI ranks yet (" + std::to_string(mpi_size()) +
           " ranks); run it without mpirun, or with one rank (docs/mpi.md: laplace, mobility, sample, bd and rigid "
           "run across ranks)");
}

}  // namespace rpyfmm::cli
