// rpyfmm — the bead force field of DistributedRigidBodyDynamics over each rank's part of the system
// (rigid_bead_forces.hpp).
#include "rigid_bead_forces.hpp"

#include <mpi.h>

#include <algorithm>
#include <cstddef>
#include <numeric>
#include <string>
#include <utility>

#include "bd_gather.hpp"
#include "bd_halo.hpp"
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

/// Not collective: the serial field's checks (ForceField::check) of this rank's beads' types, named
/// by their global indices, and of the bonds' ends against all beads.
void check_types_and_bonds(const bd::ForceField& field, std::span<const std::uint32_t> types, std::uint64_t first_bead,
                           std::uint64_t total) {
  for (std::size_t i = 0; i < types.size(); ++i)
    require(types[i] < field.types().size(), ErrorCode::invalid_input, "particles",
            "particle " + std::to_string(first_bead + i) + " has type index " + std::to_string(types[i]) +
                " but only " + std::to_string(field.types().size()) + " types are defined");
  for (const bd::Bond& b : field.bonds())
    require(b.i < total && b.j < total && b.type < field.bond_potentials().size(), ErrorCode::invalid_input, "bonds",
            "bond " + std::to_string(b.i) + "-" + std::to_string(b.j) +
                " refers to a bead beyond N = " + std::to_string(total) + " or to an unknown bond potential");
}

/// Collective: the sum of every rank's `values` in the global order, the ranks' values in rank order
/// (a running sum passed from rank to rank, then broadcast), so the bits of one sum over all values.
double sum_in_rank_order(const Communicator& comm, std::span<const double> values) {
  double running = 0.0;
  const int rank = comm.rank(), last = comm.size() - 1;
  if (rank > 0) check_mpi(MPI_Recv(&running, 1, MPI_DOUBLE, rank - 1, 0, comm.get(), MPI_STATUS_IGNORE), "MPI_Recv");
  for (const double v : values) running += v;
  if (rank < last) check_mpi(MPI_Send(&running, 1, MPI_DOUBLE, rank + 1, 0, comm.get()), "MPI_Send");
  check_mpi(MPI_Bcast(&running, 1, MPI_DOUBLE, last, comm.get()), "MPI_Bcast");
  return running;
}

}  // namespace

RigidBeadForces::RigidBeadForces(const Communicator& comm, bd::ForceField field, std::vector<std::uint32_t> local_types,
                                 const RankBeads& beads, const rpy::Geometry& geometry,
                                 const bd::NeighbourOptions& neighbours, const char* where)
    : field_(field.without_callbacks()),
      callbacks_(field.callbacks().begin(), field.callbacks().end()),
      bonds_({}, 0),
      geometry_(geometry),
      neighbours_(neighbours),
      total_(beads.total_beads),
      where_(where) {
  require_same_field(comm, field, neighbours, where);
  const std::size_t n = beads.offsets.back();
  comm.run([&] {
    if (local_types.empty()) local_types.assign(n, 0u);
    require(local_types.size() == n, ErrorCode::invalid_input, where,
            "bead types have " + std::to_string(local_types.size()) + " entries for " + std::to_string(n) +
                " beads of this rank (expected n_local, or none for type 0)");
    check_types_and_bonds(field_, local_types, beads.first_bead, total_);
    // The serial engine's list refusals (a box smaller than twice the list radius), on every rank.
    const bd::NeighbourList list(geometry, field_.max_cutoff(), neighbours);
    bonds_ = BondIndex(field_.bonds(), total_);
  });
  types_ = std::move(local_types);
  ids_.resize(n);
  std::iota(ids_.begin(), ids_.end(), std::uint64_t(beads.first_bead));
  bodies_.resize(n);
  for (std::size_t k = 0; k + 1 < beads.offsets.size(); ++k)
    for (std::size_t i = beads.offsets[k]; i < beads.offsets[k + 1]; ++i) bodies_[i] = double(beads.first_body + k);
  energies_.assign(n, 0.0);
}

RigidBeadForces::~RigidBeadForces() = default;

