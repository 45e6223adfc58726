// rpyfmm — DistributedRigidBodyDynamics: bd::RigidBodyDynamics's step on each rank's whole bodies
// with the solves across the ranks (rpyfmm/mpi/rigid_dynamics.hpp).
#include "rpyfmm/mpi/rigid_dynamics.hpp"

#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <type_traits>
#include <utility>

#include "rigid/rigid_stages.hpp"
#include "rigid_bead_forces.hpp"
#include "rpyfmm/bd/quaternion.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/sqrt.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "DistributedRigidBodyDynamics";

/// The options' numbers for the check that every rank passes the same (64-bit counters in two
/// halves, each exact as a double).
std::vector<double> option_values(const bd::RigidDynamicsOptions& o) {
  const auto halves = [](std::uint64_t v) { return std::pair{double(v >> 32), double(v & 0xffffffffu)}; };
  const auto [seed_hi, seed_lo] = halves(o.seed);
  const auto [step_hi, step_lo] = halves(o.first_step);
  return {o.dt,
          o.kT,
          seed_hi,
          seed_lo,
          step_hi,
          step_lo,
          o.drift == bd::RigidDrift::none ? 0.0 : 1.0,
          o.rfd_delta,
          o.max_displacement};
}

/// This rank's bodies and beads, checked as the serial engine checks all of them (a rank may hold
/// none). Spreads one radius over the beads and normalizes the orientations.
void check_local_bodies(const std::vector<double>& shape, std::vector<double>& radii,
                        const std::vector<std::size_t>& offsets, const std::vector<double>& positions,
                        std::vector<double>& orientations) {
  require(shape.size() % 3 == 0, ErrorCode::invalid_input, kWhere,
          "the body-frame shape has " + std::to_string(shape.size()) + " entries (expected 3 per bead)");
  const std::size_t n = shape.size() / 3;
  require_finite(shape, kWhere, "shape", 3);
  if (radii.size() == 1) radii.assign(n, radii[0]);
  require(radii.size() == n, ErrorCode::invalid_input, kWhere,
          "radii have " + std::to_string(radii.size()) + " entries for " + std::to_string(n) +
              " beads (expected one or n_local)");
  require(!offsets.empty() && offsets.front() == 0 && offsets.back() == n, ErrorCode::invalid_input, kWhere,
          "body offsets must have m_local + 1 entries from 0 to the number of this rank's beads " + std::to_string(n));
  const std::size_t m = offsets.size() - 1;
  require(positions.size() == 3 * m, ErrorCode::invalid_input, kWhere,
          "positions have " + std::to_string(positions.size()) + " entries for " + std::to_string(m) +
              " bodies (expected 3 per body)");
  require_finite(positions, kWhere, "positions", 3);
  orientations = bd::quaternion::checked(std::move(orientations), m, kWhere, "body");
}

/// The global index of this rank's first item (the ranks' items in rank order) and the total.
std::pair<std::size_t, std::size_t> first_and_total(const Communicator& comm, std::size_t local) {
  const auto mine = static_cast<std::uint64_t>(local);
  std::vector<std::uint64_t> counts(static_cast<std::size_t>(comm.size()));
  check_mpi(MPI_Allgather(&mine, 1, MPI_UINT64_T, counts.data(), 1, MPI_UINT64_T, comm.get()), "MPI_Allgather");
  std::size_t first = 0, total = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    if (r == static_cast<std::size_t>(comm.rank())) first = total;
    total += counts[r];
  }
  return {first, total};
}

}  // namespace

DistributedRigidBodyDynamics::DistributedRigidBodyDynamics(
    Operator beads, const Communicator& comm, std::vector<double> local_shape, std::vector<double> local_radii,
    std::vector<std::size_t> local_body_offsets, std::vector<double> local_positions,
    std::vector<double> local_orientations, bd::RigidDynamicsOptions options, bd::BodyForceFunction forces)
    : comm_(comm),
      forces_(std::move(forces)),
      shape_(std::move(local_shape)),
      radii_(std::move(local_radii)),
      offsets_(std::move(local_body_offsets)),
      q_(std::move(local_positions)),
      quat_(std::move(local_orientations)),
      step_(options.first_step) {
  comm_.run([&] { options_ = bd::rigid_detail::checked_options(options, kWhere); });
  comm_.run([&] {
    require(same_on_every_rank(comm_, option_values(options)), ErrorCode::invalid_argument, kWhere,
            "the ranks pass different options (dt, kT, seed, first_step, drift, rfd_delta, max_displacement must "
            "agree)");
  });
  comm_.run([&] { check_local_bodies(shape_, radii_, offsets_, q_, quat_); });
  std::tie(first_body_, total_bodies_) = first_and_total(comm_, local_bodies());
  std::tie(first_bead_, total_beads_) = first_and_total(comm_, local_beads());
  comm_.run([&] { require(total_bodies_ > 0, ErrorCode::invalid_input, kWhere, "no body on any rank"); });
  comm_.run([&] { lever_ = bd::rigid_detail::lever_arms(shape_, offsets_, first_body_, kWhere); });
  const std::size_t m = local_bodies(), n = local_beads();
  for (auto* v : {&w_, &y_, &drift_, &rfd_w_, &rfd_v_, &rfd_plus_, &rfd_minus_}) v->assign(6 * m, 0.0);
  z_.assign(3 * n, 0.0);
  rfd_lambda_.assign(3 * n, 0.0);
  bd::rigid_detail::place_beads(shape_, offsets_, q_, quat_, beads_now_);
  std::visit(
      [&](auto* op) {
        solver_ = std::make_unique<DistributedRigidBodies>(*op, options_.solver);
        rfd_solver_ = std::make_unique<DistributedRigidBodies>(*op, bd::rigid_detail::rfd_options(options_));
        if constexpr (std::is_same_v<decltype(op), DistributedPseRpy*>) geometry_ = op->geometry();
      },
      beads);
  // Plans once: DistributedRigidBodies refuses bad bodies (collinear, coincident beads, radii) here.
  solver_->set_configuration(beads_now_, radii_, offsets_, q_);
}

