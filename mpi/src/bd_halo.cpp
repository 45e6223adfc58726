// rpyfmm — the halo of a rank in distributed Brownian dynamics (bd_halo.hpp).
#include "bd_halo.hpp"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <numeric>

#include "alltoallv.hpp"
#include "rpyfmm/mpi/partition.hpp"
#include "wrap_into_box.hpp"

namespace rpyfmm::mpi {
namespace detail {
namespace {

// Particles per leaf of the tree over a rank's particles, and boxes in the cover of its region
// published to the other ranks (as the distributed Laplace FMM's regions).
constexpr std::size_t kCellCapacity = 32;
constexpr std::size_t kRegionBoxes = 64;

}  // namespace

std::array<double, 3> wrapped(const double* x, const rpy::Geometry& geometry) {
  std::array<double, 3> w{x[0], x[1], x[2]};
  if (!geometry.is_periodic()) return w;
  for (int c = 0; c < 3; ++c) w[c] = rpy::detail::wrap_into_box(w[c], geometry.box()[c]);  // as MobilityOperator
  return w;
}

OwnedCells owned_cells(std::span<const double> positions, const rpy::Geometry& geometry) {
  OwnedCells cells;
  const std::size_t n = positions.size() / 3;
  if (n == 0) return cells;
  std::vector<double> w(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::array<double, 3> p = wrapped(&positions[3 * i], geometry);
    std::copy(p.begin(), p.end(), &w[3 * i]);
  }
  // The keys in the cube of this rank's own wrapped positions (no communication).
  KeyCube cube{{w[0], w[1], w[2]}, 0.0};
  std::array<double, 3> hi = cube.origin;
  for (std::size_t k = 0; k < 3 * n; ++k) {
    cube.origin[k % 3] = std::min(cube.origin[k % 3], w[k]);
    hi[k % 3] = std::max(hi[k % 3], w[k]);
  }
  for (int c = 0; c < 3; ++c) cube.half_side = std::max(cube.half_side, 0.5 * hi[c] - 0.5 * cube.origin[c]);
  const std::vector<std::uint64_t> keys = morton_keys(cube, w);
  cells.order.resize(n);
  std::iota(cells.order.begin(), cells.order.end(), std::uint32_t{0});
  std::sort(cells.order.begin(), cells.order.end(),
            [&](std::uint32_t a, std::uint32_t b) { return keys[a] != keys[b] ? keys[a] < keys[b] : a < b; });
  std::vector<std::uint64_t> sorted_keys(n);
  cells.wrapped.resize(3 * n);
  for (std::size_t k = 0; k < n; ++k) {
    sorted_keys[k] = keys[cells.order[k]];
    std::copy(&w[3 * cells.order[k]], &w[3 * cells.order[k] + 3], &cells.wrapped[3 * k]);
  }
  cells.tree = build_cell_tree(sorted_keys, cells.wrapped, kCellCapacity);
  return cells;
}

std::vector<Box> region_of(const OwnedCells& cells) {
  return region_cover(cells.tree, kRegionBoxes);
}

double distance2(const Box& a, const Box& b, const rpy::Geometry& geometry) {
  double d2 = 0.0;
  for (std::size_t c = 0; c < 3; ++c) {
    const auto gap = [&](double shift) {
      return std::max({b.lo[c] + shift - a.hi[c], a.lo[c] - b.hi[c] - shift, 0.0});
    };
    double g = gap(0.0);
    if (geometry.is_periodic()) g = std::min({g, gap(-geometry.box()[c]), gap(geometry.box()[c])});
    d2 += g * g;
  }
  return d2;
}

std::vector<std::vector<Box>> gather_regions(const Communicator& comm, const std::vector<Box>& mine) {
  constexpr int kBoxValues = 6;  // lo, hi
  std::vector<double> packed;
  packed.reserve(kBoxValues * mine.size());
  for (const Box& b : mine) packed.insert(packed.end(), {b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1], b.hi[2]});
  const int count = static_cast<int>(packed.size());
  std::vector<int> counts(static_cast<std::size_t>(comm.size())), displs(counts.size(), 0);
  check_mpi(MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, comm.get()), "MPI_Allgather");
  for (std::size_t r = 1; r < counts.size(); ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(static_cast<std::size_t>(displs.back() + counts.back()));
  check_mpi(MPI_Allgatherv(packed.data(), count, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE,
                           comm.get()),
            "MPI_Allgatherv");
  std::vector<std::vector<Box>> regions(counts.size());
  for (std::size_t r = 0; r < regions.size(); ++r) {
    for (int k = displs[r]; k < displs[r] + counts[r]; k += kBoxValues) {
      const double* v = &all[static_cast<std::size_t>(k)];
      regions[r].push_back(Box{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}});
    }
  }
  return regions;
}

