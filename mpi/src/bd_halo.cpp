// rpyfmm — the halo of a rank in distributed Brownian dynamics (bd_halo.hpp).
#include "bd_halo.hpp"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "alltoallv.hpp"
#include "wrap_into_box.hpp"

namespace rpyfmm::mpi {
namespace detail {

std::array<double, 3> wrapped(const double* x, const rpy::Geometry& geometry) {
  std::array<double, 3> w{x[0], x[1], x[2]};
  if (!geometry.is_periodic()) return w;
  for (int c = 0; c < 3; ++c) w[c] = rpy::detail::wrap_into_box(w[c], geometry.box()[c]);  // as MobilityOperator
  return w;
}

RegionBox region_of(std::span<const double> positions, const rpy::Geometry& geometry) {
  RegionBox box;
  for (std::size_t i = 0; 3 * i < positions.size(); ++i) {
    const std::array<double, 3> p = wrapped(&positions[3 * i], geometry);
    for (int c = 0; c < 3; ++c) {
      box.lo[c] = box.empty ? p[c] : std::min(box.lo[c], p[c]);
      box.hi[c] = box.empty ? p[c] : std::max(box.hi[c], p[c]);
    }
    box.empty = false;
  }
  return box;
}

double distance2_to(const std::array<double, 3>& p, const RegionBox& box, const rpy::Geometry& geometry) {
  if (box.empty) return std::numeric_limits<double>::infinity();
  double d2 = 0.0;
  for (int c = 0; c < 3; ++c) {
    const auto gap = [&](double v) { return std::max({box.lo[c] - v, v - box.hi[c], 0.0}); };
    double g = gap(p[c]);
    if (geometry.is_periodic()) g = std::min({g, gap(p[c] - geometry.box()[c]), gap(p[c] + geometry.box()[c])});
    d2 += g * g;
  }
  return d2;
}

constexpr int kBoxValues = 7;  // lo, hi, empty flag

std::vector<RegionBox> gather_regions(const Communicator& comm, const RegionBox& mine) {
  std::array<double, kBoxValues> packed{
      mine.lo[0], mine.lo[1], mine.lo[2], mine.hi[0], mine.hi[1], mine.hi[2], mine.empty ? 1.0 : 0.0};
  std::vector<double> all(kBoxValues * static_cast<std::size_t>(comm.size()));
  check_mpi(MPI_Allgather(packed.data(), kBoxValues, MPI_DOUBLE, all.data(), kBoxValues, MPI_DOUBLE, comm.get()),
            "MPI_Allgather");
  std::vector<RegionBox> boxes(static_cast<std::size_t>(comm.size()));
  for (std::size_t r = 0; r < boxes.size(); ++r) {
    const double* v = &all[kBoxValues * r];
    boxes[r] = {{v[0], v[1], v[2]}, {v[3], v[4], v[5]}, v[6] != 0.0};
  }
  return boxes;
}

std::vector<std::vector<std::uint32_t>> select_halo(const Communicator& comm, std::span<const double> positions,
                                                    const std::vector<RegionBox>& regions,
                                                    const rpy::Geometry& geometry, double list_radius) {
  std::vector<std::vector<std::uint32_t>> send(regions.size());
  if (list_radius <= 0.0) return send;
  const double reach = list_radius * (1.0 + 1e-12);
  const double reach2 = reach * reach;
  for (std::size_t i = 0; 3 * i < positions.size(); ++i) {
    const std::array<double, 3> p = wrapped(&positions[3 * i], geometry);
    for (std::size_t r = 0; r < regions.size(); ++r) {
      if (static_cast<int>(r) == comm.rank()) continue;
      if (distance2_to(p, regions[r], geometry) <= reach2) send[r].push_back(static_cast<std::uint32_t>(i));
    }
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
                                               const rpy::Geometry& geometry, const bd::NeighbourOptions& neighbours,
                                               std::span<const double> positions, std::span<const std::uint32_t> types,
                                               std::span<const std::uint64_t> ids) {
  Halo h{.list = bd::NeighbourList(geometry, forces.max_cutoff(), neighbours), .pairs = forces.has_pairs()};
  const double list_radius = h.pairs ? h.list.list_radius() : 0.0;
  const std::vector<RegionBox> regions = detail::gather_regions(comm, detail::region_of(positions, geometry));
  h.send = detail::select_halo(comm, positions, regions, geometry, list_radius);
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
  if (h.pairs) {
    h.list.set_pair_cutoffs(h.types, forces.pair_cutoffs(), forces.types().size());
    h.list.build(h.x);
  }
  return h;
}

void DistributedBd::Halo::refresh(const Communicator& comm, std::span<const double> positions) {
  for (std::size_t i = 0; i < owned_rows.size(); ++i)
    for (int c = 0; c < 3; ++c) x[3 * owned_rows[i] + c] = positions[3 * i + c];
  if (!pairs) return;  // no pair potential (the same force field on every rank): no halo anywhere
  std::vector<std::vector<double>> packed(send.size());
  for (std::size_t r = 0; r < send.size(); ++r) {
    packed[r].reserve(3 * send[r].size());
    for (const std::uint32_t i : send[r]) packed[r].insert(packed[r].end(), &positions[3 * i], &positions[3 * i + 3]);
  }
  std::vector<std::size_t> counts(recv_counts);
  for (std::size_t& c : counts) c *= 3;
  const std::vector<double> received = detail::alltoallv(comm, packed, counts, "DistributedBd", "the halo's positions");
  for (std::size_t k = 0; k < halo_rows.size(); ++k)
    for (int c = 0; c < 3; ++c) x[3 * halo_rows[k] + c] = received[3 * k + c];
}

std::vector<double> DistributedBd::Halo::row_lengths() const {
  std::vector<double> lengths(owned_rows.size(), 0.0);
  if (list.size() == 0) return lengths;
  for (std::size_t i = 0; i < owned_rows.size(); ++i)
    lengths[i] = static_cast<double>(list.neighbours(owned_rows[i]).size());
  return lengths;
}

}  // namespace rpyfmm::mpi
