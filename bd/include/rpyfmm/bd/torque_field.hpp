// rpyfmm::bd — the torques on rotating spheres (docs/theory/bd.md Sec. 7): constant torques per
// particle type and on every particle, and point dipoles in a uniform field. A particle of type t
// carries the dipole mu_t u, u = R(q) e_z its body z axis (quaternion::body_axis); in the field E
// its energy is -mu_t u . E and its torque mu_t u x E (a uniform field exerts no force on a
// dipole). Torques are computed particle by particle, so they do not depend on the thread count.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace rpyfmm::bd {

/// What a particle type contributes to the torques.
struct TypeTorque {
  std::array<double, 3> torque{0, 0, 0};  ///< constant torque on each particle of the type
  double dipole = 0.0;                    ///< dipole magnitude mu (>= 0) along the body z axis
};

class TorqueField {
 public:
  /// No torques.
  TorqueField() = default;
  /// `types`: one entry per particle type (or empty: none); `torque`: on every particle, added
  /// to the types' torques; `field`: the uniform field E acting on the dipoles. Throws
  /// invalid_argument on non-finite values or a negative dipole.
  TorqueField(std::vector<TypeTorque> types, const std::array<double, 3>& torque, const std::array<double, 3>& field);

  /// True when some torque can be nonzero (a constant torque, or a dipole and a field).
  [[nodiscard]] bool active() const { return active_; }
  [[nodiscard]] std::span<const TypeTorque> types() const { return types_; }
  [[nodiscard]] const std::array<double, 3>& torque() const { return torque_; }
  [[nodiscard]] const std::array<double, 3>& field() const { return field_; }

  /// Throws invalid_input unless the field has no types, or one per type of `type_count`.
  void check(std::size_t type_count) const;

  /// T (3N) at the orientations (4N unit quaternions, w x y z) of particles of `types`; returns
  /// the dipole energy -sum_i mu_i u_i . E.
  double compute(std::span<const double> orientations, std::span<const std::uint32_t> types,
                 std::span<double> torques) const;

 private:
  std::vector<TypeTorque> types_;
  std::array<double, 3> torque_{0, 0, 0};
  std::array<double, 3> field_{0, 0, 0};
  bool active_ = false;
};

}  // namespace rpyfmm::bd
