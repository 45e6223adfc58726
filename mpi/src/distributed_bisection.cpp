// rpyfmm — the block preconditioner's blocks by a distributed median bisection
// (distributed_bisection.hpp).
#include "distributed_bisection.hpp"

#include <mpi.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string>

#include "alltoallv.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/block_factors.hpp"

namespace rpyfmm::mpi::detail {
namespace {

constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
constexpr std::size_t kMemberValues = 6;  // index, block, position, radius

// A particle's place in the bisection's order along one axis (rpy::bisection_less).
struct Key {
  double x = 0.0;
  std::uint64_t g = 0;
};
bool operator<(const Key& a, const Key& b) {
  return rpy::bisection_less(a.x, a.g, b.x, b.g);
}

// A sample slot that a rank with fewer candidates leaves empty (no particle has this index: the
// total is below 2^53).
constexpr std::uint64_t kAbsent = std::numeric_limits<std::uint64_t>::max();
// The samples per rank and part in a selection round: more take fewer rounds (a factor of about
// kSamples fewer candidates per round) but more bytes per round; 4 measured the fewest bytes for
// a given time at N = 1e5 on 2 and 4 ranks (docs/mpi.md, "Brownian displacements").
constexpr std::size_t kSamples = 4;

// Collective: the checks every rank must pass before the first collective, and the total count.
std::uint64_t checked_total(const Communicator& comm, std::size_t offset, std::span<const double> positions,
                            std::span<const double> radii, const char* where) {
  const std::size_t n = radii.size();
  comm.run([&] {
    require(positions.size() == 3 * n, ErrorCode::invalid_argument, where,
            "positions hold " + std::to_string(positions.size()) + " values for " + std::to_string(n) + " radii");
    require(n <= std::numeric_limits<std::uint32_t>::max(), ErrorCode::not_supported, where,
            std::to_string(n) + " particles on one rank, more than 2^32 - 1");
  });
  std::uint64_t local = n, before = 0, total = 0;
  check_mpi(MPI_Exscan(&local, &before, 1, MPI_UINT64_T, MPI_SUM, comm.get()), "MPI_Exscan");
  if (comm.rank() == 0) before = 0;  // MPI_Exscan leaves rank 0's result undefined
  check_mpi(MPI_Allreduce(&local, &total, 1, MPI_UINT64_T, MPI_SUM, comm.get()), "MPI_Allreduce");
  comm.run([&] {
    require(before == offset, ErrorCode::invalid_argument, where,
            "the share starts at particle " + std::to_string(offset) + ", but the ranks before hold " +
                std::to_string(before));
    // The members' exchange carries global indices and block numbers as doubles.
    require(total < (std::uint64_t{1} << 53), ErrorCode::not_supported, where,
            std::to_string(total) + " particles, 2^53 or more");
  });
  return total;
}

// The bisection's state on one rank: the sizes of the parts of the current tree level in the
// blocks' order, and each local particle's part.
class Bisection {
 public:
  Bisection(const Communicator& comm, std::size_t offset, std::span<const double> positions, std::uint64_t total,
            std::size_t max_block)
      : comm_(comm), offset_(offset), x_(positions), label_(positions.size() / 3, 0), max_block_(max_block) {
    if (total > 0) sizes_.push_back(total);
  }

  // Collective: splits every part of more than max_block particles; false when none was left.
  bool split_level(DistributedBlocks& out) {
    std::vector<std::size_t> open, slot(sizes_.size(), kNone);
    for (std::size_t p = 0; p < sizes_.size(); ++p) {
      if (sizes_[p] > max_block_) {
        slot[p] = open.size();
        open.push_back(p);
      }
    }
    if (open.empty()) return false;
    std::vector<char> alone;  // held by one rank
    const std::vector<int> axes = widest_axes(slot, open, alone, out);
    const std::vector<Key> pivots = select_medians(slot, open, axes, alone, out);
    split(slot, axes, alone, pivots);
    ++out.levels;
    return true;
  }

  [[nodiscard]] const std::vector<std::uint64_t>& sizes() const { return sizes_; }
  [[nodiscard]] const std::vector<std::size_t>& labels() const { return label_; }

 private:
  [[nodiscard]] Key key(std::size_t i, int axis) const { return {x_[3 * i + axis], offset_ + i}; }