bool RigidBeadForces::rebuild_due(const Communicator& comm, std::span<const double> local_positions) const {
  if (!halo_) return true;
  if (!halo_->pairs) return false;  // the bond partners do not change: the halo stays
  if (neighbours_.fixed_interval > 0) return steps_since_build_ >= std::uint64_t(neighbours_.fixed_interval);
  // bd::NeighbourList::update's test (Tran et al. (2015), Algorithm 1, line 15) over all beads.
  const double limit2 = 0.25 * skin_ * skin_;
  int moved = 0;
  for (std::size_t i = 0; i < ids_.size() && moved == 0; ++i) {
    double d2 = 0.0;
    for (int c = 0; c < 3; ++c) {
      const double d = local_positions[3 * i + c] - reference_[3 * i + c];
      d2 += d * d;
    }
    moved = d2 > limit2 ? 1 : 0;
  }
  int any = 0;
  check_mpi(MPI_Allreduce(&moved, &any, 1, MPI_INT, MPI_MAX, comm.get()), "MPI_Allreduce");
  return any != 0;
}

void RigidBeadForces::rebuild(const Communicator& comm, std::span<const double> local_positions) {
  halo_ = std::make_unique<DistributedBd::Halo>(
      DistributedBd::Halo::build(comm, field_, bonds_, geometry_, neighbours_, local_positions, types_, ids_, total_));
  skin_ = halo_->list.skin();
  const std::vector<double> bodies = halo_->part_values(comm, bodies_, 1);
  part_bodies_.assign(bodies.size(), 0u);
  std::transform(bodies.begin(), bodies.end(), part_bodies_.begin(),
                 [](double b) { return static_cast<std::uint32_t>(b); });
  reference_.assign(local_positions.begin(), local_positions.end());
  steps_since_build_ = 0;
}

RigidBeadForces::Result RigidBeadForces::compute(const Communicator& comm, std::span<const double> local_positions,
                                                 std::uint64_t step, std::span<double> forces) {
  Result result;
  result.rebuilt = rebuild_due(comm, local_positions);
  if (result.rebuilt) {
    rebuild(comm, local_positions);
  } else {
    halo_->refresh(comm, local_positions);
    ++steps_since_build_;
  }
  comm.run([&] {
    const bd::ForceField& part = halo_->part_forces ? *halo_->part_forces : field_;  // bonds as part rows
    part.compute_rows(halo_->x, halo_->types, halo_->list, step, halo_->owned_rows, halo_->ids, forces, energies_,
                      part_bodies_);
  });
  result.energy = sum_in_rank_order(comm, energies_);
  if (!callbacks_.empty()) add_callback_forces(comm, local_positions, step, forces);
  return result;
}

void RigidBeadForces::add_callback_forces(const Communicator& comm, std::span<const double> local_positions,
                                          std::uint64_t step, std::span<double> forces) const {
  // ForceField::compute calls the callbacks last, on the whole system's positions and the forces of
  // the other terms: both gathered in the global bead order (x then f per bead, one MPI_Allgatherv).
  std::vector<double> mine(6 * ids_.size());
  for (std::size_t i = 0; i < ids_.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      mine[6 * i + c] = local_positions[3 * i + c];
      mine[6 * i + 3 + c] = forces[3 * i + c];
    }
  const std::vector<double> all = gather_by_index(comm, ids_, mine, total_, 6, kEveryRank, where_);
  std::vector<double> x(3 * total_), f(3 * total_);
  for (std::size_t i = 0; i < total_; ++i)
    for (int c = 0; c < 3; ++c) {
      x[3 * i + c] = all[6 * i + c];
      f[3 * i + c] = all[6 * i + 3 + c];
    }
  comm.run([&] {  // a callback that throws on one rank fails every rank
    for (const bd::ForceCallback& callback : callbacks_) callback(x, step, f);
  });
  if (!ids_.empty())
    std::copy(f.begin() + std::ptrdiff_t(3 * ids_.front()),
              f.begin() + std::ptrdiff_t(3 * ids_.front() + forces.size()), forces.begin());
}

}  // namespace rpyfmm::mpi::detail
