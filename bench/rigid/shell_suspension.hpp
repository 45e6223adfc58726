// Shared by the rigid-body benchmarks: a suspension of m bead-shell spheres of radius R = 2
// (icosphere_beads, touching beads) at body volume fraction phi, placed by random sequential
// addition (centres at least 2 R + 2 a apart, so no beads of different bodies overlap) in a cube,
// randomly oriented. The same seed gives the same suspension in both benchmarks.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <random>
#include <vector>

#include "rpyfmm/rpy/rigid_bodies.hpp"

namespace rpyfmm_bench {

struct ShellSuspension {
  std::vector<double> shape;         ///< body-frame beads (3N): R x the unit shell, per body
  std::vector<double> radii;         ///< N bead radii
  std::vector<std::size_t> offsets;  ///< m + 1 body offsets
  std::vector<double> centres;       ///< 3m sphere centres
  std::vector<double> orientations;  ///< 4m unit quaternions (w, x, y, z)

  /// Lab-frame bead positions (3N): centre + R(quaternion) shape.
  [[nodiscard]] std::vector<double> positions() const {
    std::vector<double> x;
    x.reserve(shape.size());
    for (std::size_t k = 0; k + 1 < offsets.size(); ++k) {
      const double w = orientations[4 * k], qx = orientations[4 * k + 1], qy = orientations[4 * k + 2],
                   qz = orientations[4 * k + 3];
      const double rot[9] = {1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * w),      2 * (qx * qz + qy * w),
                             2 * (qx * qy + qz * w),      1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * w),
                             2 * (qx * qz - qy * w),      2 * (qy * qz + qx * w),      1 - 2 * (qx * qx + qy * qy)};
      for (std::size_t i = offsets[k]; i < offsets[k + 1]; ++i)
        for (std::size_t r = 0; r < 3; ++r)
          x.push_back(centres[3 * k + r] + rot[3 * r] * shape[3 * i] + rot[3 * r + 1] * shape[3 * i + 1] +
                      rot[3 * r + 2] * shape[3 * i + 2]);
    }
    return x;
  }
};

inline ShellSuspension shell_suspension(std::size_t m, int subdivisions, double phi, unsigned seed) {
  const double R = 2.0;
  const std::vector<double> shell = rpyfmm::rpy::icosphere_beads(subdivisions);
  const double a = rpyfmm::rpy::icosphere_bead_radius(subdivisions) * R;
  const double L = std::cbrt(double(m) * 4.0 / 3.0 * std::numbers::pi * R * R * R / phi);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, L);
  std::normal_distribution<double> g;
  ShellSuspension s;
  s.offsets.push_back(0);
  while (s.centres.size() < 3 * m) {
    const std::array<double, 3> c{u(rng), u(rng), u(rng)};
    bool free = true;
    for (std::size_t k = 0; k < s.centres.size(); k += 3) {
      double d2 = 0.0;
      for (std::size_t r = 0; r < 3; ++r) d2 += (c[r] - s.centres[k + r]) * (c[r] - s.centres[k + r]);
      if (d2 < (2 * R + 2 * a) * (2 * R + 2 * a)) free = false;
    }
    if (!free) continue;
    s.centres.insert(s.centres.end(), c.begin(), c.end());
    double q[4] = {g(rng), g(rng), g(rng), g(rng)};
    const double qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (double e : q) s.orientations.push_back(e / qn);
    for (double v : shell) s.shape.push_back(R * v);
    s.radii.insert(s.radii.end(), shell.size() / 3, a);
    s.offsets.push_back(s.radii.size());
  }
  return s;
}

}  // namespace rpyfmm_bench
