// rpyfmm::bd — RigidBodyDynamics: Euler-Maruyama with a random-finite-difference drift for
// rigid bodies of beads (see the header; design note 32).
#include "rpyfmm/bd/rigid_dynamics.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "rigid/rigid_stages.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/random.hpp"

namespace rpyfmm::bd {

namespace {

constexpr const char* kWhere = "RigidBodyDynamics";

rpy::MobilityOperator& checked(const std::unique_ptr<rpy::MobilityOperator>& beads) {
  require(beads != nullptr, ErrorCode::invalid_argument, kWhere, "no bead mobility operator given");
  return *beads;
}

/// The options, checked; used before the solvers are built from them.
const RigidDynamicsOptions& checked(const RigidDynamicsOptions& options) {
  return rigid_detail::checked_options(options, kWhere);
}

}  // namespace

RigidBodyDynamics::RigidBodyDynamics(std::unique_ptr<rpy::MobilityOperator> beads, std::vector<double> shape,
                                     std::vector<double> radii, std::vector<std::size_t> body_offsets,
                                     std::vector<double> positions, std::vector<double> orientations,
                                     RigidDynamicsOptions options, BodyForceFunction forces)
    : RigidBodyDynamics(checked(beads), std::move(shape), std::move(radii), std::move(body_offsets),
                        std::move(positions), std::move(orientations), options, std::move(forces)) {
  owned_ = std::move(beads);
}

RigidBodyDynamics::RigidBodyDynamics(rpy::MobilityOperator& beads, std::vector<double> shape, std::vector<double> radii,
                                     std::vector<std::size_t> body_offsets, std::vector<double> positions,
                                     std::vector<double> orientations, RigidDynamicsOptions options,
                                     BodyForceFunction forces)
    : bead_operator_(beads),
      options_(checked(options)),
      forces_(std::move(forces)),
      shape_(std::move(shape)),
      radii_(std::move(radii)),
      offsets_(std::move(body_offsets)),
      q_(std::move(positions)),
      quat_(std::move(orientations)),
      solver_(beads, options.solver),
      rfd_solver_(beads, rigid_detail::rfd_options(options)),
      step_(options.first_step) {
  require(shape_.size() % 3 == 0 && !shape_.empty(), ErrorCode::invalid_input, kWhere,
          "the body-frame shape has " + std::to_string(shape_.size()) + " entries (expected 3 per bead, N >= 3)");
  const std::size_t n = shape_.size() / 3;
  require_finite(shape_, kWhere, "shape", 3);
  if (radii_.size() == 1) radii_.assign(n, radii_[0]);
  require(radii_.size() == n, ErrorCode::invalid_input, kWhere,
          "radii have " + std::to_string(radii_.size()) + " entries for " + std::to_string(n) +
              " beads (expected one or N)");
  require(offsets_.size() >= 2 && offsets_.front() == 0 && offsets_.back() == n, ErrorCode::invalid_input, kWhere,
          "body offsets must have m + 1 >= 2 entries from 0 to the number of beads " + std::to_string(n));
  const std::size_t m = offsets_.size() - 1;
  require(q_.size() == 3 * m, ErrorCode::invalid_input, kWhere,
          "positions have " + std::to_string(q_.size()) + " entries for " + std::to_string(m) +
              " bodies (expected 3 per body)");
  require_finite(q_, kWhere, "positions", 3);
  quat_ = quaternion::checked(std::move(quat_), m, kWhere, "body");
  // Lever arms l_k (validates offsets on the way: RigidBodies below names the problem).
  lever_ = rigid_detail::lever_arms(shape_, offsets_, 0, kWhere);
  w_.assign(6 * m, 0.0);
  y_.assign(6 * m, 0.0);
  drift_.assign(6 * m, 0.0);
  z_.assign(3 * n, 0.0);
  rfd_w_.assign(6 * m, 0.0);
  rfd_v_.assign(6 * m, 0.0);
  rfd_plus_.assign(6 * m, 0.0);
  rfd_minus_.assign(6 * m, 0.0);
  rfd_lambda_.assign(3 * n, 0.0);
  place_beads(q_, quat_, beads_now_);
  // Plans once: RigidBodies refuses bad bodies (collinear, coincident beads, radii) here.
  solver_.set_configuration(beads_now_, radii_, offsets_, q_);
}

void RigidBodyDynamics::set_bead_forces(ForceField field, std::vector<std::uint32_t> bead_types,
                                        NeighbourOptions neighbours) {
  const std::size_t n = beads();
  if (bead_types.empty()) bead_types.assign(n, 0u);
  require(bead_types.size() == n, ErrorCode::invalid_input, kWhere,
          "bead types have " + std::to_string(bead_types.size()) + " entries for " + std::to_string(n) +
              " beads (expected N, or none for type 0)");
  field.check(bead_types);
  auto list = std::make_unique<NeighbourList>(bead_operator_.geometry(), field.max_cutoff(), neighbours);
  bead_body_.resize(n);
  for (std::size_t k = 0; k < bodies(); ++k)
    for (std::size_t i = offsets_[k]; i < offsets_[k + 1]; ++i) bead_body_[i] = static_cast<std::uint32_t>(k);
  bead_forces_.assign(3 * n, 0.0);
  bead_field_ = std::move(field);
  bead_types_ = std::move(bead_types);
  bead_list_ = std::move(list);
}

double RigidBodyDynamics::rfd_tolerance() const {
  return std::min(options_.solver.tolerance, 1e-3 * options_.rfd_delta);
}

void RigidBodyDynamics::place_beads(std::span<const double> positions, std::span<const double> orientations,
                                    std::vector<double>& out) const {
  rigid_detail::place_beads(shape_, offsets_, positions, orientations, out);
}

void RigidBodyDynamics::bead_forces_to_bodies(std::span<const double> bead_forces,
                                              std::span<double> forces_torques) const {
  require_size(bead_forces, shape_.size(), kWhere, "bead forces");
  require_size(forces_torques, 6 * bodies(), kWhere, "forces_torques");
  rigid_detail::add_bead_loads(offsets_, beads_now_, q_, bead_forces, forces_torques);
}

int RigidBodyDynamics::perturbed_solve(rpy::RigidBodies& solver, std::span<const double> w, double sign,
                                       std::span<double> out, bool warm) {
  rigid_detail::perturb(q_, quat_, lever_, w, 0.5 * sign * options_.rfd_delta, q_work_, quat_work_, rfd_v_);
  place_beads(q_work_, quat_work_, beads_work_);
  solver.set_configuration(beads_work_, radii_, offsets_, q_work_);
  if (!warm) return solver.apply(rfd_v_, out, rfd_lambda_).iterations;
  // The other side's solution is within O(delta) of this one: start GMRES from it.
  return solver.apply_from(rfd_v_, rfd_plus_, rfd_lambda_, out).iterations;
}

int RigidBodyDynamics::drift_estimate(std::span<const double> w, std::span<double> drift) {
  require_size(w, 6 * bodies(), kWhere, "RFD direction w");
  require_finite(w, kWhere, "RFD direction w", 6);
  require_size(drift, 6 * bodies(), kWhere, "drift");
  int iterations = perturbed_solve(rfd_solver_, w, +1.0, rfd_plus_, false);
  iterations += perturbed_solve(rfd_solver_, w, -1.0, rfd_minus_, true);
  rigid_detail::rfd_difference(rfd_plus_, rfd_minus_, options_.rfd_delta, drift);
  return iterations;
}

void RigidBodyDynamics::gather_forces_and_torques() {
  std::fill(w_.begin(), w_.end(), 0.0);
  if (forces_) {
    forces_(RigidBodyState{time(), q_, quat_, beads_now_}, w_);
    rigid_detail::require_finite_loads(w_, step_, 0, kWhere);
  }
  if (bead_field_) {
    report_.neighbour_rebuild = bead_list_->update(beads_now_);
    report_.potential_energy =
        bead_field_->compute(beads_now_, bead_types_, *bead_list_, step_, bead_forces_, bead_body_);
    bead_forces_to_bodies(bead_forces_, w_);
  }
}

void RigidBodyDynamics::solve_velocities() {
  StopWatch watch;
  solver_.set_configuration(beads_now_, radii_, offsets_, q_);
  totals_.seconds["plan"] += watch.seconds();
  if (options_.kT > 0.0) rpy::fill_normal(z_, options_.seed, step_, 0);
  rigid_detail::solve_velocities(solver_, w_, z_, y_, options_, report_, totals_);
}

void RigidBodyDynamics::estimate_drift() {
  std::fill(drift_.begin(), drift_.end(), 0.0);
  if (options_.kT > 0.0 && options_.drift == RigidDrift::random_finite_difference) {
    StopWatch watch;
    rpy::fill_normal(rfd_w_, options_.seed, step_, 1);
    report_.drift_iterations = drift_estimate(rfd_w_, drift_);
    for (double& d : drift_) d *= options_.kT;
    totals_.seconds["drift"] += watch.seconds();
  }
}

void RigidBodyDynamics::update_bodies() {
  rigid_detail::advance(q_, quat_, lever_, y_, drift_, options_, step_, 0, q_work_, quat_work_, kWhere);
  q_.swap(q_work_);
  quat_.swap(quat_work_);
  place_beads(q_, quat_, beads_now_);
}

const RigidStepReport& RigidBodyDynamics::step() {
  report_ = {};
  rigid_detail::take_step(
      report_, totals_, [this] { gather_forces_and_torques(); }, [this] { solve_velocities(); },
      [this] { estimate_drift(); },
      [this] {
        update_bodies();
        ++step_;
      });
  return report_;
}

void RigidBodyDynamics::run(std::uint64_t count) {
  for (std::uint64_t i = 0; i < count; ++i) step();
}

}  // namespace rpyfmm::bd
