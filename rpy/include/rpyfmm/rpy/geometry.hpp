// rpyfmm — the geometry a mobility operator lives in: open (free space) or a
// periodic rectangular box. Chosen at operator construction; an operator that
// does not support a geometry rejects it there.
#pragma once

#include <array>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy {

class Geometry {
 public:
  /// Free space (no boundaries).
  static Geometry open() { return Geometry(false, {0.0, 0.0, 0.0}); }
  /// Periodic cube of side L.
  static Geometry periodic(double L) { return periodic(L, L, L); }
  /// Periodic rectangular box Lx x Ly x Lz with origin at (0,0,0); particles
  /// outside [0,L) are wrapped back into the box.
  static Geometry periodic(double Lx, double Ly, double Lz) {
    require_positive(Lx, "Geometry::periodic", "box length Lx");
    require_positive(Ly, "Geometry::periodic", "box length Ly");
    require_positive(Lz, "Geometry::periodic", "box length Lz");
    return Geometry(true, {Lx, Ly, Lz});
  }

  [[nodiscard]] bool is_periodic() const { return periodic_; }
  [[nodiscard]] bool is_open() const { return !periodic_; }
  /// Box lengths (zeros for open geometry).
  [[nodiscard]] const std::array<double, 3>& box() const { return box_; }
  [[nodiscard]] double volume() const { return box_[0] * box_[1] * box_[2]; }

 private:
  Geometry(bool periodic, std::array<double, 3> box) : periodic_(periodic), box_(box) {}
  bool periodic_;
  std::array<double, 3> box_;
};

}  // namespace rpyfmm::rpy
