// rpyfmm — the locally essential tree of DistributedLaplaceFmm: regions, the cells sent to every
// rank, the geometry exchanged once per plan, and the charges exchanged per evaluation
// (fmm_plan.hpp, docs/mpi.md).
#include <algorithm>
#include <array>
#include <functional>
#include <memory>
#include <numeric>
#include <string>

#include "alltoallv.hpp"
#include "chebyshev.hpp"
#include "fmm_plan.hpp"

namespace rpyfmm::mpi::detail {
namespace {

constexpr const char* kWhere = "rpyfmm::mpi::DistributedLaplaceFmm";
// Boxes per rank in the cover of its region (region_cover): more boxes describe a region more
// tightly (fewer cells opened for it) at 48 bytes each to every neighbour; 512 instead of 64
// changed no essential source at 4e5 sources on 4 ranks (docs/mpi.md).
constexpr std::size_t kRegionBoxes = 64;
constexpr std::size_t kBoxDoubles = 6;   // lo, hi
constexpr std::size_t kCubeDoubles = 5;  // center, half-side, order

// The geometry sent to rank r: the halo particles' positions, then each compressed cell's cube.
std::vector<double> geometry_for(const Plan& plan, std::size_t r, std::size_t& halo) {
  std::vector<double> out;
  halo = 0;
  for (std::uint32_t c : plan.sent[r].halo) {
    const Cell& cell = plan.tree.cells[c];
    out.insert(out.end(), plan.owned_x.begin() + static_cast<std::ptrdiff_t>(3 * cell.begin),
               plan.owned_x.begin() + static_cast<std::ptrdiff_t>(3 * cell.end));
    halo += cell.size();
  }
  for (const Compressed& c : plan.sent[r].compressed) {
    const Cube cube = cell_cube(plan.tree.cells[c.cell]);
    out.insert(out.end(), {cube.center[0], cube.center[1], cube.center[2], cube.half, static_cast<double>(c.order)});
  }
  return out;
}

// The halo charges sent to rank r: per density, the halo particles' charges (in the order of
// exchange_geometry's halo sources).
std::vector<double> halo_charges_for(const Plan& plan, std::size_t r, std::span<const double> owned_q, std::size_t nd) {
  const std::size_t m = plan.owned_x.size() / 3;
  std::vector<double> out;
  for (std::size_t d = 0; d < nd; ++d) {
    for (std::uint32_t c : plan.sent[r].halo) {
      const Cell& cell = plan.tree.cells[c];
      out.insert(out.end(), owned_q.begin() + static_cast<std::ptrdiff_t>(d * m + cell.begin),
                 owned_q.begin() + static_cast<std::ptrdiff_t>(d * m + cell.end));
    }
  }
  return out;
}

// The equivalent charges sent to rank r: per density, each compressed cell's p^3 values (in the
// order of exchange_geometry's node sources).
std::vector<double> node_charges_for(const Plan& plan, std::size_t r, std::span<const double> eq, std::size_t nd) {
  std::vector<double> out;
  for (std::size_t d = 0; d < nd; ++d) {
    for (std::size_t slot : plan.slots[r]) {
      const std::size_t nodes = cube_nodes(plan.jobs[slot].order);
      const auto first = eq.begin() + static_cast<std::ptrdiff_t>(nd * plan.job_offset[slot] + d * nodes);
      out.insert(out.end(), first, first + static_cast<std::ptrdiff_t>(nodes));
    }
  }
  return out;
}

// Jobs per piece of the anterpolation between two progress calls of the halo charges' exchange.
constexpr std::size_t kJobsPerPiece = 64;

}  // namespace

namespace {

constexpr std::size_t kSummaryDoubles = 5;  // the root cell's cube (centre, half-side) and particles
constexpr int kCoverTag = 0x5247;           // a cover sent to a neighbour (collectives do not match it)

std::vector<double> pack_boxes(const std::vector<Box>& boxes) {
  std::vector<double> packed;
  for (const Box& b : boxes) {
    packed.insert(packed.end(), b.lo.begin(), b.lo.end());
    packed.insert(packed.end(), b.hi.begin(), b.hi.end());
  }
  return packed;
}

std::vector<Box> unpack_boxes(const double* v, std::size_t doubles) {
  std::vector<Box> boxes;
  for (std::size_t i = 0; i < doubles; i += kBoxDoubles, v += kBoxDoubles)
    boxes.push_back(Box{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}});
  return boxes;
}

// Reference: every rank's cover on every rank, one all-gather of counts and one of the boxes; every
// other rank's region is walked.
std::vector<Region> all_regions(const Communicator& comm, const std::vector<Box>& cover, FmmCommunication& stats) {
  const auto ranks = static_cast<std::size_t>(comm.size());
  const int count = static_cast<int>(kBoxDoubles * cover.size());
  std::vector<int> counts(ranks), displs(ranks);
  check_mpi(MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, comm.get()), "MPI_Allgather");
  std::partial_sum(counts.begin(), counts.end() - 1, displs.begin() + 1);
  std::vector<double> packed = pack_boxes(cover), all(static_cast<std::size_t>(displs.back() + counts.back()));
  check_mpi(MPI_Allgatherv(packed.data(), count, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE,
                           comm.get()),
            "MPI_Allgatherv");
  stats.plan_bytes_received += all.size() * sizeof(double);
  std::vector<Region> regions(ranks);
  for (std::size_t r = 0; r < ranks; ++r) {
    if (static_cast<int>(r) == comm.rank()) continue;
    regions[r].cover = unpack_boxes(all.data() + displs[r], static_cast<std::size_t>(counts[r]));
    if (regions[r].cover.empty()) continue;
    ++stats.region_neighbours;
    stats.region_bytes_received += static_cast<std::uint64_t>(counts[r]) * sizeof(double);
  }
  if (!cover.empty()) stats.region_sent_to = ranks - 1;
  return regions;
}

