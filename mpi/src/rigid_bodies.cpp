// rpyfmm — DistributedRigidBodies: the serial rigid-body solve (rpy/src/rigid/body_system.hpp) on
// each rank's whole bodies, the bead products and the inner products across the ranks
// (rpyfmm/mpi/rigid_bodies.hpp).
#include "rpyfmm/mpi/rigid_bodies.hpp"

#include <mpi.h>

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <string>
#include <vector>

#include "bd_gather.hpp"
#include "rigid/body_system.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/sqrt.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "DistributedRigidBodies";

/// The options' numbers, for the check that every rank passes the same.
std::vector<double> option_values(const rpy::RigidBodyOptions& o) {
  return {o.tolerance, double(o.max_iterations), double(o.restart), o.precondition ? 1.0 : 0.0,
          double(o.max_preconditioner_bytes)};
}

/// <a, b> over the vectors of all ranks: each rank's sequential sum over its own entries, the
/// ranks' sums gathered and added in rank order on every rank, so every rank gets the same value.
rpy::rigid_detail::InnerProduct global_inner_product(const Communicator& comm) {
  return [&comm](const double* a, const double* b, std::size_t n) {
    const double mine = rpy::rigid_detail::sequential_dot(a, b, n);
    std::vector<double> sums(static_cast<std::size_t>(comm.size()));
    check_mpi(MPI_Allgather(&mine, 1, MPI_DOUBLE, sums.data(), 1, MPI_DOUBLE, comm.get()), "MPI_Allgather");
    double total = 0.0;
    for (const double s : sums) total += s;
    return total;
  };
}

/// This rank's bodies in the global body order (the ranks' bodies in rank order): its first global
/// index, their global indices, and the number of bodies on all ranks.
struct BodyIndex {
  std::size_t first = 0, total = 0;
  std::vector<std::uint64_t> ids;
};

BodyIndex body_index(const Communicator& comm, std::size_t local_bodies) {
  const auto mine = static_cast<std::uint64_t>(local_bodies);
  std::vector<std::uint64_t> counts(static_cast<std::size_t>(comm.size()));
  check_mpi(MPI_Allgather(&mine, 1, MPI_UINT64_T, counts.data(), 1, MPI_UINT64_T, comm.get()), "MPI_Allgather");
  BodyIndex index;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    if (r == static_cast<std::size_t>(comm.rank())) index.first = index.total;
    index.total += counts[r];
  }
  index.ids.resize(local_bodies);
  std::iota(index.ids.begin(), index.ids.end(), std::uint64_t{index.first});
  return index;
}

/// The bead operator's geometry, in which the lever arms are minimum images: DistributedPseRpy's
/// periodic box, open space for the others (as RigidBodies takes MobilityOperator::geometry()).
rpy::Geometry bead_geometry(const DistributedDirectRpy&) {
  return rpy::Geometry::open();
}
rpy::Geometry bead_geometry(const DistributedFmmRpy&) {
  return rpy::Geometry::open();
}
rpy::Geometry bead_geometry(const DistributedPseRpy& op) {
  return op.geometry();
}

/// B z (B B^T = M) across the ranks, as RigidBodies::apply_with_noise takes it from the serial
/// operator's apply_sqrt: mpi::sqrt_apply's samplers for the direct and FMM operators, the split
/// sampler of DistributedPseRpy::apply_sqrt (PseRpy::apply_sqrt's) for PSE.
rpy::SqrtReport bead_sqrt(const DistributedDirectRpy& op, std::span<const double> z, std::span<double> w,
                          const rpy::SqrtOptions& options) {
  return sqrt_apply(op, z, w, options);
}
rpy::SqrtReport bead_sqrt(const DistributedFmmRpy& op, std::span<const double> z, std::span<double> w,
                          const rpy::SqrtOptions& options) {
  return sqrt_apply(op, z, w, options);
}
rpy::SqrtReport bead_sqrt(const DistributedPseRpy& op, std::span<const double> z, std::span<double> w,
                          const rpy::SqrtOptions& options) {
  return op.apply_sqrt(z, w, options);
}

}  // namespace

DistributedRigidBodies::DistributedRigidBodies(DistributedDirectRpy& beads, rpy::RigidBodyOptions options)
    : DistributedRigidBodies(Operator(&beads), beads.communicator(), options) {}

DistributedRigidBodies::DistributedRigidBodies(DistributedFmmRpy& beads, rpy::RigidBodyOptions options)
    : DistributedRigidBodies(Operator(&beads), beads.communicator(), options) {}

