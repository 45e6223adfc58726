// rpyfmm — the distributed Lanczos basis and its inner products, the serial ones bit for bit
// (krylov_space.hpp). Compiled with the project's usual flags, as rpy/src/sqrt/kernels.cpp is,
// so that `s += x[i] * y[i]` rounds here as it does there.
#include "krylov_space.hpp"

#include <mpi.h>

#include <algorithm>
#include <array>

#include "sqrt/detail.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr std::size_t kChunk = rpy::sqrt_detail::kReductionChunk;
constexpr int kTag = 0x4b52;  // the chain of a straddling chunk's sum (collectives do not match it)

// s[q] continued over entries [lo, hi) of x_q . y, as kernels.cpp sums a chunk.
void continue_sums(std::size_t k, const double* const* x, const double* y, std::size_t lo, std::size_t hi, double* s) {
  for (std::size_t q = 0; q < k; ++q) {
    double sum = s[q];
    const double* xq = x[q];
    for (std::size_t i = lo; i < hi; ++i) sum += xq[i] * y[i];
    s[q] = sum;
  }
}

}  // namespace

DistributedKrylovSpace::DistributedKrylovSpace(const Communicator& comm, std::span<const std::size_t> counts)
    : comm_(comm), local_(3 * counts[static_cast<std::size_t>(comm.rank())]) {
  const auto rank = static_cast<std::size_t>(comm.rank());
  finished_.assign(counts.size(), 0);
  std::size_t start = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    const std::size_t n = 3 * counts[r];
    if (r == rank) offset_ = start, local_n_ = n;
    if (n > 0 && r < rank) previous_ = static_cast<int>(r);
    if (n > 0 && r > rank && next_ < 0) next_ = static_cast<int>(r);
    start += n;
  }
  total_ = start;
  // A chunk ends on the rank that holds its last entry.
  for (std::size_t c = 0; c * kChunk < total_; ++c) {
    const std::size_t last = std::min(total_, (c + 1) * kChunk) - 1;
    std::size_t r = 0, end = 3 * counts[0];
    while (last >= end) end += 3 * counts[++r];
    ++finished_[r];
  }
}

std::vector<double> DistributedKrylovSpace::chunk_sums(std::size_t k, const double* const* x, const double* y) {
  std::vector<double> mine;
  if (local_n_ == 0) return mine;
  const std::size_t first = offset_ / kChunk, last = (offset_ + local_n_ - 1) / kChunk;
  const bool started_before = offset_ % kChunk != 0;  // the first chunk began on `previous_`
  const bool goes_on = (offset_ + local_n_) % kChunk != 0 && offset_ + local_n_ < total_;  // to `next_`
  std::vector<double> s(k), passed(k);
  MPI_Request send = MPI_REQUEST_NULL;
  const auto range = [&](std::size_t c) {  // this rank's entries of chunk c, local indices
    return std::array<std::size_t, 2>{std::max(offset_, c * kChunk) - offset_,
                                      std::min(offset_ + local_n_, (c + 1) * kChunk) - offset_};
  };
  const auto timed = [&](auto&& body) {
    const double t0 = MPI_Wtime();
    body();
    seconds_ += MPI_Wtime() - t0;
  };
  // The last chunk first where it needs nothing from `previous_`: its sum leaves early.
  if (goes_on && !(started_before && first == last)) {
    const auto [lo, hi] = range(last);
    std::fill(passed.begin(), passed.end(), 0.0);
    continue_sums(k, x, y, lo, hi, passed.data());
    timed([&] {
      check_mpi(MPI_Isend(passed.data(), static_cast<int>(k), MPI_DOUBLE, next_, kTag, comm_.get(), &send),
                "MPI_Isend");
    });
  }
  for (std::size_t c = first; c <= last; ++c) {
    if (c == last && goes_on && !(started_before && first == last)) break;  // sent above
    std::fill(s.begin(), s.end(), 0.0);
    if (c == first && started_before) {
      timed([&] {
        check_mpi(MPI_Recv(s.data(), static_cast<int>(k), MPI_DOUBLE, previous_, kTag, comm_.get(), MPI_STATUS_IGNORE),
                  "MPI_Recv");
      });
    }
    const auto [lo, hi] = range(c);
    continue_sums(k, x, y, lo, hi, s.data());
    if (c == last && goes_on) {  // a chunk passing through this rank
      passed = s;
      timed([&] {
        check_mpi(MPI_Isend(passed.data(), static_cast<int>(k), MPI_DOUBLE, next_, kTag, comm_.get(), &send),
                  "MPI_Isend");
      });
    } else {
      mine.insert(mine.end(), s.begin(), s.end());
    }
  }
  timed([&] { check_mpi(MPI_Wait(&send, MPI_STATUS_IGNORE), "MPI_Wait"); });
  return mine;
}

void DistributedKrylovSpace::sum_chunks(std::size_t k, const std::vector<double>& mine, bool always_fold, double* out) {
  if (k == 0) return;
  const auto ranks = finished_.size();
  std::vector<int> counts(ranks), displs(ranks);
  int total = 0;
  for (std::size_t r = 0; r < ranks; ++r) {
    counts[r] = finished_[r] * static_cast<int>(k);
    displs[r] = total;
    total += counts[r];
  }
  std::vector<double> all(static_cast<std::size_t>(total));
  const double t0 = MPI_Wtime();
  check_mpi(MPI_Allgatherv(mine.data(), static_cast<int>(mine.size()), MPI_DOUBLE, all.data(), counts.data(),
                           displs.data(), MPI_DOUBLE, comm_.get()),
            "MPI_Allgatherv");
  seconds_ += MPI_Wtime() - t0;
  const std::size_t chunks = all.size() / k;
  for (std::size_t q = 0; q < k; ++q) {
    if (chunks == 1 && !always_fold) {
      out[q] = all[q];
      continue;
    }
    double s = 0.0;
    for (std::size_t c = 0; c < chunks; ++c) s += all[c * k + q];
    out[q] = s;
  }
}

double DistributedKrylovSpace::dot(const double* x, const double* y) {
  double out = 0.0;
  sum_chunks(1, chunk_sums(1, &x, y), false, &out);
  return out;
}

void DistributedKrylovSpace::dots(std::size_t k, const double* y, double* h) {
  std::vector<const double*> v(k);
  for (std::size_t q = 0; q < k; ++q) v[q] = local_.vector(q);
  sum_chunks(k, chunk_sums(k, v.data(), y), true, h);
}

void DistributedKrylovSpace::require_finite(const double* y, const char* where, long long product) {
  comm_.run([&] { local_.require_finite(y, where, product); });
}

}  // namespace rpyfmm::mpi