// What a region (cover) asks of a rank's cells, from that rank's summary (root cube, particles): 0,
// nothing (an empty region or tree, where essential_cells sends nothing); p > 0, its root cell
// compressed at order p (where the walk would stop at the root); -k, a walk against the cover's k
// boxes, which then goes to that rank.
int region_request(const double* summary, std::span<const Box> cover, const Acceptance& acceptance) {
  const auto particles = static_cast<std::size_t>(summary[4]);
  if (cover.empty() || particles == 0) return 0;
  const Cube root{{summary[0], summary[1], summary[2]}, summary[3]};
  const int p = compressed_order(root, particles, cover, acceptance);
  return p > 0 ? p : -static_cast<int>(cover.size());
}

// Collective: every rank's summary (its root cell's cube and particles; 0 particles for an empty
// tree), by rank, one all-gather.
std::vector<double> gather_roots(const Communicator& comm, const CellTree& tree) {
  std::array<double, kSummaryDoubles> mine{};
  if (!tree.cells.empty()) {
    const Cube root = cell_cube(tree.cells[0]);
    mine = {root.center[0], root.center[1], root.center[2], root.half, static_cast<double>(tree.cells[0].size())};
  }
  std::vector<double> summaries(kSummaryDoubles * static_cast<std::size_t>(comm.size()));
  check_mpi(MPI_Allgather(mine.data(), static_cast<int>(kSummaryDoubles), MPI_DOUBLE, summaries.data(),
                          static_cast<int>(kSummaryDoubles), MPI_DOUBLE, comm.get()),
            "MPI_Allgather");
  return summaries;
}

// Collective: this rank's cover to every rank s with asked[s] < 0, and rank r's cover of -told[r]
// boxes from every rank r with told[r] < 0, point to point; the covers received go into regions.
void exchange_covers(const Communicator& comm, const std::vector<Box>& cover, const std::vector<int>& asked,
                     const std::vector<int>& told, std::vector<Region>& regions, FmmCommunication& stats) {
  const std::vector<double> packed = pack_boxes(cover);
  std::vector<std::vector<double>> got(told.size());
  std::vector<MPI_Request> requests;
  for (std::size_t r = 0; r < told.size(); ++r) {
    if (told[r] >= 0) continue;
    got[r].resize(kBoxDoubles * static_cast<std::size_t>(-told[r]));
    requests.push_back(MPI_REQUEST_NULL);
    check_mpi(MPI_Irecv(got[r].data(), static_cast<int>(got[r].size()), MPI_DOUBLE, static_cast<int>(r), kCoverTag,
                        comm.get(), &requests.back()),
              "MPI_Irecv");
  }
  for (std::size_t s = 0; s < asked.size(); ++s) {
    if (asked[s] >= 0) continue;
    requests.push_back(MPI_REQUEST_NULL);
    check_mpi(MPI_Isend(packed.data(), static_cast<int>(packed.size()), MPI_DOUBLE, static_cast<int>(s), kCoverTag,
                        comm.get(), &requests.back()),
              "MPI_Isend");
    ++stats.region_sent_to;
  }
  check_mpi(MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE), "MPI_Waitall");
  for (std::size_t r = 0; r < got.size(); ++r) {
    if (got[r].empty()) continue;
    regions[r].cover = unpack_boxes(got[r].data(), got[r].size());
    ++stats.region_neighbours;
    stats.region_bytes_received += got[r].size() * sizeof(double);
  }
  stats.plan_bytes_received += stats.region_bytes_received;
}

