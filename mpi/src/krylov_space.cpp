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

// s[q] continued over entries [lo, hi) of x_q . y_q, as kernels.cpp sums a chunk.
void continue_sums(std::size_t k, const double* const* x, const double* const* y, std::size_t lo, std::size_t hi,
                   double* s) {
  for (std::size_t q = 0; q < k; ++q) {
    double sum = s[q];
    const double* xq = x[q];
    const double* yq = y[q];
    for (std::size_t i = lo; i < hi; ++i) sum += xq[i] * yq[i];
    s[q] = sum;
  }
}

}  // namespace

DistributedKrylovSpace::DistributedKrylovSpace(const Communicator& comm, std::span<const std::size_t> counts,
                                               std::size_t segments)
    : comm_(comm), local_(3 * segments * counts[static_cast<std::size_t>(comm.rank())]) {
  // Every nonempty share in global order: segment after segment, rank after rank.
  struct Piece {
    int owner;
    std::size_t global, n;
  };
  std::vector<Piece> pieces;
  for (std::size_t s = 0; s < segments; ++s) {
    for (std::size_t r = 0; r < counts.size(); ++r) {
      const std::size_t n = 3 * counts[r];
      if (n > 0) pieces.push_back({static_cast<int>(r), total_, n});
      total_ += n;
    }
  }
  std::size_t local = 0;
  for (std::size_t p = 0; p < pieces.size(); ++p) {
    if (pieces[p].owner != comm.rank()) continue;
    shares_.push_back({pieces[p].global, local, pieces[p].n, p > 0 ? pieces[p - 1].owner : -1,
                       p + 1 < pieces.size() ? pieces[p + 1].owner : -1});
    local += pieces[p].n;
  }
  // A chunk ends on the rank that holds its last entry; the gathered sums come rank after rank,
  // each rank's in chunk order.
  std::vector<int> owner;
  finished_.assign(counts.size(), 0);
  for (std::size_t c = 0, p = 0; c * kChunk < total_; ++c) {
    const std::size_t last = std::min(total_, (c + 1) * kChunk) - 1;
    while (last >= pieces[p].global + pieces[p].n) ++p;
    owner.push_back(pieces[p].owner);
    ++finished_[static_cast<std::size_t>(pieces[p].owner)];
  }
  std::vector<std::size_t> next_slot(counts.size(), 0);
  for (std::size_t r = 1; r < counts.size(); ++r)
    next_slot[r] = next_slot[r - 1] + static_cast<std::size_t>(finished_[r - 1]);
  for (int r : owner) chunk_slot_.push_back(next_slot[static_cast<std::size_t>(r)]++);
}

std::vector<double> DistributedKrylovSpace::chunk_sums(std::size_t k, const double* const* x, const double* const* y) {
  std::vector<double> mine;
  std::vector<std::vector<double>> sent;  // at most one per share
  std::vector<MPI_Request> sends;
  sent.reserve(shares_.size());
  for (const Share& share : shares_) share_sums(share, k, x, y, mine, sent, sends);
  timed([&] {
    check_mpi(MPI_Waitall(static_cast<int>(sends.size()), sends.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
  });
  return mine;
}

void DistributedKrylovSpace::share_sums(const Share& share, std::size_t k, const double* const* x,
                                        const double* const* y, std::vector<double>& mine,
                                        std::vector<std::vector<double>>& sent, std::vector<MPI_Request>& sends) {
  const std::size_t end = share.global + share.n;
  const std::size_t first = share.global / kChunk, last = (end - 1) / kChunk;
  const bool started_before = share.global % kChunk != 0;  // the first chunk began in the previous share
  const bool goes_on = end % kChunk != 0 && end < total_;  // the last chunk goes on in the next share
  // The last chunk first where it needs nothing from the previous share: its sum leaves early.
  const bool early = goes_on && !(started_before && first == last);
  const auto range = [&](std::size_t c) {  // this share's entries of chunk c, local indices
    return std::array<std::size_t, 2>{share.local + std::max(share.global, c * kChunk) - share.global,
                                      share.local + std::min(end, (c + 1) * kChunk) - share.global};
  };
  const auto pass_on = [&](const std::vector<double>& s) {
    sent.push_back(s);
    sends.push_back(MPI_REQUEST_NULL);
    timed([&] {
      check_mpi(
          MPI_Isend(sent.back().data(), static_cast<int>(k), MPI_DOUBLE, share.next, kTag, comm_.get(), &sends.back()),
          "MPI_Isend");
    });
  };
  std::vector<double> s(k);
  if (early) {
    const auto [lo, hi] = range(last);
    continue_sums(k, x, y, lo, hi, s.data());
    pass_on(s);
  }
  for (std::size_t c = first; c <= last; ++c) {
    if (c == last && early) break;  // passed on above
    std::fill(s.begin(), s.end(), 0.0);
    if (c == first && started_before) {
      timed([&] {
        check_mpi(
            MPI_Recv(s.data(), static_cast<int>(k), MPI_DOUBLE, share.previous, kTag, comm_.get(), MPI_STATUS_IGNORE),
            "MPI_Recv");
      });
    }
    const auto [lo, hi] = range(c);
    continue_sums(k, x, y, lo, hi, s.data());
    if (c == last && goes_on) {  // a chunk passing through this share
      pass_on(s);
    } else {
      mine.insert(mine.end(), s.begin(), s.end());
    }
  }
}

void DistributedKrylovSpace::sum_chunks(std::size_t k, const std::vector<double>& mine, bool always_fold, double* out) {
  if (k == 0) return;
  ++exchanges_;
  const auto ranks = finished_.size();
  std::vector<int> counts(ranks), displs(ranks);
  int total = 0;
  for (std::size_t r = 0; r < ranks; ++r) {
    counts[r] = finished_[r] * static_cast<int>(k);
    displs[r] = total;
    total += counts[r];
  }
  std::vector<double> all(static_cast<std::size_t>(total));
  timed([&] {
    check_mpi(MPI_Allgatherv(mine.data(), static_cast<int>(mine.size()), MPI_DOUBLE, all.data(), counts.data(),
                             displs.data(), MPI_DOUBLE, comm_.get()),
              "MPI_Allgatherv");
  });
  const std::size_t chunks = chunk_slot_.size();
  for (std::size_t q = 0; q < k; ++q) {
    if (chunks == 1 && !always_fold) {
      out[q] = all[q];
      continue;
    }
    double s = 0.0;
    for (std::size_t c = 0; c < chunks; ++c) s += all[chunk_slot_[c] * k + q];
    out[q] = s;
  }
}

double DistributedKrylovSpace::dot(const double* x, const double* y) {
  double out = 0.0;
  sum_chunks(1, chunk_sums(1, &x, &y), false, &out);
  return out;
}

void DistributedKrylovSpace::dots(std::size_t k, const double* y, double* h) {
  std::vector<const double*> v(k);
  for (std::size_t q = 0; q < k; ++q) v[q] = local_.vector(q);
  const std::vector<const double*> ys(k, y);
  sum_chunks(k, chunk_sums(k, v.data(), ys.data()), true, h);
}

void DistributedKrylovSpace::pair_dots(std::size_t k, const double* const* x, const double* const* y, double* out) {
  // Folded always, as dots: a chunk sum starts from +0.0 and so is never -0.0, and 0.0 + s is s
  // bit for bit, so a single chunk's value is also dot's.
  sum_chunks(k, chunk_sums(k, x, y), true, out);
}

void DistributedKrylovSpace::require_finite(const double* y, const char* where, long long product) {
  comm_.run([&] { local_.require_finite(y, where, product); });
}

}  // namespace rpyfmm::mpi
