// Shared by the rigid-body dynamics tests: body-frame shapes, quaternions, and bead placement
// written independently of the library (Eigen rotations).
#pragma once

#include <Eigen/Dense>
#include <random>
#include <span>
#include <vector>

namespace rpyfmm_test {

using Vec3 = Eigen::Vector3d;

inline Eigen::Matrix3d from_quaternion(std::span<const double> q) {
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
}

/// Bodies in the body frame: shapes relative to their reference points.
struct Shapes {
  std::vector<double> shape, radii;
  std::vector<std::size_t> offsets{0};
  void add(const std::vector<double>& points, double scale, double radius, const Vec3& shift) {
    for (std::size_t i = 0; i < points.size(); i += 3) {
      for (int c = 0; c < 3; ++c) shape.push_back(scale * points[i + std::size_t(c)] + shift[c]);
      radii.push_back(radius);
    }
    offsets.push_back(radii.size());
  }
  [[nodiscard]] std::size_t bodies() const { return offsets.size() - 1; }
};

/// Beads at (positions, quaternions) placed independently of the library (Eigen rotations).
inline std::vector<double> place(const Shapes& s, const std::vector<double>& q, const std::vector<double>& quat) {
  std::vector<double> x(s.shape.size());
  for (std::size_t k = 0; k < s.bodies(); ++k) {
    const Eigen::Matrix3d R = from_quaternion({&quat[4 * k], 4});
    for (std::size_t i = s.offsets[k]; i < s.offsets[k + 1]; ++i) {
      const Vec3 r = Eigen::Map<const Vec3>(&q[3 * k]) + R * Eigen::Map<const Vec3>(&s.shape[3 * i]);
      for (int c = 0; c < 3; ++c) x[3 * i + std::size_t(c)] = r[c];
    }
  }
  return x;
}

/// m random quaternions, not normalized (the library and from_quaternion normalize them).
inline std::vector<double> random_quaternions(std::size_t m, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  std::vector<double> q(4 * m);
  for (double& v : q) v = g(rng);
  return q;
}

}  // namespace rpyfmm_test