// Covers exchanged only with the ranks that walk them: one all-gather of every rank's summary, one
// all-to-all of the requests, the covers point to point.
std::vector<Region> neighbour_regions(const Communicator& comm, const std::vector<Box>& cover, const CellTree& tree,
                                      const Acceptance& acceptance, FmmCommunication& stats) {
  const auto ranks = static_cast<std::size_t>(comm.size());
  const auto me = static_cast<std::size_t>(comm.rank());
  const std::vector<double> summaries = gather_roots(comm, tree);
  // asked[s]: what this rank's region asks of rank s's cells; told[r]: what rank r's asks of this
  // rank's (0 from itself).
  std::vector<int> asked(ranks), told(ranks);
  for (std::size_t s = 0; s < ranks; ++s)
    asked[s] = s == me ? 0 : region_request(summaries.data() + kSummaryDoubles * s, cover, acceptance);
  check_mpi(MPI_Alltoall(asked.data(), 1, MPI_INT, told.data(), 1, MPI_INT, comm.get()), "MPI_Alltoall");
  stats.plan_bytes_received += summaries.size() * sizeof(double) + told.size() * sizeof(int);
  std::vector<Region> regions(ranks);
  for (std::size_t r = 0; r < ranks; ++r) regions[r].root_order = std::max(told[r], 0);
  exchange_covers(comm, cover, asked, told, regions, stats);
  return regions;
}

}  // namespace

std::vector<Region> exchange_regions(const Communicator& comm, const CellTree& region_tree, const CellTree& tree,
                                     const Acceptance& acceptance, bool gather_all, FmmCommunication& stats) {
  const std::vector<Box> cover = region_cover(region_tree, kRegionBoxes);
  stats.region_boxes = cover.size();
  return gather_all ? all_regions(comm, cover, stats) : neighbour_regions(comm, cover, tree, acceptance, stats);
}

void select_cells(Plan& plan, const std::vector<Region>& regions, int rank, const Acceptance& acceptance) {
  plan.sent.assign(regions.size(), {});
  for (std::size_t r = 0; r < regions.size(); ++r) {
    if (static_cast<int>(r) == rank) continue;
    // A root compressed for r is what the walk against r's cover gives (its first step).
    plan.sent[r] = regions[r].root_order > 0 ? EssentialCells{{}, {Compressed{0, regions[r].root_order}}}
                                             : essential_cells(plan.tree, regions[r].cover, acceptance);
    plan.jobs.insert(plan.jobs.end(), plan.sent[r].compressed.begin(), plan.sent[r].compressed.end());
  }
  std::sort(plan.jobs.begin(), plan.jobs.end());
  plan.jobs.erase(std::unique(plan.jobs.begin(), plan.jobs.end()), plan.jobs.end());
  plan.job_offset.assign(plan.jobs.size() + 1, 0);
  for (std::size_t j = 0; j < plan.jobs.size(); ++j)
    plan.job_offset[j + 1] = plan.job_offset[j] + cube_nodes(plan.jobs[j].order);
  plan.slots.assign(regions.size(), {});
  for (std::size_t r = 0; r < regions.size(); ++r) {
    for (const Compressed& c : plan.sent[r].compressed) {
      plan.slots[r].push_back(
          static_cast<std::size_t>(std::lower_bound(plan.jobs.begin(), plan.jobs.end(), c) - plan.jobs.begin()));
    }
  }
}

