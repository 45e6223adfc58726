#include "rpyfmm/bd/quaternion.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::bd::quaternion {

std::array<double, 9> rotation_matrix(std::span<const double, 4> q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
          2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
          2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
}

void rotate(std::span<double, 4> q, const double phi[3]) {
  // dq = (cos(theta/2), sin(theta/2) phi / theta), theta = |phi|; q <- dq q (Hamilton product),
  // so that R(dq q) = R(dq) R(q): a rotation in the lab frame.
  const double theta = std::sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]);
  const double half = 0.5 * theta;
  // sin(theta/2) / theta, by its series where theta is tiny.
  const double s = theta > 1e-4 ? std::sin(half) / theta : 0.5 - theta * theta / 48.0;
  const double a = std::cos(half), b = s * phi[0], c = s * phi[1], d = s * phi[2];
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  double r[4] = {a * w - b * x - c * y - d * z, a * x + b * w + c * z - d * y, a * y - b * z + c * w + d * x,
                 a * z + b * y - c * x + d * w};
  const double norm = std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
  for (int i = 0; i < 4; ++i) q[i] = r[i] / norm;
}

std::array<double, 3> body_axis(std::span<const double, 4> q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return {2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)};
}

namespace {
/// |q| without overflow: the sum of squares where it is finite, else |q| in units of its largest
/// component (components of 1e300 overflowed the squares to infinity, and dividing by the
/// infinite norm turned the orientation into NaN).
double quaternion_norm(std::span<const double, 4> q) {
  double norm2 = 0.0;
  for (const double v : q) norm2 += v * v;
  if (std::isfinite(norm2)) return std::sqrt(norm2);
  double largest = 0.0;
  for (const double v : q) largest = std::max(largest, std::abs(v));
  double scaled2 = 0.0;
  for (const double v : q) scaled2 += (v / largest) * (v / largest);
  return largest * std::sqrt(scaled2);
}
}  // namespace

std::vector<double> checked(std::vector<double> q, std::size_t count, const char* where, const char* object) {
  const std::string name(object);
  if (q.empty()) {
    q.assign(4 * count, 0.0);
    for (std::size_t k = 0; k < count; ++k) q[4 * k] = 1.0;
    return q;
  }
  require(q.size() == 4 * count, ErrorCode::invalid_input, where,
          "orientations have " + std::to_string(q.size()) + " entries, expected 4 x " + std::to_string(count) +
              " (quaternions w, x, y, z, one per " + name + ")");
  require_finite(q, where, "orientations", 4);
  for (std::size_t k = 0; k < count; ++k) {
    const double norm = quaternion_norm(std::span<const double, 4>(q.data() + 4 * k, 4));
    require(norm > 1e-12, ErrorCode::invalid_input, where,
            "the orientation of " + name + " " + std::to_string(k) + " is a zero quaternion");
    // Unit quaternions (a saved state) are kept as they are, so that a restart is bitwise.
    if (std::abs(norm - 1.0) > 1e-14)
      for (int c = 0; c < 4; ++c) q[4 * k + c] /= norm;
  }
  return q;
}

}  // namespace rpyfmm::bd::quaternion