  // Collective: each open part's axis of widest extent, from its bounding box over the ranks, and
  // whether one rank holds all of it (alone[s]), by one MPI_Allreduce: the minimum of lo, of -hi
  // (so exact) and of -1 where this rank holds the whole part, 0 elsewhere.
  std::vector<int> widest_axes(const std::vector<std::size_t>& slot, const std::vector<std::size_t>& open,
                               std::vector<char>& alone, DistributedBlocks& out) const {
    constexpr std::size_t kPer = 7;
    const std::size_t count = open.size();
    std::vector<double> box(kPer * count, std::numeric_limits<double>::infinity());
    std::vector<std::uint64_t> held(count, 0);
    for (std::size_t i = 0; i < label_.size(); ++i) {
      const std::size_t s = slot[label_[i]];
      if (s == kNone) continue;
      ++held[s];
      for (std::size_t c = 0; c < 3; ++c) {
        box[kPer * s + c] = std::min(box[kPer * s + c], x_[3 * i + c]);
        box[kPer * s + 3 + c] = std::min(box[kPer * s + 3 + c], -x_[3 * i + c]);
      }
    }
    for (std::size_t s = 0; s < count; ++s) box[kPer * s + 6] = held[s] == sizes_[open[s]] ? -1.0 : 0.0;
    allreduce(box.data(), box.size(), MPI_DOUBLE, MPI_MIN, sizeof(double), out);
    std::vector<int> axes(count);
    alone.assign(count, 0);
    for (std::size_t s = 0; s < count; ++s) {
      const double* b = box.data() + kPer * s;
      axes[s] = rpy::widest_axis(std::array<double, 3>{b[0], b[1], b[2]}, std::array<double, 3>{-b[3], -b[4], -b[5]});
      alone[s] = b[6] < 0.0 ? 1 : 0;
    }
    return axes;
  }

  // Collective: the element of rank floor(n / 2) of every open part in the order along its axis.
  std::vector<Key> select_medians(const std::vector<std::size_t>& slot, const std::vector<std::size_t>& open,
                                  const std::vector<int>& axes, const std::vector<char>& alone,
                                  DistributedBlocks& out) {
    const std::size_t count = open.size();
    // This rank's members of each open part, sorted: keys_[first_[s] .. first_[s + 1]).
    first_.assign(count + 1, 0);
    for (const std::size_t p : label_)
      if (slot[p] != kNone) ++first_[slot[p] + 1];
    std::partial_sum(first_.begin(), first_.end(), first_.begin());
    keys_.assign(first_.back(), Key{});
    std::vector<std::size_t> fill(first_.begin(), first_.end() - 1);
    for (std::size_t i = 0; i < label_.size(); ++i) {
      const std::size_t s = slot[label_[i]];
      if (s != kNone) keys_[fill[s]++] = key(i, axes[s]);
    }
    for (std::size_t s = 0; s < count; ++s)
      std::sort(keys_.begin() + static_cast<std::ptrdiff_t>(first_[s]),
                keys_.begin() + static_cast<std::ptrdiff_t>(first_[s + 1]));
    // Candidates: keys_[lo[s] .. hi[s]) on this rank; the wanted element is among the ranks'.
    std::vector<std::size_t> lo(first_.begin(), first_.end() - 1), hi(first_.begin() + 1, first_.end());
    std::vector<Key> pivots(count);
    std::vector<std::size_t> unsolved;  // a part held by one rank is split there (split())
    for (std::size_t s = 0; s < count; ++s)
      if (!alone[s]) unsolved.push_back(s);
    const std::size_t stride = kSamples * static_cast<std::size_t>(comm_.size());
    while (!unsolved.empty()) {
      const Trials trials = sample_pivots(unsolved, lo, hi, out);
      std::vector<std::uint64_t> below(unsolved.size() * stride, 0);
      for (std::size_t u = 0; u < unsolved.size(); ++u)
        for (std::size_t j = 0; j < trials.count[u]; ++j)
          below[u * stride + j] = lower(unsolved[u], trials.keys[u * stride + j]) - first_[unsolved[u]];
      allreduce(below.data(), below.size(), MPI_UINT64_T, MPI_SUM, sizeof(std::uint64_t), out);
      ++out.rounds;
      std::vector<std::size_t> left;
      for (std::size_t u = 0; u < unsolved.size(); ++u) {
        const std::size_t s = unsolved[u];
        const std::uint64_t wanted = sizes_[open[s]] / 2;
        // The pivots ascend, so do their counts below: the wanted element is a pivot (solved) or
        // lies between the last pivot below it and the first above it (the new candidates).
        bool solved = false;
        for (std::size_t j = 0; j < trials.count[u] && !solved; ++j) {
          const std::uint64_t b = below[u * stride + j];
          const Key& pivot = trials.keys[u * stride + j];
          solved = b == wanted;
          if (solved) pivots[s] = pivot;
          if (b < wanted) lo[s] = std::max(lo[s], upper(s, pivot));
          if (b > wanted) hi[s] = std::min(hi[s], lower(s, pivot));
        }
        if (!solved) left.push_back(s);
      }
      unsolved = std::move(left);
    }
    return pivots;
  }

