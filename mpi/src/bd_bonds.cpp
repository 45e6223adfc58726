// rpyfmm — bonds in distributed Brownian dynamics (bd_bonds.hpp).
#include "bd_bonds.hpp"

#include <algorithm>
#include <string>

#include "alltoallv.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi::detail {
namespace {

constexpr const char* kWhere = "DistributedBd";

// The home rank of a global index: the block [r N / P, (r + 1) N / P) that holds it, and its first.
int home_of(std::uint64_t id, std::uint64_t total, int ranks) {
  return static_cast<int>((id * static_cast<std::uint64_t>(ranks)) / total);
}
std::uint64_t first_of_home(int rank, std::uint64_t total, int ranks) {
  const auto p = static_cast<std::uint64_t>(ranks);
  return (static_cast<std::uint64_t>(rank) * total + p - 1) / p;
}

// The position of `id` in the increasing `ids`, or ids.size() when absent.
std::size_t find(std::span<const std::uint64_t> ids, std::uint64_t id) {
  const auto it = std::lower_bound(ids.begin(), ids.end(), id);
  return it != ids.end() && *it == id ? static_cast<std::size_t>(it - ids.begin()) : ids.size();
}

// The owner of each index of this rank's home block (registration: every owner sends its indices).
std::vector<int> register_owners(const Communicator& comm, std::span<const std::uint64_t> ids, std::uint64_t total) {
  std::vector<std::vector<double>> send(static_cast<std::size_t>(comm.size()));
  for (const std::uint64_t id : ids) send[home_of(id, total, comm.size())].push_back(static_cast<double>(id));
  std::vector<std::size_t> counts;
  const std::vector<double> got = alltoallv(comm, send, kWhere, "the owners of the bond partners", &counts);
  const std::uint64_t first = first_of_home(comm.rank(), total, comm.size());
  const std::uint64_t last = first_of_home(comm.rank() + 1, total, comm.size());
  std::vector<int> owner(last - first, -1);
  std::size_t k = 0;
  for (std::size_t source = 0; source < counts.size(); ++source)
    for (std::size_t c = 0; c < counts[source]; ++c, ++k)
      owner[static_cast<std::uint64_t>(got[k]) - first] = static_cast<int>(source);
  return owner;
}

}  // namespace

BondIndex::BondIndex(std::span<const bd::Bond> bonds, std::uint64_t particles)
    : bonds_(bonds.begin(), bonds.end()), offsets_(particles + 1, 0) {
  for (const bd::Bond& b : bonds_) {
    require(b.i < particles && b.j < particles, ErrorCode::invalid_input, "bonds",
            "bond (" + std::to_string(b.i) + ", " + std::to_string(b.j) +
                ") refers to a particle >= N = " + std::to_string(particles));
    ++offsets_[b.i + 1];
    ++offsets_[b.j + 1];
  }
  for (std::uint64_t i = 0; i < particles; ++i) offsets_[i + 1] += offsets_[i];
  entries_.resize(offsets_[particles]);
  std::vector<std::uint64_t> fill(offsets_.begin(), offsets_.end() - 1);
  for (std::size_t k = 0; k < bonds_.size(); ++k) {  // bond order, as ForceField's own index
    entries_[fill[bonds_[k].i]++] = static_cast<std::uint32_t>(k);
    entries_[fill[bonds_[k].j]++] = static_cast<std::uint32_t>(k);
  }
}

std::vector<std::vector<std::uint32_t>> bond_partners_wanted(const Communicator& comm, const BondIndex& index,
                                                             std::span<const std::uint64_t> ids, std::uint64_t total) {
  const auto ranks = static_cast<std::size_t>(comm.size());
  std::vector<std::vector<std::uint32_t>> wanted(ranks);
  if (index.empty()) return wanted;  // the same on every rank: no exchange anywhere
  const std::vector<int> owner = register_owners(comm, ids, total);
  // The partners this rank lacks, each asked once, to their home ranks.
  std::vector<std::uint64_t> lacking;
  for (const std::uint64_t id : ids) {
    for (const std::uint32_t k : index.of(id)) {
      const bd::Bond& b = index.bonds()[k];
      const std::uint64_t partner = b.i == id ? b.j : b.i;
      if (find(ids, partner) == ids.size()) lacking.push_back(partner);
    }
  }
  std::sort(lacking.begin(), lacking.end());
  lacking.erase(std::unique(lacking.begin(), lacking.end()), lacking.end());
  std::vector<std::vector<double>> requests(ranks);
  for (const std::uint64_t id : lacking) requests[home_of(id, total, comm.size())].push_back(static_cast<double>(id));
  std::vector<std::size_t> counts;
  const std::vector<double> asked = alltoallv(comm, requests, kWhere, "the requests for bond partners", &counts);
  // The home ranks forward each request (index, requester) to the index's owner.
  const std::uint64_t first = first_of_home(comm.rank(), total, comm.size());
  std::vector<std::vector<double>> forwarded(ranks);
  std::size_t k = 0;
  for (std::size_t requester = 0; requester < counts.size(); ++requester) {
    for (std::size_t c = 0; c < counts[requester]; ++c, ++k) {
      const auto id = static_cast<std::uint64_t>(asked[k]);
      forwarded[static_cast<std::size_t>(owner[id - first])].insert(
          forwarded[static_cast<std::size_t>(owner[id - first])].end(), {asked[k], static_cast<double>(requester)});
    }
  }
  const std::vector<double> mine = alltoallv(comm, forwarded, kWhere, "the bond partners' owners");
  for (std::size_t m = 0; m < mine.size(); m += 2) {
    const std::size_t i = find(ids, static_cast<std::uint64_t>(mine[m]));
    wanted[static_cast<std::size_t>(mine[m + 1])].push_back(static_cast<std::uint32_t>(i));
  }
  for (auto& w : wanted) std::sort(w.begin(), w.end());
  return wanted;
}

PartBonds part_bonds(const BondIndex& index, std::span<const std::uint64_t> owned_ids,
                     std::span<const std::uint64_t> part_ids) {
  std::vector<std::uint32_t> touching;
  for (const std::uint64_t id : owned_ids) {
    const auto of = index.of(id);
    touching.insert(touching.end(), of.begin(), of.end());
  }
  std::sort(touching.begin(), touching.end());  // bond order: each row sums its bonds as the serial engine
  touching.erase(std::unique(touching.begin(), touching.end()), touching.end());
  PartBonds part;
  part.bonds.reserve(touching.size());
  part.names.reserve(touching.size());
  for (const std::uint32_t k : touching) {
    const bd::Bond& b = index.bonds()[k];
    const std::size_t i = find(part_ids, b.i), j = find(part_ids, b.j);
    require(i < part_ids.size() && j < part_ids.size(), ErrorCode::invalid_input, kWhere,
            "bond " + std::to_string(k) + " has an end outside the rank's part");
    part.bonds.push_back(bd::Bond{static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j), b.type});
    part.names.push_back(k);
  }
  return part;
}

}  // namespace rpyfmm::mpi::detail
