// rpyfmm::bd — the Gronbech-Jensen-Farago Langevin step with half-step velocities (langevin.hpp).
#include "rpyfmm/bd/langevin.hpp"

#include <cmath>
#include <numbers>
#include <string>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/random.hpp"

namespace rpyfmm::bd {

namespace {

constexpr std::uint32_t kMaxwellStream = 5;

void check(std::span<const LangevinParticle> particles, std::span<const std::uint64_t> index, std::size_t n3,
           const char* where) {
  require(index.size() == particles.size(), ErrorCode::invalid_argument, where,
          "one noise index per particle expected, got " + std::to_string(index.size()) + " for " +
              std::to_string(particles.size()));
  require(
      n3 == 3 * particles.size(), ErrorCode::invalid_argument, where,
      "arrays of 3 per particle expected (" + std::to_string(3 * particles.size()) + "), got " + std::to_string(n3));
  for (std::size_t i = 0; i < particles.size(); ++i) {
    const LangevinParticle& p = particles[i];
    require(std::isnormal(p.mass) && p.mass > 0.0 && std::isnormal(p.friction) && p.friction > 0.0,
            ErrorCode::invalid_argument, where,
            "particle " + std::to_string(i) + ": mass and friction must be finite, > 0 and normal (>= 2.2e-308)");
  }
}

/// kT finite, >= 0 and, unless 0, normal (thermal_energy.hpp: a subnormal kT loses the noise).
void require_kT(double kT, const char* where) {
  require(std::isfinite(kT) && kT >= 0.0 && (kT == 0.0 || std::isnormal(kT)), ErrorCode::invalid_argument, where,
          "kT must be finite, >= 0 and 0 or normal (>= 2.2e-308), got " + format_number(kT));
}

}  // namespace

double sphere_mass(double radius, double density) {
  require(std::isfinite(radius) && radius > 0.0 && std::isfinite(density) && density > 0.0, ErrorCode::invalid_argument,
          "sphere_mass", "radius and density must be finite and > 0");
  return 4.0 / 3.0 * std::numbers::pi * radius * radius * radius * density;
}

void langevin_step(const LangevinStep& s, std::span<const LangevinParticle> particles,
                   std::span<const std::uint64_t> index, std::span<const double> forces, std::span<double> x,
                   std::span<double> v) {
  const char* where = "langevin_step";
  require(std::isfinite(s.dt) && s.dt > 0.0, ErrorCode::invalid_argument, where, "dt must be finite and > 0");
  require_kT(s.kT, where);
  check(particles, index, x.size(), where);
  require(forces.size() == x.size() && v.size() == x.size(), ErrorCode::invalid_argument, where,
          "forces, positions and velocities must have the same size");
  const auto n = static_cast<std::int64_t>(particles.size());
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (std::int64_t ii = 0; ii < n; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const LangevinParticle& p = particles[i];
    const double half = 0.5 * p.friction * s.dt / p.mass;
    const double b = 1.0 / (1.0 + half);
    const double a = (1.0 - half) * b;
    const double sqrt_b = std::sqrt(b);
    double now[3] = {0.0, 0.0, 0.0}, next[3] = {0.0, 0.0, 0.0};
    if (s.kT > 0.0) {
      rpy::normal3(s.seed, s.step, kLangevinNoiseStream, index[i], now);
      rpy::normal3(s.seed, s.step + 1, kLangevinNoiseStream, index[i], next);
    }
    const double sigma = std::sqrt(2.0 * p.friction * s.kT * s.dt);
    for (std::size_t c = 0; c < 3; ++c) {
      double& vc = v[3 * i + c];
      vc = a * vc + sqrt_b * s.dt / p.mass * forces[3 * i + c] + sqrt_b / (2.0 * p.mass) * sigma * (now[c] + next[c]);
      x[3 * i + c] += sqrt_b * s.dt * vc;
    }
  }
}

void maxwell_velocities(double kT, std::uint64_t seed, std::span<const LangevinParticle> particles,
                        std::span<const std::uint64_t> index, std::span<double> v) {
  const char* where = "maxwell_velocities";
  require_kT(kT, where);
  check(particles, index, v.size(), where);
  for (std::size_t i = 0; i < particles.size(); ++i) {
    double z[3];
    rpy::normal3(seed, 0, kMaxwellStream, index[i], z);
    const double scale = std::sqrt(kT / particles[i].mass);
    for (std::size_t c = 0; c < 3; ++c) v[3 * i + c] = scale * z[c];
  }
}

}  // namespace rpyfmm::bd