  // Per unsolved part u, the ranks' samples together, ascending: keys[u * stride + j], j < count[u].
  struct Trials {
    std::vector<Key> keys;
    std::vector<std::size_t> count;
  };

  // Collective (one MPI_Allgather): per unsolved part, kSamples keys from each rank, spread evenly
  // over its candidates (all of them where it has at most kSamples), as pivots. Between two
  // consecutive pivots lie at most c_r / kSamples + 1 candidates of rank r (c_r its candidates),
  // so each round leaves at most a kSamples-th of the candidates plus one per rank, and a part
  // with at most kSamples candidates on every rank is solved (a sample sort's splitters: Blelloch,
  // Leiserson, Maggs, Plaxton, Smith and Zagha 1991, Proc. ACM SPAA, section 2).
  Trials sample_pivots(const std::vector<std::size_t>& unsolved, const std::vector<std::size_t>& lo,
                       const std::vector<std::size_t>& hi, DistributedBlocks& out) const {
    const std::size_t count = unsolved.size();
    const auto ranks = static_cast<std::size_t>(comm_.size());
    // The same counts on every rank (the parts' sizes are global), so these checks fail everywhere.
    require(count <= static_cast<std::size_t>(INT_MAX) / (sizeof(Key) * kSamples * ranks), ErrorCode::not_supported,
            "rpyfmm::mpi distributed bisection", std::to_string(count) + " parts exceed MPI's int counts");
    std::vector<Key> mine(count * kSamples, Key{0.0, kAbsent});
    for (std::size_t u = 0; u < count; ++u) {
      const std::size_t s = unsolved[u], c = hi[s] - lo[s];
      for (std::size_t j = 0; j < std::min(c, kSamples); ++j) {
        const std::size_t at = c <= kSamples ? j : (2 * j + 1) * c / (2 * kSamples);
        mine[u * kSamples + j] = keys_[lo[s] + at];
      }
    }
    std::vector<Key> all(ranks * mine.size());
    const int bytes = static_cast<int>(mine.size() * sizeof(Key));
    check_mpi(MPI_Allgather(mine.data(), bytes, MPI_BYTE, all.data(), bytes, MPI_BYTE, comm_.get()), "MPI_Allgather");
    out.bytes_received += static_cast<std::uint64_t>(bytes) * (ranks - 1);
    const std::size_t stride = kSamples * ranks;
    Trials trials{std::vector<Key>(count * stride), std::vector<std::size_t>(count, 0)};
    for (std::size_t u = 0; u < count; ++u) {
      Key* keys = trials.keys.data() + u * stride;
      for (std::size_t r = 0; r < ranks; ++r)
        for (std::size_t j = 0; j < kSamples; ++j)
          if (const Key& k = all[(r * count + u) * kSamples + j]; k.g != kAbsent) keys[trials.count[u]++] = k;
      std::sort(keys, keys + trials.count[u]);
    }
    return trials;
  }

  // This rank's members of open part s before the key, and up to and including it.
  [[nodiscard]] std::size_t lower(std::size_t s, const Key& k) const {
    return static_cast<std::size_t>(std::lower_bound(keys_.begin() + static_cast<std::ptrdiff_t>(first_[s]),
                                                     keys_.begin() + static_cast<std::ptrdiff_t>(first_[s + 1]), k) -
                                    keys_.begin());
  }
  [[nodiscard]] std::size_t upper(std::size_t s, const Key& k) const {
    return static_cast<std::size_t>(std::upper_bound(keys_.begin() + static_cast<std::ptrdiff_t>(first_[s]),
                                                     keys_.begin() + static_cast<std::ptrdiff_t>(first_[s + 1]), k) -
                                    keys_.begin());
  }