DistributedRigidBodies::DistributedRigidBodies(DistributedPseRpy& beads, rpy::RigidBodyOptions options)
    : DistributedRigidBodies(Operator(&beads), beads.communicator(), options) {}

DistributedRigidBodies::DistributedRigidBodies(Operator beads, const Communicator& comm, rpy::RigidBodyOptions options)
    : beads_(beads), comm_(comm), options_(options) {
  comm_.run([&] { rpy::rigid_detail::require_options(options, kWhere); });
  comm_.run([&] {
    require(same_on_every_rank(comm_, option_values(options)), ErrorCode::invalid_argument, kWhere,
            "the ranks pass different options (tolerance, max_iterations, restart, precondition, "
            "max_preconditioner_bytes must agree)");
  });
}

DistributedRigidBodies::~DistributedRigidBodies() = default;

std::size_t DistributedRigidBodies::local_bodies() const {
  return system_ ? system_->bodies() : 0;
}
std::size_t DistributedRigidBodies::local_beads() const {
  return system_ ? system_->beads() : 0;
}

std::span<const double> DistributedRigidBodies::local_reference_points() const {
  return system_ ? std::span<const double>(system_->reference) : std::span<const double>();
}

void DistributedRigidBodies::set_configuration(std::span<const double> local_bead_positions,
                                               std::span<const double> local_radii,
                                               std::span<const std::size_t> local_body_offsets,
                                               std::span<const double> local_reference_points) {
  StopWatch watch;
  system_.reset();  // unconfigured on every rank until everything below succeeds on every rank
  comm_.run([&] {
    rpy::rigid_detail::require_bodies(local_bead_positions, local_radii.size(), local_body_offsets,
                                      local_reference_points, options_, true, kWhere);
  });
  // Collective; validates positions and radii on every rank (NaN/Inf, radius <= 0, no bead at all).
  std::visit([&](auto* op) { op->set_positions(local_bead_positions, local_radii); }, beads_);
  const double eta = std::visit([](auto* op) { return op->viscosity(); }, beads_);
  const rpy::Geometry geometry = std::visit([](auto* op) { return bead_geometry(*op); }, beads_);
  // The largest radius over all ranks: every rank solves in the same units (the mobility scale).
  const double local_largest = local_radii.empty() ? 0.0 : std::ranges::max(local_radii);
  double largest = 0.0;
  check_mpi(MPI_Allreduce(&local_largest, &largest, 1, MPI_DOUBLE, MPI_MAX, comm_.get()), "MPI_Allreduce");
  std::shared_ptr<const rpy::rigid_detail::BodySystem> system;
  comm_.run([&] {
    system = std::make_shared<const rpy::rigid_detail::BodySystem>(rpy::rigid_detail::make_body_system(
        local_bead_positions, local_radii, local_body_offsets, local_reference_points, geometry, eta, largest,
        options_.precondition, kWhere));
  });
  system_ = std::move(system);
  seconds_setup_ = watch.seconds();
}

void DistributedRigidBodies::check_call(std::span<const double> local_forces_torques,
                                        std::span<double> local_velocities, std::span<double> local_bead_forces) const {
  comm_.run([&] {
    require(system_ != nullptr, ErrorCode::invalid_input, kWhere, "apply before set_configuration");
    rpy::rigid_detail::require_call(*system_, local_forces_torques, local_velocities, local_bead_forces, kWhere);
  });
}

rpy::RigidBodyReport DistributedRigidBodies::solve(std::span<const double> local_forces_torques, std::vector<double>& b,
                                                   std::span<double> local_velocities,
                                                   std::span<double> local_bead_forces,
                                                   std::span<const double> local_guess_velocities,
                                                   std::span<const double> local_guess_bead_forces) const {
  StopWatch watch;
  const rpy::rigid_detail::BeadProduct product = [this](std::span<const double> x, std::span<double> y) {
    std::visit([&](auto* op) { op->apply(x, y); }, beads_);  // collective
  };
  const rpy::rigid_detail::SaddleSolution solution = rpy::rigid_detail::solve_saddle_point(
      *system_, product, options_, local_forces_torques, b, local_guess_velocities, local_guess_bead_forces,
      global_inner_product(comm_));
  rpy::RigidBodyReport report;
  // GMRES's decisions follow the global inner products, so convergence is the same on every rank;
  // a non-finite result on one rank fails all.
  comm_.run([&] {
    report = rpy::rigid_detail::finish_solve(*system_, solution, options_, local_velocities, local_bead_forces, kWhere);
  });
  report.seconds_setup = seconds_setup_;
  report.seconds_solve = watch.seconds();
  return report;
}