namespace {

// Appends to `out` the index of every particle of `cells` within sqrt(reach2) of `box`: a descent
// of the cell tree that skips the cells whose tight box lies farther.
void particles_near(const OwnedCells& cells, const Box& box, const rpy::Geometry& geometry, double reach2,
                    std::vector<std::uint32_t>& out) {
  if (cells.tree.cells.empty()) return;
  std::vector<std::uint32_t> stack{0};
  while (!stack.empty()) {
    const Cell& cell = cells.tree.cells[stack.back()];
    stack.pop_back();
    if (distance2(cell.box, box, geometry) > reach2) continue;
    if (!cell.leaf()) {
      for (std::uint32_t k = 0; k < cell.child_count; ++k) stack.push_back(cell.first_child + k);
      continue;
    }
    for (std::size_t k = cell.begin; k < cell.end; ++k) {
      const double* p = &cells.wrapped[3 * k];
      if (distance2(Box{{p[0], p[1], p[2]}, {p[0], p[1], p[2]}}, box, geometry) <= reach2)
        out.push_back(cells.order[k]);
    }
  }
}

}  // namespace

std::vector<std::vector<std::uint32_t>> select_halo(const Communicator& comm, const OwnedCells& cells,
                                                    const std::vector<std::vector<Box>>& regions,
                                                    const rpy::Geometry& geometry, double list_radius) {
  std::vector<std::vector<std::uint32_t>> send(regions.size());
  if (list_radius <= 0.0) return send;
  const double reach = list_radius * (1.0 + 1e-12);
  const double reach2 = reach * reach;
  for (std::size_t r = 0; r < regions.size(); ++r) {
    if (static_cast<int>(r) == comm.rank()) continue;
    for (const Box& box : regions[r]) particles_near(cells, box, geometry, reach2, send[r]);
    std::sort(send[r].begin(), send[r].end());  // a particle near several boxes is sent once
    send[r].erase(std::unique(send[r].begin(), send[r].end()), send[r].end());
  }
  return send;
}

}  // namespace detail

namespace {

constexpr int kHaloValues = 5;  // id, type, x, y, z

// The part: owned and received particles merged in increasing global index.
void assemble_part(DistributedBd::Halo& h, std::span<const double> positions, std::span<const std::uint32_t> types,
                   std::span<const std::uint64_t> ids, const std::vector<double>& received) {
  const std::size_t n = ids.size(), m = received.size() / kHaloValues;
  // (id, source): source < n an owned particle, else halo particle source - n
  std::vector<std::pair<std::uint64_t, std::size_t>> order(n + m);
  for (std::size_t i = 0; i < n; ++i) order[i] = {ids[i], i};
  for (std::size_t k = 0; k < m; ++k) order[n + k] = {static_cast<std::uint64_t>(received[kHaloValues * k]), n + k};
  std::sort(order.begin(), order.end());
  h.x.resize(3 * (n + m));
  h.types.resize(n + m);
  h.ids.resize(n + m);
  h.owned_rows.resize(n);
  h.halo_rows.resize(m);
  for (std::size_t row = 0; row < order.size(); ++row) {
    const auto [id, source] = order[row];
    h.ids[row] = id;
    const auto r32 = static_cast<std::uint32_t>(row);
    if (source < n) {
      h.owned_rows[source] = r32;
      h.types[row] = types[source];
      for (int c = 0; c < 3; ++c) h.x[3 * row + c] = positions[3 * source + c];
    } else {
      const double* v = &received[kHaloValues * (source - n)];
      h.halo_rows[source - n] = r32;
      h.types[row] = static_cast<std::uint32_t>(v[1]);
      for (int c = 0; c < 3; ++c) h.x[3 * row + c] = v[2 + c];
    }
  }
}

}  // namespace

