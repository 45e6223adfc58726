// rpyfmm::bd — the inertial particles of a mixed BD run: which particles move by the Langevin
// step (langevin.hpp) instead of the Brownian one, their masses and frictions (from their types),
// and their half-step velocities v_{n-1/2}. The Integrator asks it for the displacements of a
// step, guards them with the Brownian ones, then commits the new velocities, so a refused step
// leaves the velocities as they were (docs/theory/bd.md Sec. 8).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "rpyfmm/bd/langevin.hpp"

namespace rpyfmm::bd {

class LangevinGroup {
 public:
  LangevinGroup() = default;
  /// `inertia[t]` set: particles of type t are inertial with that mass and friction (types past
  /// the end are Brownian). Throws on a non-positive mass or friction.
  LangevinGroup(std::span<const std::optional<LangevinParticle>> inertia, std::span<const std::uint32_t> types);

  [[nodiscard]] bool empty() const { return index_.empty(); }
  [[nodiscard]] std::size_t size() const { return index_.size(); }
  /// Whether particle i is inertial (false for every i when empty()).
  [[nodiscard]] bool contains(std::size_t i) const { return !flag_.empty() && flag_[i] != 0; }
  /// The half-step velocities (3N; 0 for Brownian particles).
  [[nodiscard]] std::span<const double> velocities() const { return v_; }

  /// Sets the velocities: `velocities` (3N; entries of Brownian particles must be 0), or, when
  /// empty, the Maxwell distribution at kT keyed by `seed` (maxwell_velocities). Throws naming the
  /// first bad entry.
  void set_velocities(std::vector<double> velocities, double kT, std::uint64_t seed);

  /// The displacements of the inertial particles over step `s` from the forces F_n (3N), written
  /// into their entries of dx (3N; other entries untouched). The new velocities wait for commit().
  void displacements(const LangevinStep& s, std::span<const double> forces, std::span<double> dx);
  /// Keeps the velocities of the last displacements() (the step was accepted).
  void commit();

  /// Kinetic temperature of the half-step velocities, the mean of m |v|^2 / 3 over the inertial
  /// particles (kT at equilibrium; 0 when empty()).
  [[nodiscard]] double kinetic_temperature() const;

 private:
  std::vector<LangevinParticle> particles_;  // per inertial particle
  std::vector<std::uint64_t> index_;         // its index in the system (the noise key)
  std::vector<char> flag_;                   // N: 1 = inertial (empty when none is)
  std::vector<double> v_;                    // 3N velocities
  std::vector<double> pending_, f_, dx_;     // 3 per inertial particle: new velocities, forces, steps
};

}  // namespace rpyfmm::bd
