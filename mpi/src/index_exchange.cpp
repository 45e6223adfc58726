// rpyfmm — particle values sent by fixed lists and back (index_exchange.hpp).
#include "index_exchange.hpp"

#include <mpi.h>

#include "alltoallv.hpp"

namespace rpyfmm::mpi::detail {
namespace {

// Runs the exchange `body`, adding its wall time to `traffic`.
template <class Body>
std::vector<double> timed_exchange(IndexExchange::Traffic& traffic, Body&& body) {
  const double start = MPI_Wtime();
  std::vector<double> received = body();
  traffic.seconds += MPI_Wtime() - start;
  return received;
}

// The bytes of `width` values per particle from every rank but `self`.
template <class Count>
std::uint64_t bytes_from_others(std::size_t ranks, int self, std::size_t width, Count&& particles_from) {
  std::uint64_t bytes = 0;
  for (std::size_t r = 0; r < ranks; ++r)
    if (static_cast<int>(r) != self) bytes += width * particles_from(r) * sizeof(double);
  return bytes;
}

}  // namespace

std::vector<double> IndexExchange::forward(const Communicator& comm, const double* values, std::size_t width,
                                           const char* where, const char* what) {
  std::vector<std::vector<double>> packed(send.size());
  for (std::size_t r = 0; r < send.size(); ++r) {
    packed[r].reserve(width * send[r].size());
    for (const std::uint32_t i : send[r])
      packed[r].insert(packed[r].end(), values + width * i, values + width * (i + 1));
  }
  std::vector<double> received;
  if (recv_counts.empty()) {
    received = timed_exchange(traffic, [&] { return alltoallv(comm, packed, where, what, &recv_counts); });
    for (std::size_t& count : recv_counts) count /= width;
  } else {
    std::vector<std::size_t> counts(recv_counts);
    for (std::size_t& count : counts) count *= width;
    received = timed_exchange(traffic, [&] { return alltoallv(comm, packed, counts, where, what); });
  }
  traffic.bytes_received +=
      bytes_from_others(recv_counts.size(), self, width, [&](std::size_t r) { return recv_counts[r]; });
  return received;
}

std::vector<double> IndexExchange::backward(const Communicator& comm, const std::vector<double>& values,
                                            std::size_t width, const char* where, const char* what) const {
  std::vector<std::vector<double>> packed(recv_counts.size());
  std::size_t at = 0;
  for (std::size_t r = 0; r < recv_counts.size(); ++r) {
    packed[r].assign(values.begin() + static_cast<std::ptrdiff_t>(at),
                     values.begin() + static_cast<std::ptrdiff_t>(at + width * recv_counts[r]));
    at += width * recv_counts[r];
  }
  std::vector<std::size_t> counts(send.size());
  for (std::size_t r = 0; r < send.size(); ++r) counts[r] = width * send[r].size();
  std::vector<double> received = timed_exchange(traffic, [&] { return alltoallv(comm, packed, counts, where, what); });
  traffic.bytes_received += bytes_from_others(send.size(), self, width, [&](std::size_t r) { return send[r].size(); });
  return received;
}

std::size_t IndexExchange::sent() const {
  std::size_t n = 0;
  for (std::size_t r = 0; r < send.size(); ++r)
    if (static_cast<int>(r) != self) n += send[r].size();
  return n;
}

std::size_t IndexExchange::received() const {
  std::size_t n = 0;
  for (std::size_t r = 0; r < recv_counts.size(); ++r)
    if (static_cast<int>(r) != self) n += recv_counts[r];
  return n;
}

}  // namespace rpyfmm::mpi::detail