DistributedBd::Halo DistributedBd::Halo::build(const Communicator& comm, const bd::ForceField& forces,
                                               const detail::BondIndex& bonds, const rpy::Geometry& geometry,
                                               const bd::NeighbourOptions& neighbours,
                                               std::span<const double> positions, std::span<const std::uint32_t> types,
                                               std::span<const std::uint64_t> ids, std::uint64_t total, double reach) {
  Halo h{.list = bd::NeighbourList(geometry, forces.max_cutoff(), neighbours),
         .pairs = forces.has_pairs(),
         .exchanges = forces.has_pairs() || !bonds.empty() || reach > 0.0};
  h.skin = h.list.skin() > 0.0 ? h.list.skin() : 0.3 * reach;
  const double list_radius = std::max(h.pairs ? h.list.list_radius() : 0.0, reach > 0.0 ? reach + h.skin : 0.0);
  const detail::OwnedCells cells = detail::owned_cells(positions, geometry);
  const std::vector<std::vector<detail::Box>> regions = detail::gather_regions(comm, detail::region_of(cells));
  h.send = detail::select_halo(comm, cells, regions, geometry, list_radius);
  // The bond partners that other ranks lack join what goes to them (each particle once).
  const std::vector<std::vector<std::uint32_t>> partners = detail::bond_partners_wanted(comm, bonds, ids, total);
  for (std::size_t r = 0; r < h.send.size(); ++r) {
    if (partners[r].empty()) continue;
    std::vector<std::uint32_t> merged;
    std::set_union(h.send[r].begin(), h.send[r].end(), partners[r].begin(), partners[r].end(),
                   std::back_inserter(merged));
    h.send[r] = std::move(merged);
  }
  std::vector<std::vector<double>> packed(h.send.size());
  for (std::size_t r = 0; r < h.send.size(); ++r) {
    for (const std::uint32_t i : h.send[r]) {
      packed[r].insert(packed[r].end(), {static_cast<double>(ids[i]), static_cast<double>(types[i]), positions[3 * i],
                                         positions[3 * i + 1], positions[3 * i + 2]});
    }
  }
  const std::vector<double> received =
      detail::alltoallv(comm, packed, "DistributedBd", "the halo's particles", &h.recv_counts);
  for (std::size_t& count : h.recv_counts) count /= kHaloValues;
  assemble_part(h, positions, types, ids, received);
  if (!bonds.empty()) {  // the same bond list on every rank; a failure here fails every rank alike
    comm.run([&] {
      const detail::PartBonds part = detail::part_bonds(bonds, ids, h.ids);
      h.part_forces = forces.with_bonds(part.bonds, part.names);
    });
  }
  if (h.pairs && !h.ids.empty()) {  // an empty part (a rank without particles near any) has no list
    h.list.set_pair_cutoffs(h.types, forces.pair_cutoffs(), forces.types().size());
    h.list.build(h.x);
  }
  return h;
}

void DistributedBd::Halo::refresh(const Communicator& comm, std::span<const double> positions) {
  if (!exchanges) {  // no pair potential, bond or complex (the same on every rank): no halo anywhere
    for (std::size_t i = 0; i < owned_rows.size(); ++i)
      for (int c = 0; c < 3; ++c) x[3 * owned_rows[i] + c] = positions[3 * i + c];
    return;
  }
  x = part_values(comm, positions, 3);
}

std::vector<double> DistributedBd::Halo::part_values(const Communicator& comm, std::span<const double> owned,
                                                     std::size_t per) const {
  std::vector<double> part(per * ids.size());
  for (std::size_t i = 0; i < owned_rows.size(); ++i)
    std::copy(&owned[per * i], &owned[per * i] + per, &part[per * owned_rows[i]]);
  if (!exchanges) return part;
  std::vector<std::vector<double>> packed(send.size());
  for (std::size_t r = 0; r < send.size(); ++r) {
    packed[r].reserve(per * send[r].size());
    for (const std::uint32_t i : send[r]) packed[r].insert(packed[r].end(), &owned[per * i], &owned[per * i] + per);
  }
  std::vector<std::size_t> counts(recv_counts);
  for (std::size_t& c : counts) c *= per;
  const std::vector<double> received = detail::alltoallv(comm, packed, counts, "DistributedBd", "the halo's values");
  for (std::size_t k = 0; k < halo_rows.size(); ++k)
    std::copy(&received[per * k], &received[per * k] + per, &part[per * halo_rows[k]]);
  return part;
}

std::vector<double> DistributedBd::Halo::row_lengths() const {
  std::vector<double> lengths(owned_rows.size(), 0.0);
  if (list.size() == 0) return lengths;
  for (std::size_t i = 0; i < owned_rows.size(); ++i)
    lengths[i] = static_cast<double>(list.neighbours(owned_rows[i]).size());
  return lengths;
}

}  // namespace rpyfmm::mpi