std::vector<double> exchange_geometry(const Communicator& comm, Plan& plan, std::uint64_t& bytes) {
  const auto ranks = static_cast<std::size_t>(comm.size());
  std::vector<std::vector<double>> send(ranks);
  std::vector<std::uint64_t> counts(2 * ranks), recv(2 * ranks);  // (halo particles, cells) per rank
  for (std::size_t r = 0; r < ranks; ++r) {
    send[r] = geometry_for(plan, r, counts[2 * r]);
    counts[2 * r + 1] = plan.sent[r].compressed.size();
  }
  check_mpi(MPI_Alltoall(counts.data(), 2, MPI_UINT64_T, recv.data(), 2, MPI_UINT64_T, comm.get()), "MPI_Alltoall");
  plan.recv_halo.resize(ranks);
  plan.recv_cells.resize(ranks);
  std::vector<std::size_t> recv_doubles(ranks);
  for (std::size_t r = 0; r < ranks; ++r) {
    plan.recv_halo[r] = recv[2 * r];
    plan.recv_cells[r] = recv[2 * r + 1];
    recv_doubles[r] = 3 * plan.recv_halo[r] + kCubeDoubles * plan.recv_cells[r];
  }
  const std::vector<double> got = alltoallv(comm, send, recv_doubles, kWhere, "the essential tree's geometry");
  bytes += got.size() * sizeof(double);

  std::vector<double> sources = plan.owned_x, cell_nodes;
  plan.recv_nodes.assign(ranks, 0);
  std::size_t at = 0;
  for (std::size_t r = 0; r < ranks; ++r) {
    sources.insert(sources.end(), got.begin() + static_cast<std::ptrdiff_t>(at),
                   got.begin() + static_cast<std::ptrdiff_t>(at + 3 * plan.recv_halo[r]));
    at += 3 * plan.recv_halo[r];
    for (std::size_t c = 0; c < plan.recv_cells[r]; ++c, at += kCubeDoubles) {
      const Cube cube{{got[at], got[at + 1], got[at + 2]}, got[at + 3]};
      const int order = static_cast<int>(got[at + 4]);
      cell_nodes.resize(3 * cube_nodes(order));
      chebyshev_nodes(cube, order, cell_nodes);
      sources.insert(sources.end(), cell_nodes.begin(), cell_nodes.end());
      plan.recv_nodes[r] += cube_nodes(order);
    }
  }
  return sources;
}

void count_essential(const Plan& plan, FmmCommunication& stats) {
  for (std::size_t r = 0; r < plan.sent.size(); ++r) {
    for (std::uint32_t c : plan.sent[r].halo) stats.halo_sent += plan.tree.cells[c].size();
    for (const Compressed& c : plan.sent[r].compressed) stats.nodes_sent += cube_nodes(c.order);
    stats.cells_sent += plan.sent[r].compressed.size();
    stats.halo_received += plan.recv_halo[r];
    stats.cells_received += plan.recv_cells[r];
    stats.nodes_received += plan.recv_nodes[r];
  }
}

std::vector<double> anterpolate_cells(const Plan& plan, std::span<const double> owned_q, std::size_t nd,
                                      const std::function<void()>& between_pieces) {
  const std::size_t m = plan.owned_x.size() / 3;
  std::vector<double> eq(nd * plan.job_offset.back());
  for (std::size_t begin = 0; begin < plan.jobs.size(); begin += kJobsPerPiece) {
    const auto end = static_cast<std::ptrdiff_t>(std::min(plan.jobs.size(), begin + kJobsPerPiece));
#pragma omp parallel for schedule(dynamic, 1)
    for (auto i = static_cast<std::ptrdiff_t>(begin); i < end; ++i) {
      const auto j = static_cast<std::size_t>(i);
      const Cell& cell = plan.tree.cells[plan.jobs[j].cell];
      const std::span<const double> x(plan.owned_x.data() + 3 * cell.begin, 3 * cell.size());
      const std::size_t nodes = cube_nodes(plan.jobs[j].order);
      anterpolate(cell_cube(cell), plan.jobs[j].order, x, owned_q.data() + cell.begin, m, nd,
                  std::span<double>(eq.data() + nd * plan.job_offset[j], nd * nodes));
    }
    if (between_pieces) between_pieces();  // on the calling thread, outside the parallel region
  }
  return eq;
}

