// rpyfmm — DistributedDirectRpy: all-gather, then the serial DirectRpy's rows of this rank (direct_operator.hpp).
#include "rpyfmm/mpi/direct_operator.hpp"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdint>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kSetPositions = "DistributedDirectRpy::set_positions";
constexpr const char* kApply = "DistributedDirectRpy::apply";

// The viscosity, once every rank has checked its own and all ranks agree on one value.
double agreed_viscosity(const Communicator& comm, double viscosity) {
  comm.run([&] { require_positive(viscosity, "DistributedDirectRpy", "viscosity"); });
  std::array<double, 2> local{viscosity, -viscosity}, global{};
  check_mpi(MPI_Allreduce(local.data(), global.data(), 2, MPI_DOUBLE, MPI_MIN, comm.get()), "MPI_Allreduce");
  require(global[0] == -global[1], ErrorCode::invalid_argument, "DistributedDirectRpy",
          "the ranks pass different viscosities (from " + format_number(global[0]) + " to " +
              format_number(-global[1]) + "); every rank must pass the same one");
  return viscosity;
}

// This rank's positions and radii as set_positions requires them (the message names no rank:
// Communicator::agree adds it).
void check_local_particles(std::span<const double> positions, std::span<const double> radii) {
  require(positions.size() % 3 == 0, ErrorCode::invalid_input, kSetPositions,
          "local positions have " + std::to_string(positions.size()) + " entries, not a multiple of 3");
  require_size(radii, positions.size() / 3, kSetPositions, "local radii");
  require_finite(positions, kSetPositions, "local positions", 3);
  for (std::size_t i = 0; i < radii.size(); ++i) {
    if (!(std::isfinite(radii[i]) && radii[i] > 0.0)) {
      fail(ErrorCode::invalid_argument, kSetPositions,
           "radius of local particle " + std::to_string(i) + " must be finite and > 0, got " + format_number(radii[i]));
    }
  }
}

}  // namespace

DistributedDirectRpy::DistributedDirectRpy(MPI_Comm comm, double viscosity)
    : comm_(comm), serial_(rpy::Geometry::open(), agreed_viscosity(comm_, viscosity)) {}

void DistributedDirectRpy::set_positions(std::span<const double> local_positions, double radius) {
  global_n_ = 0;  // no positions until this call succeeds on every rank
  // Checked first so that the message speaks of the radius, not of a radius per particle.
  comm_.run([&] { require_positive(radius, kSetPositions, "radius"); });
  const std::vector<double> radii(local_positions.size() / 3, radius);
  set_positions(local_positions, radii);
}

void DistributedDirectRpy::set_positions(std::span<const double> local_positions, std::span<const double> local_radii) {
  global_n_ = 0;  // no positions until this call succeeds on every rank
  comm_.run([&] { check_local_particles(local_positions, local_radii); });
  gather_and_set(local_positions, local_radii);
}

void DistributedDirectRpy::gather_and_set(std::span<const double> local_positions,
                                          std::span<const double> local_radii) {
  const auto ranks = static_cast<std::size_t>(comm_.size());
  // Every rank's local size.
  const auto mine = static_cast<std::uint64_t>(local_radii.size());
  std::vector<std::uint64_t> all(ranks);
  check_mpi(MPI_Allgather(&mine, 1, MPI_UINT64_T, all.data(), 1, MPI_UINT64_T, comm_.get()), "MPI_Allgather");
  std::uint64_t total = 0;
  for (std::uint64_t n : all) total += n;
  // Same values on every rank, so every rank throws alike here without agreement.
  require(total > 0, ErrorCode::invalid_input, kSetPositions,
          "no particles on any of the " + std::to_string(ranks) + " ranks (N = 0)");
  require(3 * total <= static_cast<std::uint64_t>(INT_MAX), ErrorCode::not_supported, kSetPositions,
          std::to_string(total) + " particles in all: more than MPI's int counts address (" +
              std::to_string(INT_MAX / 3) + ")");
  counts_.assign(all.begin(), all.end());
  counts3_.resize(ranks);
  displs3_.resize(ranks);
  counts1_.resize(ranks);
  displs1_.resize(ranks);
  std::size_t offset = 0;
  for (std::size_t r = 0; r < ranks; ++r) {
    counts1_[r] = static_cast<int>(counts_[r]);
    displs1_[r] = static_cast<int>(offset);
    counts3_[r] = 3 * counts1_[r];
    displs3_[r] = 3 * displs1_[r];
    offset += counts_[r];
  }
  local_n_ = counts_[static_cast<std::size_t>(comm_.rank())];
  offset_ = static_cast<std::size_t>(displs1_[static_cast<std::size_t>(comm_.rank())]);

  std::vector<double> positions(3 * total), radii(total);
  check_mpi(MPI_Allgatherv(local_positions.data(), counts3_[comm_.rank()], MPI_DOUBLE, positions.data(),
                           counts3_.data(), displs3_.data(), MPI_DOUBLE, comm_.get()),
            "MPI_Allgatherv");
  check_mpi(MPI_Allgatherv(local_radii.data(), counts1_[comm_.rank()], MPI_DOUBLE, radii.data(), counts1_.data(),
                           displs1_.data(), MPI_DOUBLE, comm_.get()),
            "MPI_Allgatherv");
  // Deterministic on the same gathered data, but a rank may still run out of memory alone.
  comm_.run([&] { serial_.set_positions(positions, radii); });
  global_n_ = total;
}

void DistributedDirectRpy::apply(std::span<const double> local_forces, std::span<double> local_velocities) const {
  // global_n_ is the same on every rank (set_positions succeeds or fails on all of them).
  require(global_n_ > 0, ErrorCode::invalid_input, kApply, "positions not set (call set_positions first)");
  comm_.run([&] {
    require_size(local_forces, 3 * local_n_, kApply, "local forces");
    require_size(std::span<const double>(local_velocities.data(), local_velocities.size()), 3 * local_n_, kApply,
                 "local velocities");
    require_finite(local_forces, kApply, "local forces", 3);
  });
  std::vector<double> forces(3 * global_n_);
  check_mpi(MPI_Allgatherv(local_forces.data(), counts3_[comm_.rank()], MPI_DOUBLE, forces.data(), counts3_.data(),
                           displs3_.data(), MPI_DOUBLE, comm_.get()),
            "MPI_Allgatherv");
  // This rank's rows only (DirectRpy::apply_rows): each target summed over all sources in
  // the serial order, with the serial load scaling, so the rows equal the serial ones bit for bit
  // and the N^2 pair work is divided by the number of ranks.
  comm_.run([&] { serial_.apply_rows(offset_, local_n_, forces, local_velocities.first(3 * local_n_)); });
}

}  // namespace rpyfmm::mpi
