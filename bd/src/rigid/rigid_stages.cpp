// rpyfmm::bd — the stages of a rigid-body BD step on a run of whole bodies (rigid_stages.hpp).
#include "rigid_stages.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "../thermal_energy.hpp"
#include "rpyfmm/bd/quaternion.hpp"
#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd::rigid_detail {

const RigidDynamicsOptions& checked_options(const RigidDynamicsOptions& options, const char* where) {
  require_positive(options.dt, where, "dt");
  require_thermal_energy(options.kT, 2.0 * options.kT / options.dt, where, "2 kT / dt");
  require_in_range(options.rfd_delta, 1e-6, 0.1, where, "rfd_delta");
  require_positive(options.max_displacement, where, "max_displacement");
  return options;
}

rpy::RigidBodyOptions rfd_options(const RigidDynamicsOptions& options) {
  rpy::RigidBodyOptions o = options.solver;
  o.tolerance = std::min(o.tolerance, 1e-3 * options.rfd_delta);
  return o;
}

std::vector<double> lever_arms(std::span<const double> shape, std::span<const std::size_t> offsets,
                               std::size_t first_body, const char* where) {
  const std::size_t m = offsets.size() - 1;
  std::vector<double> lever(m, 0.0);
  for (std::size_t k = 0; k < m; ++k) {
    require(offsets[k + 1] > offsets[k], ErrorCode::invalid_input, where,
            "body " + std::to_string(first_body + k) + " has no beads (body offsets must increase strictly)");
    double sum = 0.0;
    for (std::size_t i = offsets[k]; i < offsets[k + 1]; ++i)
      for (int c = 0; c < 3; ++c) sum += shape[3 * i + c] * shape[3 * i + c];
    lever[k] = std::sqrt(sum / double(offsets[k + 1] - offsets[k]));
    require(lever[k] > 0.0, ErrorCode::invalid_input, where,
            "body " + std::to_string(first_body + k) + " has all its beads at its reference point");
  }
  return lever;
}

void place_beads(std::span<const double> shape, std::span<const std::size_t> offsets, std::span<const double> positions,
                 std::span<const double> orientations, std::vector<double>& out) {
  out.resize(shape.size());
  const std::size_t m = offsets.size() - 1;
  for (std::size_t k = 0; k < m; ++k) {
    const auto r = quaternion::rotation_matrix(std::span<const double, 4>(orientations.data() + 4 * k, 4));
    for (std::size_t i = offsets[k]; i < offsets[k + 1]; ++i) {
      const double* rho = &shape[3 * i];
      for (int c = 0; c < 3; ++c)
        out[3 * i + c] = positions[3 * k + c] + r[3 * c] * rho[0] + r[3 * c + 1] * rho[1] + r[3 * c + 2] * rho[2];
    }
  }
}

void add_bead_loads(std::span<const std::size_t> offsets, std::span<const double> beads, std::span<const double> q,
                    std::span<const double> bead_forces, std::span<double> forces_torques) {
  for (std::size_t k = 0; k + 1 < offsets.size(); ++k) {
    double* w = &forces_torques[6 * k];
    for (std::size_t i = offsets[k]; i < offsets[k + 1]; ++i) {
      const double* f = &bead_forces[3 * i];
      double arm[3];
      for (int c = 0; c < 3; ++c) arm[c] = beads[3 * i + c] - q[3 * k + c];
      for (int c = 0; c < 3; ++c) w[c] += f[c];
      w[3] += arm[1] * f[2] - arm[2] * f[1];
      w[4] += arm[2] * f[0] - arm[0] * f[2];
      w[5] += arm[0] * f[1] - arm[1] * f[0];
    }
  }
}

void require_finite_loads(std::span<const double> forces_torques, std::uint64_t step, std::size_t first_body,
                          const char* where) {
  for (std::size_t k = 0; 6 * k < forces_torques.size(); ++k)
    for (int c = 0; c < 6; ++c)
      require(std::isfinite(forces_torques[6 * k + c]), ErrorCode::invalid_input, where,
              "step " + std::to_string(step) + ": the force function gave a non-finite " +
                  (c < 3 ? "force" : "torque") + " on body " + std::to_string(first_body + k));
}

void perturb(std::span<const double> q, std::span<const double> quat, std::span<const double> lever,
             std::span<const double> w, double half_step, std::vector<double>& q_out, std::vector<double>& quat_out,
             std::span<double> v_out) {
  q_out.assign(q.begin(), q.end());
  quat_out.assign(quat.begin(), quat.end());
  for (std::size_t k = 0; k < lever.size(); ++k) {
    const double phi[3] = {half_step * w[6 * k + 3], half_step * w[6 * k + 4], half_step * w[6 * k + 5]};
    for (int c = 0; c < 3; ++c) {
      q_out[3 * k + c] += half_step * lever[k] * w[6 * k + c];
      v_out[6 * k + c] = w[6 * k + c] / lever[k];  // S^{-1} w
      v_out[6 * k + 3 + c] = w[6 * k + 3 + c];
    }
    quaternion::rotate(std::span<double, 4>(quat_out.data() + 4 * k, 4), phi);
  }
}

void rfd_difference(std::span<const double> plus, std::span<const double> minus, double delta,
                    std::span<double> drift) {
  for (std::size_t i = 0; i < drift.size(); ++i) drift[i] = (plus[i] - minus[i]) / delta;
}

void advance(std::span<const double> q, std::span<const double> quat, std::span<const double> lever,
             std::span<const double> velocities, std::span<const double> drift, const RigidDynamicsOptions& options,
             std::uint64_t step, std::size_t first_body, std::vector<double>& q_out, std::vector<double>& quat_out,
             const char* where) {
  const double dt = options.dt;
  q_out.assign(q.begin(), q.end());
  quat_out.assign(quat.begin(), quat.end());
  for (std::size_t k = 0; k < lever.size(); ++k) {
    double move = 0.0, turn = 0.0, phi[3];
    for (int c = 0; c < 3; ++c) {
      const double dq = dt * (velocities[6 * k + c] + drift[6 * k + c]);
      phi[c] = dt * (velocities[6 * k + 3 + c] + drift[6 * k + 3 + c]);
      q_out[3 * k + c] += dq;
      move += dq * dq;
      turn += phi[c] * phi[c];
    }
    const double moved = std::sqrt(move) + lever[k] * std::sqrt(turn);
    if (!(moved <= options.max_displacement * lever[k])) {
      std::ostringstream what;
      what << "step " << step << ": body " << first_body + k << " would move its beads by " << moved
           << " (translation + lever arm x rotation), above max_displacement x lever arm = "
           << options.max_displacement * lever[k] << "; reduce dt";
      fail(ErrorCode::numerical_failure, where, what.str());
    }
    quaternion::rotate(std::span<double, 4>(quat_out.data() + 4 * k, 4), phi);
  }
}

}  // namespace rpyfmm::bd::rigid_detail
