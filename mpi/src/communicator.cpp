// rpyfmm — Communicator: rank, size and collective error agreement (communicator.hpp).
#include "rpyfmm/mpi/communicator.hpp"

#include <array>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi {
namespace {

// The longest message broadcast by agree(); longer ones are cut (with "...").
constexpr std::size_t kMaxMessage = 4096;

}  // namespace

void check_mpi(int rc, const char* call) {
  if (rc == MPI_SUCCESS) return;
  std::array<char, MPI_MAX_ERROR_STRING> text{};
  int length = 0;
  if (MPI_Error_string(rc, text.data(), &length) != MPI_SUCCESS) length = 0;
  fail(ErrorCode::io_error, call, "MPI error " + std::to_string(rc) + " (" + std::string(text.data(), length) + ")");
}

Communicator::Communicator(MPI_Comm comm) : comm_(comm) {
  const char* where = "rpyfmm::mpi::Communicator";
  int initialized = 0, finalized = 0;
  check_mpi(MPI_Initialized(&initialized), "MPI_Initialized");
  check_mpi(MPI_Finalized(&finalized), "MPI_Finalized");
  require(initialized != 0 && finalized == 0, ErrorCode::invalid_argument, where,
          "MPI is not initialized or already finalized (call MPI_Init first)");
  require(comm != MPI_COMM_NULL, ErrorCode::invalid_argument, where, "the communicator is MPI_COMM_NULL");
  int inter = 0;
  check_mpi(MPI_Comm_test_inter(comm, &inter), "MPI_Comm_test_inter");
  require(inter == 0, ErrorCode::invalid_argument, where, "inter-communicators are not supported");
  check_mpi(MPI_Comm_rank(comm, &rank_), "MPI_Comm_rank");
  check_mpi(MPI_Comm_size(comm, &size_), "MPI_Comm_size");
}

void Communicator::agree(const std::optional<Error>& local_problem) const {
  // How many ranks failed: the only collective when none did.
  const int mine = local_problem ? 1 : 0;
  int failed = 0;
  check_mpi(MPI_Allreduce(&mine, &failed, 1, MPI_INT, MPI_SUM, comm_), "MPI_Allreduce");
  if (failed == 0) return;
  // The lowest failing rank tells every rank its code and message.
  const int candidate = local_problem ? rank_ : size_;
  int first = 0;
  check_mpi(MPI_Allreduce(&candidate, &first, 1, MPI_INT, MPI_MIN, comm_), "MPI_Allreduce");
  std::string message;
  std::array<int, 2> header{};  // code, message length
  if (rank_ == first) {
    message = local_problem->what();
    if (message.size() > kMaxMessage) message = message.substr(0, kMaxMessage - 3) + "...";
    header = {static_cast<int>(local_problem->code()), static_cast<int>(message.size())};
  }
  check_mpi(MPI_Bcast(header.data(), 2, MPI_INT, first, comm_), "MPI_Bcast");
  message.resize(static_cast<std::size_t>(header[1]));
  check_mpi(MPI_Bcast(message.data(), header[1], MPI_CHAR, first, comm_), "MPI_Bcast");
  std::string text = "rank " + std::to_string(first) + " of " + std::to_string(size_) + ": " + message;
  if (failed == size_ && size_ > 1) {
    text += " (all " + std::to_string(size_) + " ranks failed)";
  } else if (failed > 1) {
    text += " (" + std::to_string(failed - 1) + (failed == 2 ? " other rank" : " other ranks") + " failed too)";
  }
  throw Error(static_cast<ErrorCode>(header[0]), text);
}

bool same_on_every_rank(const Communicator& comm, std::vector<double> values) {
  const std::size_t n = values.size();
  for (std::size_t i = 0; i < n; ++i) values.push_back(-values[i]);
  std::vector<double> seen(values.size());
  check_mpi(MPI_Allreduce(values.data(), seen.data(), static_cast<int>(values.size()), MPI_DOUBLE, MPI_MIN, comm.get()),
            "MPI_Allreduce");
  for (std::size_t i = 0; i < n; ++i) {
    if (seen[i] != -seen[n + i]) return false;
  }
  return true;
}

}  // namespace rpyfmm::mpi
