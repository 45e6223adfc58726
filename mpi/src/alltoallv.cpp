// rpyfmm — one MPI_Alltoallv of doubles (alltoallv.hpp).
#include "alltoallv.hpp"

#include <algorithm>
#include <climits>
#include <cstdint>
#include <string>
#include <utility>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi::detail {
namespace {

// MPI's int counts and displacements (exclusive prefix sums); throws (not collective) beyond INT_MAX.
std::vector<int> int_counts(std::span<const std::size_t> counts, std::vector<int>& displs, const char* where,
                            const char* what) {
  std::vector<int> c(counts.size());
  displs.assign(counts.size(), 0);
  std::size_t sum = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    displs[r] = static_cast<int>(sum);
    c[r] = static_cast<int>(counts[r]);
    sum += counts[r];
    require(sum <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, where,
            std::string(what) + " exceed MPI's int counts");
  }
  return c;
}

// Collective: the int counts and displacements of an exchange, checked on every rank, and the
// packed send buffer.
std::vector<double> pack(const Communicator& comm, const std::vector<std::vector<double>>& send,
                         std::span<const std::size_t> recv_counts, const char* where, const char* what,
                         std::vector<int>& sc, std::vector<int>& sd, std::vector<int>& rc, std::vector<int>& rd) {
  std::vector<std::size_t> send_counts(send.size());
  for (std::size_t r = 0; r < send.size(); ++r) send_counts[r] = send[r].size();
  comm.run([&] {
    sc = int_counts(send_counts, sd, where, what);
    rc = int_counts(recv_counts, rd, where, what);
  });
  std::vector<double> packed(static_cast<std::size_t>(sd.empty() ? 0 : sd.back() + sc.back()));
  for (std::size_t r = 0; r < send.size(); ++r) std::copy(send[r].begin(), send[r].end(), packed.begin() + sd[r]);
  return packed;
}

std::size_t total(const std::vector<int>& counts, const std::vector<int>& displs) {
  return static_cast<std::size_t>(displs.empty() ? 0 : displs.back() + counts.back());
}

}  // namespace

std::vector<double> alltoallv(const Communicator& comm, const std::vector<std::vector<double>>& send,
                              std::span<const std::size_t> recv_counts, const char* where, const char* what) {
  std::vector<int> sc, sd, rc, rd;
  const std::vector<double> packed = pack(comm, send, recv_counts, where, what, sc, sd, rc, rd);
  std::vector<double> received(total(rc, rd));
  check_mpi(MPI_Alltoallv(packed.data(), sc.data(), sd.data(), MPI_DOUBLE, received.data(), rc.data(), rd.data(),
                          MPI_DOUBLE, comm.get()),
            "MPI_Alltoallv");
  return received;
}

PendingAlltoallv::PendingAlltoallv(const Communicator& comm, const std::vector<std::vector<double>>& send,
                                   std::span<const std::size_t> recv_counts, const char* where, const char* what)
    : packed_(pack(comm, send, recv_counts, where, what, send_counts_, send_displs_, recv_counts_, recv_displs_)),
      received_(total(recv_counts_, recv_displs_)) {
  check_mpi(MPI_Ialltoallv(packed_.data(), send_counts_.data(), send_displs_.data(), MPI_DOUBLE, received_.data(),
                           recv_counts_.data(), recv_displs_.data(), MPI_DOUBLE, comm.get(), &request_),
            "MPI_Ialltoallv");
}

PendingAlltoallv::~PendingAlltoallv() {
  if (request_ != MPI_REQUEST_NULL) MPI_Wait(&request_, MPI_STATUS_IGNORE);  // the buffers outlive the exchange
}

void PendingAlltoallv::test() {
  if (request_ == MPI_REQUEST_NULL) return;
  int done = 0;
  check_mpi(MPI_Test(&request_, &done, MPI_STATUS_IGNORE), "MPI_Test");
}

std::vector<double> PendingAlltoallv::wait() {
  check_mpi(MPI_Wait(&request_, MPI_STATUS_IGNORE), "MPI_Wait");
  return std::move(received_);
}

std::vector<double> alltoallv(const Communicator& comm, const std::vector<std::vector<double>>& send, const char* where,
                              const char* what, std::vector<std::size_t>* recv_counts) {
  std::vector<std::uint64_t> sent(send.size()), received(send.size());
  for (std::size_t r = 0; r < send.size(); ++r) sent[r] = send[r].size();
  check_mpi(MPI_Alltoall(sent.data(), 1, MPI_UINT64_T, received.data(), 1, MPI_UINT64_T, comm.get()), "MPI_Alltoall");
  std::vector<std::size_t> counts(received.begin(), received.end());
  std::vector<double> values = alltoallv(comm, send, counts, where, what);
  if (recv_counts != nullptr) *recv_counts = std::move(counts);
  return values;
}

}  // namespace rpyfmm::mpi::detail
