// rpyfmm::bd — the inertial particles of a mixed BD run (langevin_group.hpp).
#include "rpyfmm/bd/langevin_group.hpp"

#include <cmath>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd {

LangevinGroup::LangevinGroup(std::span<const std::optional<LangevinParticle>> inertia,
                             std::span<const std::uint32_t> types) {
  for (std::size_t i = 0; i < types.size(); ++i) {
    if (types[i] >= inertia.size() || !inertia[types[i]]) continue;
    if (flag_.empty()) flag_.assign(types.size(), 0);
    flag_[i] = 1;
    particles_.push_back(*inertia[types[i]]);
    index_.push_back(i);
  }
  for (const LangevinParticle& p : particles_)
    require(std::isnormal(p.mass) && p.mass > 0.0 && std::isnormal(p.friction) && p.friction > 0.0,
            ErrorCode::invalid_argument, "Integrator",
            "inertia: mass and friction must be finite, > 0 and normal (>= 2.2e-308)");
  v_.assign(empty() ? 0 : 3 * types.size(), 0.0);
  pending_.assign(3 * size(), 0.0);
  f_.assign(3 * size(), 0.0);
  dx_.assign(3 * size(), 0.0);
}

void LangevinGroup::set_velocities(std::vector<double> velocities, double kT, std::uint64_t seed) {
  const char* where = "Integrator";
  if (velocities.empty()) {
    maxwell_velocities(kT, seed, particles_, index_, pending_);
    for (std::size_t k = 0; k < size(); ++k)
      for (std::size_t c = 0; c < 3; ++c) v_[3 * index_[k] + c] = pending_[3 * k + c];
    return;
  }
  require(!empty(), ErrorCode::invalid_argument, where, "velocities given but no particle is inertial");
  require(
      velocities.size() == v_.size(), ErrorCode::invalid_argument, where,
      "velocities has " + std::to_string(velocities.size()) + " entries, expected 3N = " + std::to_string(v_.size()));
  require_finite(velocities, where, "velocities", 3);
  for (std::size_t i = 0; i < flag_.size(); ++i)
    for (std::size_t c = 0; c < 3 && !flag_[i]; ++c)
      require(velocities[3 * i + c] == 0.0, ErrorCode::invalid_argument, where,
              "particle " + std::to_string(i) + " is Brownian but has a non-zero velocity");
  v_ = std::move(velocities);
}

void LangevinGroup::displacements(const LangevinStep& s, std::span<const double> forces, std::span<double> dx) {
  for (std::size_t k = 0; k < size(); ++k) {
    for (std::size_t c = 0; c < 3; ++c) {
      pending_[3 * k + c] = v_[3 * index_[k] + c];
      f_[3 * k + c] = forces[3 * index_[k] + c];
      dx_[3 * k + c] = 0.0;  // the step adds sqrt(b) dt v to x = 0: exactly its displacement
    }
  }
  langevin_step(s, particles_, index_, f_, dx_, pending_);
  for (std::size_t k = 0; k < size(); ++k)
    for (std::size_t c = 0; c < 3; ++c) dx[3 * index_[k] + c] = dx_[3 * k + c];
}

void LangevinGroup::commit() {
  for (std::size_t k = 0; k < size(); ++k)
    for (std::size_t c = 0; c < 3; ++c) v_[3 * index_[k] + c] = pending_[3 * k + c];
}

double LangevinGroup::kinetic_temperature() const {
  if (empty()) return 0.0;
  double sum = 0.0;
  for (std::size_t k = 0; k < size(); ++k) {
    const double* v = v_.data() + 3 * index_[k];
    sum += particles_[k].mass * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  }
  return sum / (3.0 * static_cast<double>(size()));
}

}  // namespace rpyfmm::bd