rpy::RigidBodyReport DistributedRigidBodies::apply(std::span<const double> local_forces_torques,
                                                   std::span<double> local_velocities,
                                                   std::span<double> local_bead_forces) const {
  check_call(local_forces_torques, local_velocities, local_bead_forces);
  std::vector<double> b(3 * system_->beads() + 6 * system_->bodies(), 0.0);  // no slip
  return solve(local_forces_torques, b, local_velocities, local_bead_forces);
}

rpy::RigidBodyReport DistributedRigidBodies::apply_from(std::span<const double> local_forces_torques,
                                                        std::span<const double> local_guess_velocities,
                                                        std::span<const double> local_guess_bead_forces,
                                                        std::span<double> local_velocities,
                                                        std::span<double> local_bead_forces) const {
  check_call(local_forces_torques, local_velocities, local_bead_forces);
  comm_.run(
      [&] { rpy::rigid_detail::require_guesses(*system_, local_guess_velocities, local_guess_bead_forces, kWhere); });
  // A rank without bodies passes empty guesses and starts from its (empty) zero share; the bead
  // product of the initial residual is collective on every rank alike (gmres.hpp).
  std::vector<double> b(3 * system_->beads() + 6 * system_->bodies(), 0.0);  // no slip
  return solve(local_forces_torques, b, local_velocities, local_bead_forces, local_guess_velocities,
               local_guess_bead_forces);
}

std::vector<double> DistributedRigidBodies::mobility_matrix(std::size_t max_bodies) const {
  comm_.run([&] {
    require(system_ != nullptr, ErrorCode::invalid_input, kWhere, "mobility_matrix before set_configuration");
  });
  comm_.run([&] {
    require(same_on_every_rank(comm_, {double(max_bodies)}), ErrorCode::invalid_argument, kWhere,
            "the ranks pass different max_bodies");
  });
  const BodyIndex index = body_index(comm_, system_->bodies());
  comm_.run([&] { rpy::rigid_detail::require_matrix_bodies(index.total, max_bodies, kWhere); });
  const std::size_t m_local = system_->bodies();
  std::vector<double> unit(6 * m_local, 0.0), local(6 * m_local);
  return rpy::rigid_detail::symmetric_mobility_matrix(6 * index.total, [&](std::size_t c, std::span<double> column) {
    // Column c: a unit force or torque on entry c of the global order, on the rank holding it.
    const bool mine = c >= 6 * index.first && c < 6 * (index.first + m_local);
    if (mine) unit[c - 6 * index.first] = 1.0;
    apply(unit, local);
    if (mine) unit[c - 6 * index.first] = 0.0;
    const std::vector<double> all =
        detail::gather_by_index(comm_, index.ids, local, index.total, 6, detail::kEveryRank, kWhere);
    std::copy(all.begin(), all.end(), column.begin());
  });
}

rpy::RigidBodyReport DistributedRigidBodies::apply_with_noise(std::span<const double> local_forces_torques,
                                                              double noise_scale, std::span<const double> local_z,
                                                              std::span<double> local_velocities,
                                                              const rpy::SqrtOptions& sqrt_options,
                                                              std::span<double> local_bead_forces) const {
  check_call(local_forces_torques, local_velocities, local_bead_forces);
  const std::size_t n3 = 3 * system_->beads();
  comm_.run([&] { rpy::rigid_detail::require_noise(*system_, local_z, noise_scale, kWhere); });
  comm_.run([&] {
    require(same_on_every_rank(comm_, {noise_scale}), ErrorCode::invalid_argument, kWhere,
            "the ranks pass different noise scales");
  });
  StopWatch watch;
  // The random slip s = -c B z of RigidBodies::apply_with_noise (Sprinkle, Balboa Usabiaga,
  // Patankar & Donev, J. Chem. Phys. 147, 244103 (2017)), B z across the ranks.
  std::vector<double> b(n3 + 6 * system_->bodies(), 0.0), w(n3);
  const rpy::SqrtReport sqrt_report =
      std::visit([&](auto* op) { return bead_sqrt(*op, local_z, w, sqrt_options); }, beads_);
  for (std::size_t i = 0; i < n3; ++i) b[i] = -noise_scale * w[i];
  const double seconds_sqrt = watch.seconds();
  rpy::RigidBodyReport report = solve(local_forces_torques, b, local_velocities, local_bead_forces);
  report.sqrt = sqrt_report;
  report.seconds_sqrt = seconds_sqrt;
  return report;
}

}  // namespace rpyfmm::mpi