  // The next level: each open part becomes its lower part (the floor(n / 2) members before the
  // pivot) and its upper part, in this order, where it stood; a part held by one rank becomes its
  // blocks at once, split by that rank alone (split_alone()).
  void split(const std::vector<std::size_t>& slot, const std::vector<int>& axes, const std::vector<char>& alone,
             const std::vector<Key>& pivots) {
    std::vector<std::uint64_t> sizes;
    std::vector<std::size_t> moved(sizes_.size());
    for (std::size_t p = 0; p < sizes_.size(); ++p) {
      moved[p] = sizes.size();
      const std::size_t s = slot[p];
      if (s == kNone) {
        sizes.push_back(sizes_[p]);
      } else if (alone[s]) {
        leaf_sizes(sizes_[p], sizes);
      } else {
        sizes.push_back(sizes_[p] / 2);
        sizes.push_back(sizes_[p] - sizes_[p] / 2);
      }
    }
    std::vector<std::vector<std::size_t>> mine(slot.size());  // this rank's members of parts it holds alone
    for (std::size_t i = 0; i < label_.size(); ++i) {
      const std::size_t p = label_[i], s = slot[p];
      if (s != kNone && alone[s]) {
        mine[p].push_back(i);
        continue;
      }
      label_[i] = moved[p] + (s != kNone && !(key(i, axes[s]) < pivots[s]) ? 1 : 0);
    }
    for (std::size_t p = 0; p < mine.size(); ++p)
      if (!mine[p].empty()) split_alone(mine[p], moved[p]);
    sizes_ = std::move(sizes);
  }

  // The blocks' sizes of a part of n particles, in order: they depend on n alone.
  void leaf_sizes(std::uint64_t n, std::vector<std::uint64_t>& sizes) const {
    if (n <= max_block_) {
      sizes.push_back(n);
      return;
    }
    leaf_sizes(n / 2, sizes);
    leaf_sizes(n - n / 2, sizes);
  }

  // A part this rank holds whole (`members`, ascending): rpy::bisect_blocks on it, whose blocks are
  // the whole set's, the local indices in the order of the global ones; labels from `first` on.
  void split_alone(const std::vector<std::size_t>& members, std::size_t first) {
    std::vector<double> x(3 * members.size());
    for (std::size_t k = 0; k < members.size(); ++k) std::copy_n(x_.data() + 3 * members[k], 3, x.data() + 3 * k);
    const rpy::BlockPartition blocks = rpy::bisect_blocks(x, max_block_);
    for (std::size_t b = 0; b < blocks.blocks(); ++b)
      for (std::size_t k = blocks.offsets[b]; k < blocks.offsets[b + 1]; ++k)
        label_[members[blocks.order[k]]] = first + b;
  }

  void allreduce(void* values, std::size_t count, MPI_Datatype type, MPI_Op op, std::size_t size,
                 DistributedBlocks& out) const {
    require(count <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, "rpyfmm::mpi distributed bisection",
            std::to_string(count) + " values exceed MPI's int counts");  // the same count on every rank
    check_mpi(MPI_Allreduce(MPI_IN_PLACE, values, static_cast<int>(count), type, op, comm_.get()), "MPI_Allreduce");
    if (comm_.size() > 1) out.bytes_received += count * size;
  }

