// rpyfmm — the bead force field of DistributedRigidBodyDynamics over the whole system's beads
// (rigid_bead_forces.hpp).
#include "rigid_bead_forces.hpp"

#include <algorithm>
#include <cstddef>
#include <numeric>
#include <string>
#include <utility>

#include "bd_gather.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi::detail {
namespace {

/// The numbers of a field and its neighbour options that every rank must pass alike, a fixed count
/// whatever the field (the pair cut-offs follow once the type counts agree).
std::vector<double> field_summary(const bd::ForceField& field, const bd::NeighbourOptions& neighbours) {
  const auto& g = field.global_force();
  return {double(field.types().size()),
          field.max_cutoff(),
          double(field.bonds().size()),
          double(field.callbacks().size()),
          field.trap_stiffness(),
          g[0],
          g[1],
          g[2],
          neighbours.skin,
          double(neighbours.fixed_interval)};
}

/// Collective: throws on every rank unless every rank passes the same field summary and pair cut-offs.
void require_same_field(const Communicator& comm, const bd::ForceField& field, const bd::NeighbourOptions& neighbours,
                        const char* where) {
  const std::string what = "the ranks pass different bead force fields or neighbour options";
  comm.run([&] {
    require(same_on_every_rank(comm, field_summary(field, neighbours)), ErrorCode::invalid_argument, where, what);
  });
  comm.run([&] { require(same_on_every_rank(comm, field.pair_cutoffs()), ErrorCode::invalid_argument, where, what); });
}

}  // namespace

RigidBeadForces::RigidBeadForces(const Communicator& comm, bd::ForceField field, std::vector<std::uint32_t> local_types,
                                 const RankBeads& beads, const rpy::Geometry& geometry,
                                 const bd::NeighbourOptions& neighbours, const char* where)
    : field_(field.without_callbacks()), callbacks_(field.callbacks().begin(), field.callbacks().end()), where_(where) {
  require_same_field(comm, field, neighbours, where);
  const std::size_t n = beads.offsets.back();
  comm.run([&] {
    if (local_types.empty()) local_types.assign(n, 0u);
    require(local_types.size() == n, ErrorCode::invalid_input, where,
            "bead types have " + std::to_string(local_types.size()) + " entries for " + std::to_string(n) +
                " beads of this rank (expected n_local, or none for type 0)");
  });
  local_ids_.resize(n);
  std::iota(local_ids_.begin(), local_ids_.end(), std::uint64_t(beads.first_bead));
  rows_.assign(local_ids_.begin(), local_ids_.end());
  // Every bead's type and body in the global bead order (both exact as doubles).
  std::vector<double> mine(2 * n);
  for (std::size_t k = 0; k + 1 < beads.offsets.size(); ++k)
    for (std::size_t i = beads.offsets[k]; i < beads.offsets[k + 1]; ++i) {
      mine[2 * i] = double(local_types[i]);
      mine[2 * i + 1] = double(beads.first_body + k);
    }
  const std::vector<double> all = gather_by_index(comm, local_ids_, mine, beads.total_beads, 2, kEveryRank, where);
  types_.resize(beads.total_beads);
  bodies_.resize(beads.total_beads);
  for (std::size_t i = 0; i < beads.total_beads; ++i) {
    types_[i] = static_cast<std::uint32_t>(all[2 * i]);
    bodies_[i] = static_cast<std::uint32_t>(all[2 * i + 1]);
  }
  ids_.resize(beads.total_beads);
  std::iota(ids_.begin(), ids_.end(), std::uint64_t{0});
  // The same data on every rank: a refusal here is every rank's (the serial engine's checks).
  comm.run([&] {
    field_.check(types_);
    list_.emplace(geometry, field_.max_cutoff(), neighbours);
  });
  energies_.assign(n, 0.0);
}

RigidBeadForces::Result RigidBeadForces::compute(const Communicator& comm, std::span<const double> local_positions,
                                                 std::uint64_t step, std::span<double> forces) {
  x_ = gather_by_index(comm, local_ids_, local_positions, ids_.size(), 3, kEveryRank, where_);
  Result result;
  comm.run([&] {
    result.rebuilt = list_->update(x_);  // the same decision on every rank: the same positions
    field_.compute_rows(x_, types_, *list_, step, rows_, ids_, forces, energies_, bodies_);
  });
  // Every bead's force and energy in the global order: the energy summed as ForceField::compute sums
  // it, the forces for the callbacks.
  std::vector<double> mine(4 * rows_.size());
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    for (int c = 0; c < 3; ++c) mine[4 * i + c] = forces[3 * i + c];
    mine[4 * i + 3] = energies_[i];
  }
  const std::vector<double> all = gather_by_index(comm, local_ids_, mine, ids_.size(), 4, kEveryRank, where_);
  for (std::size_t i = 0; i < ids_.size(); ++i) result.energy += all[4 * i + 3];
  if (callbacks_.empty()) return result;
  std::vector<double> f(3 * ids_.size());
  for (std::size_t i = 0; i < ids_.size(); ++i)
    for (int c = 0; c < 3; ++c) f[3 * i + c] = all[4 * i + c];
  comm.run([&] {  // a callback that throws on one rank fails every rank
    for (const bd::ForceCallback& callback : callbacks_) callback(x_, step, f);
  });
  if (!rows_.empty())
    std::copy(f.begin() + std::ptrdiff_t(3 * rows_.front()),
              f.begin() + std::ptrdiff_t(3 * rows_.front() + forces.size()), forces.begin());
  return result;
}

}  // namespace rpyfmm::mpi::detail
