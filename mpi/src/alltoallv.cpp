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

}  // namespace

std::vector<double> alltoallv(const Communicator& comm, const std::vector<std::vector<double>>& send,
                              std::span<const std::size_t> recv_counts, const char* where, const char* what) {
  std::vector<std::size_t> send_counts(send.size());
  for (std::size_t r = 0; r < send.size(); ++r) send_counts[r] = send[r].size();
  std::vector<int> sc, sd, rc, rd;
  comm.run([&] {
    sc = int_counts(send_counts, sd, where, what);
    rc = int_counts(recv_counts, rd, where, what);
  });
  std::vector<double> packed(static_cast<std::size_t>(sd.empty() ? 0 : sd.back() + sc.back()));
  for (std::size_t r = 0; r < send.size(); ++r) std::copy(send[r].begin(), send[r].end(), packed.begin() + sd[r]);
  std::vector<double> received(static_cast<std::size_t>(rd.empty() ? 0 : rd.back() + rc.back()));
  check_mpi(MPI_Alltoallv(packed.data(), sc.data(), sd.data(), MPI_DOUBLE, received.data(), rc.data(), rd.data(),
                          MPI_DOUBLE, comm.get()),
            "MPI_Alltoallv");
  return received;
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