  const Communicator& comm_;
  std::size_t offset_;
  std::span<const double> x_;
  std::vector<std::size_t> label_;
  std::size_t max_block_;
  std::vector<std::uint64_t> sizes_;
  std::vector<Key> keys_;
  std::vector<std::size_t> first_;
};

// Collective (one MPI_Allreduce, MPI_MAXLOC): each block's owner, the rank holding most of its
// members, the lowest such rank on a tie (MPI_MAXLOC's rule for equal values).
std::vector<int> block_owners(const Communicator& comm, const std::vector<std::size_t>& labels, std::size_t blocks,
                              DistributedBlocks& out, const char* where) {
  struct LongInt {
    long count;
    int rank;
  };
  require(blocks <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, where,
          std::to_string(blocks) + " blocks exceed MPI's int counts");  // the same count on every rank
  std::vector<LongInt> held(blocks, LongInt{0, comm.rank()});
  for (const std::size_t b : labels) ++held[b].count;
  check_mpi(MPI_Allreduce(MPI_IN_PLACE, held.data(), static_cast<int>(blocks), MPI_LONG_INT, MPI_MAXLOC, comm.get()),
            "MPI_Allreduce");
  if (comm.size() > 1) out.bytes_received += blocks * sizeof(LongInt);
  std::vector<int> owners(blocks);
  for (std::size_t b = 0; b < blocks; ++b) owners[b] = held[b].rank;
  return owners;
}

// Collective (one MPI_Alltoallv): every particle's index, block, position and radius to its block's
// owner, by block, then index; the owned blocks' members in ascending index.
void send_members(const Communicator& comm, std::size_t offset, std::span<const double> positions,
                  std::span<const double> radii, const std::vector<std::size_t>& labels, DistributedBlocks& out,
                  const char* where) {
  const auto ranks = static_cast<std::size_t>(comm.size());
  std::vector<std::size_t> by_block(labels.size());
  std::iota(by_block.begin(), by_block.end(), std::size_t{0});
  std::stable_sort(by_block.begin(), by_block.end(),
                   [&](std::size_t i, std::size_t j) { return labels[i] < labels[j]; });
  out.send.assign(ranks, {});
  std::vector<std::vector<double>> values(ranks);
  for (const std::size_t i : by_block) {
    const auto owner = static_cast<std::size_t>(out.owner[labels[i]]);
    out.send[owner].push_back(static_cast<std::uint32_t>(i));
    values[owner].insert(values[owner].end(), {static_cast<double>(offset + i), static_cast<double>(labels[i]),
                                               positions[3 * i], positions[3 * i + 1], positions[3 * i + 2], radii[i]});
  }
  std::vector<std::size_t> counts;
  const std::vector<double> received = alltoallv(comm, values, where, "block members", &counts);
  out.recv_counts.assign(ranks, 0);
  for (std::size_t r = 0; r < ranks; ++r) {
    out.recv_counts[r] = counts[r] / kMemberValues;
    if (r != static_cast<std::size_t>(comm.rank())) out.bytes_received += sizeof(double) * counts[r];
  }
  const std::size_t rows = received.size() / kMemberValues;
  const auto at = [&](std::size_t t, std::size_t c) { return received[kMemberValues * t + c]; };
  out.arrived.resize(rows);
  std::iota(out.arrived.begin(), out.arrived.end(), std::size_t{0});
  std::sort(out.arrived.begin(), out.arrived.end(), [&](std::size_t s, std::size_t t) {
    return std::pair(at(s, 1), at(s, 0)) < std::pair(at(t, 1), at(t, 0));
  });
  for (std::size_t k = 0; k < rows; ++k) {
    const std::size_t t = out.arrived[k];
    const auto block = static_cast<std::size_t>(at(t, 1));
    if (out.owned.empty() || out.owned.back() != block) {
      if (!out.owned.empty()) out.owned_offsets.push_back(k);
      out.owned.push_back(block);
    }
    out.members.push_back(static_cast<std::uint64_t>(at(t, 0)));
    out.positions.insert(out.positions.end(), {at(t, 2), at(t, 3), at(t, 4)});
    out.radii.push_back(at(t, 5));
  }
  if (!out.owned.empty()) out.owned_offsets.push_back(rows);
}

}  // namespace

DistributedBlocks distributed_bisection(const Communicator& comm, std::size_t offset, std::span<const double> positions,
                                        std::span<const double> radii, std::size_t max_block, const char* where) {
  const std::uint64_t total = checked_total(comm, offset, positions, radii, where);
  DistributedBlocks out;
  Bisection bisection(comm, offset, positions, total, std::max<std::size_t>(max_block, 1));
  while (bisection.split_level(out)) {
  }
  for (const std::uint64_t size : bisection.sizes()) out.global_offsets.push_back(out.global_offsets.back() + size);
  out.owner = block_owners(comm, bisection.labels(), out.blocks(), out, where);
  send_members(comm, offset, positions, radii, bisection.labels(), out, where);
  return out;
}

}  // namespace rpyfmm::mpi::detail