DistributedRigidBodyDynamics::~DistributedRigidBodyDynamics() = default;

void DistributedRigidBodyDynamics::set_bead_forces(bd::ForceField field, std::vector<std::uint32_t> local_bead_types,
                                                   bd::NeighbourOptions neighbours) {
  const detail::RankBeads beads{first_body_, first_bead_, total_beads_, offsets_};
  bead_field_ = std::make_unique<detail::RigidBeadForces>(comm_, std::move(field), std::move(local_bead_types), beads,
                                                          geometry_, neighbours, kWhere);
  bead_forces_.assign(3 * local_beads(), 0.0);
}

void DistributedRigidBodyDynamics::gather_forces_and_torques() {
  std::fill(w_.begin(), w_.end(), 0.0);
  if (forces_) {
    comm_.run([&] {
      forces_(bd::RigidBodyState{time(), q_, quat_, beads_now_}, w_);
      bd::rigid_detail::require_finite_loads(w_, step_, first_body_, kWhere);
    });
  }
  if (bead_field_) {
    const detail::RigidBeadForces::Result result = bead_field_->compute(comm_, beads_now_, step_, bead_forces_);
    report_.neighbour_rebuild = result.rebuilt;
    report_.potential_energy = result.energy;
    bd::rigid_detail::add_bead_loads(offsets_, beads_now_, q_, bead_forces_, w_);
  }
}

void DistributedRigidBodyDynamics::solve_velocities() {
  StopWatch watch;
  solver_->set_configuration(beads_now_, radii_, offsets_, q_);
  totals_.seconds["plan"] += watch.seconds();
  if (options_.kT > 0.0) fill_normal(z_, first_bead_, options_.seed, step_, 0);  // the serial z of this rank's beads
  bd::rigid_detail::solve_velocities(*solver_, w_, z_, y_, options_, report_, totals_);
}

int DistributedRigidBodyDynamics::perturbed_solve(double sign, std::span<double> out, bool warm) {
  bd::rigid_detail::perturb(q_, quat_, lever_, rfd_w_, 0.5 * sign * options_.rfd_delta, q_work_, quat_work_, rfd_v_);
  bd::rigid_detail::place_beads(shape_, offsets_, q_work_, quat_work_, beads_work_);
  rfd_solver_->set_configuration(beads_work_, radii_, offsets_, q_work_);
  if (!warm) return rfd_solver_->apply(rfd_v_, out, rfd_lambda_).iterations;
  // The other side's solution is within O(delta) of this one: start GMRES from it.
  return rfd_solver_->apply_from(rfd_v_, rfd_plus_, rfd_lambda_, out).iterations;
}

void DistributedRigidBodyDynamics::estimate_drift() {
  std::fill(drift_.begin(), drift_.end(), 0.0);
  if (options_.kT > 0.0 && options_.drift == bd::RigidDrift::random_finite_difference) {
    StopWatch watch;
    // The serial w (6m entries: two triples per body) of this rank's bodies.
    fill_normal(rfd_w_, 2 * first_body_, options_.seed, step_, 1);
    int iterations = perturbed_solve(+1.0, rfd_plus_, false);
    iterations += perturbed_solve(-1.0, rfd_minus_, true);
    bd::rigid_detail::rfd_difference(rfd_plus_, rfd_minus_, options_.rfd_delta, drift_);
    for (double& d : drift_) d *= options_.kT;
    report_.drift_iterations = iterations;
    totals_.seconds["drift"] += watch.seconds();
  }
}

void DistributedRigidBodyDynamics::update_bodies() {
  // Every rank checks its bodies before any rank commits: a refusal on one keeps all at the last step.
  comm_.run([&] {
    bd::rigid_detail::advance(q_, quat_, lever_, y_, drift_, options_, step_, first_body_, q_work_, quat_work_, kWhere);
  });
  q_.swap(q_work_);
  quat_.swap(quat_work_);
  bd::rigid_detail::place_beads(shape_, offsets_, q_, quat_, beads_now_);
}

const bd::RigidStepReport& DistributedRigidBodyDynamics::step() {
  report_ = {};
  bd::rigid_detail::take_step(
      report_, totals_, [this] { gather_forces_and_torques(); }, [this] { solve_velocities(); },
      [this] { estimate_drift(); },
      [this] {
        update_bodies();  // checked on every rank before any commits
        ++step_;
      });
  return report_;
}

void DistributedRigidBodyDynamics::run(std::uint64_t count) {
  for (std::uint64_t i = 0; i < count; ++i) step();
}

}  // namespace rpyfmm::mpi
