// rpyfmm — RigidBodies: the body mobility N = (K^T M^{-1} K)^{-1} by preconditioned GMRES on
// the saddle-point system (see the header; the solve itself in body_system.hpp).
#include "rpyfmm/rpy/rigid_bodies.hpp"

#include <algorithm>
#include <string>

#include "body_system.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy {
namespace {

constexpr const char* kWhere = "RigidBodies";

}  // namespace

RigidBodies::RigidBodies(MobilityOperator& beads, RigidBodyOptions options) : beads_(beads), options_(options) {
  rigid_detail::require_options(options, kWhere);
}

std::size_t RigidBodies::bodies() const {
  return system_ ? system_->bodies() : 0;
}

std::span<const double> RigidBodies::reference_points() const {
  return system_ ? std::span<const double>(system_->reference) : std::span<const double>();
}

void RigidBodies::set_configuration(std::span<const double> bead_positions, double radius,
                                    std::span<const std::size_t> body_offsets,
                                    std::span<const double> reference_points) {
  require_positive(radius, kWhere, "bead radius");
  const std::vector<double> radii(bead_positions.size() / 3, radius);
  set_configuration(bead_positions, radii, body_offsets, reference_points);
}

void RigidBodies::set_configuration(std::span<const double> bead_positions, std::span<const double> radii,
                                    std::span<const std::size_t> body_offsets,
                                    std::span<const double> reference_points) {
  StopWatch watch;
  system_.reset();  // unconfigured until everything below succeeds
  rigid_detail::require_bodies(bead_positions, radii.size(), body_offsets, reference_points, options_, false, kWhere);
  // Plans the bead operator; validates positions and radii (NaN/Inf, radius <= 0).
  beads_.set_positions(bead_positions, radii);
  system_ = std::make_shared<const rigid_detail::BodySystem>(rigid_detail::make_body_system(
      bead_positions, beads_.radii(), body_offsets, reference_points, beads_.geometry(), beads_.viscosity(),
      std::ranges::max(beads_.radii()), options_.precondition, kWhere));
  seconds_setup_ = watch.seconds();
}

void RigidBodies::check_call(std::span<const double> forces_torques, std::span<double> velocities,
                             std::span<double> bead_forces) const {
  require(system_ != nullptr, ErrorCode::invalid_input, kWhere, "apply before set_configuration");
  require(beads_.size() == system_->beads(), ErrorCode::invalid_input, kWhere,
          "the bead operator now holds " + std::to_string(beads_.size()) + " particles, not the " +
              std::to_string(system_->beads()) + " beads of set_configuration (its positions were set elsewhere)");
  rigid_detail::require_call(*system_, forces_torques, velocities, bead_forces, kWhere);
}

RigidBodyReport RigidBodies::solve(std::span<const double> forces_torques, std::vector<double>& b,
                                   std::span<double> velocities, std::span<double> bead_forces,
                                   std::span<const double> guess_velocities,
                                   std::span<const double> guess_bead_forces) const {
  StopWatch watch;
  const rigid_detail::BeadProduct product = [this](std::span<const double> x, std::span<double> y) {
    beads_.apply(x, y);
  };
  const rigid_detail::SaddleSolution solution = rigid_detail::solve_saddle_point(
      *system_, product, options_, forces_torques, b, guess_velocities, guess_bead_forces);
  RigidBodyReport report = rigid_detail::finish_solve(*system_, solution, options_, velocities, bead_forces, kWhere);
  report.seconds_setup = seconds_setup_;
  report.seconds_solve = watch.seconds();
  return report;
}

RigidBodyReport RigidBodies::apply(std::span<const double> forces_torques, std::span<double> velocities,
                                   std::span<double> bead_forces) const {
  check_call(forces_torques, velocities, bead_forces);
  std::vector<double> b(3 * beads_.size() + 6 * bodies(), 0.0);  // no slip
  return solve(forces_torques, b, velocities, bead_forces);
}

RigidBodyReport RigidBodies::apply_from(std::span<const double> forces_torques,
                                        std::span<const double> guess_velocities,
                                        std::span<const double> guess_bead_forces, std::span<double> velocities,
                                        std::span<double> bead_forces) const {
  check_call(forces_torques, velocities, bead_forces);
  rigid_detail::require_guesses(*system_, guess_velocities, guess_bead_forces, kWhere);
  std::vector<double> b(3 * beads_.size() + 6 * bodies(), 0.0);  // no slip
  return solve(forces_torques, b, velocities, bead_forces, guess_velocities, guess_bead_forces);
}

RigidBodyReport RigidBodies::apply_with_noise(std::span<const double> forces_torques, double noise_scale,
                                              std::span<const double> z, std::span<double> velocities,
                                              const SqrtOptions& sqrt_options, std::span<double> bead_forces) const {
  check_call(forces_torques, velocities, bead_forces);
  const std::size_t n3 = 3 * beads_.size();
  rigid_detail::require_noise(*system_, z, noise_scale, kWhere);
  StopWatch watch;
  // Random slip s = -c B z with B B^T = M: Y = N W + c N K^T M^{-1} B z, whose noise part has
  // covariance c^2 N K^T M^{-1} M M^{-1} K N = c^2 N (Sprinkle et al., J. Chem. Phys. 147, 244103 (2017)).
  std::vector<double> b(n3 + 6 * bodies(), 0.0), w(n3);
  const SqrtReport sqrt_report = beads_.apply_sqrt(z, w, sqrt_options);
  for (std::size_t i = 0; i < n3; ++i) b[i] = -noise_scale * w[i];
  const double seconds_sqrt = watch.seconds();
  RigidBodyReport report = solve(forces_torques, b, velocities, bead_forces);
  report.sqrt = sqrt_report;
  report.seconds_sqrt = seconds_sqrt;
  return report;
}

std::vector<double> RigidBodies::mobility_matrix(std::size_t max_bodies) const {
  require(system_ != nullptr, ErrorCode::invalid_input, kWhere, "mobility_matrix before set_configuration");
  const std::size_t m = bodies();
  rigid_detail::require_matrix_bodies(m, max_bodies, kWhere);
  std::vector<double> unit(6 * m, 0.0);
  return rigid_detail::symmetric_mobility_matrix(6 * m, [&](std::size_t c, std::span<double> column) {
    unit[c] = 1.0;
    apply(unit, column);
    unit[c] = 0.0;
  });
}

}  // namespace rpyfmm::rpy