namespace {

// One exchange of charges: what charges_for(r) packs for each rank r, and nd x incoming[r] values
// from each.
struct ChargeExchange {
  std::vector<std::vector<double>> send;
  std::vector<std::size_t> recv_counts;
};
template <class Pack>
ChargeExchange charge_exchange(std::size_t ranks, std::size_t nd, const std::vector<std::size_t>& incoming,
                               Pack&& charges_for) {
  ChargeExchange e{std::vector<std::vector<double>>(ranks), std::vector<std::size_t>(ranks)};
  for (std::size_t r = 0; r < ranks; ++r) {
    e.send[r] = charges_for(r);
    e.recv_counts[r] = nd * incoming[r];
  }
  return e;
}

}  // namespace

std::unique_ptr<PendingAlltoallv> post_halo_charges(const Communicator& comm, const Plan& plan,
                                                    std::span<const double> owned_q, std::size_t nd) {
  const ChargeExchange e = charge_exchange(static_cast<std::size_t>(comm.size()), nd, plan.recv_halo,
                                           [&](std::size_t r) { return halo_charges_for(plan, r, owned_q, nd); });
  return std::make_unique<PendingAlltoallv>(comm, e.send, e.recv_counts, kWhere, "the essential halo charges");
}

namespace {

ChargeExchange node_exchange(const Communicator& comm, const Plan& plan, std::span<const double> equivalent,
                             std::size_t nd) {
  return charge_exchange(static_cast<std::size_t>(comm.size()), nd, plan.recv_nodes,
                         [&](std::size_t r) { return node_charges_for(plan, r, equivalent, nd); });
}

}  // namespace

std::vector<double> exchange_node_charges(const Communicator& comm, const Plan& plan,
                                          std::span<const double> equivalent, std::size_t nd) {
  const ChargeExchange e = node_exchange(comm, plan, equivalent, nd);
  return alltoallv(comm, e.send, e.recv_counts, kWhere, "the essential equivalent charges");
}

std::unique_ptr<PendingAlltoallv> post_node_charges(const Communicator& comm, const Plan& plan,
                                                    std::span<const double> equivalent, std::size_t nd) {
  const ChargeExchange e = node_exchange(comm, plan, equivalent, nd);
  return std::make_unique<PendingAlltoallv>(comm, e.send, e.recv_counts, kWhere, "the essential equivalent charges");
}

namespace {

// Writes what came from the other ranks into q (nd rows of `width` values, from column `first`):
// per rank in rank order its halo sources, then its cells' nodes (exchange_geometry's order).
void place_received(const Plan& plan, const ReceivedCharges& received, std::size_t nd, std::size_t width,
                    std::size_t first, std::vector<double>& q) {
  std::size_t at_halo = 0, at_nodes = 0, offset = first;
  for (std::size_t r = 0; r < plan.recv_halo.size(); ++r) {
    const std::size_t halo = plan.recv_halo[r], nodes = plan.recv_nodes[r];
    for (std::size_t d = 0; d < nd; ++d, at_halo += halo, at_nodes += nodes) {
      const auto to = q.begin() + static_cast<std::ptrdiff_t>(d * width + offset);
      std::copy_n(received.halo.begin() + static_cast<std::ptrdiff_t>(at_halo), halo, to);
      std::copy_n(received.nodes.begin() + static_cast<std::ptrdiff_t>(at_nodes), nodes,
                  to + static_cast<std::ptrdiff_t>(halo));
    }
    offset += halo + nodes;
  }
}

}  // namespace

std::vector<double> assemble_charges(const Plan& plan, std::span<const double> owned_q, const ReceivedCharges& received,
                                     std::size_t nd) {
  const std::size_t m = plan.owned_x.size() / 3;
  std::vector<double> q(nd * plan.sources);
  for (std::size_t d = 0; d < nd; ++d) {
    std::copy_n(owned_q.begin() + static_cast<std::ptrdiff_t>(d * m), m,
                q.begin() + static_cast<std::ptrdiff_t>(d * plan.sources));
  }
  place_received(plan, received, nd, plan.sources, m, q);
  return q;
}

std::vector<double> assemble_received(const Plan& plan, const ReceivedCharges& received, std::size_t nd) {
  const std::size_t width = plan.sources - plan.owned_x.size() / 3;
  std::vector<double> q(nd * width);
  place_received(plan, received, nd, width, 0, q);
  return q;
}

}  // namespace rpyfmm::mpi::detail
