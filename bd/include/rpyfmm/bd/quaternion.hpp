// rpyfmm::bd — unit quaternions (w, x, y, z) for the orientations of rigid bodies and of
// rotating spheres: rotation matrices, the exponential map that advances an orientation by a
// rotation vector, and the body axis that carries a sphere's dipole.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <vector>

namespace rpyfmm::bd::quaternion {

/// Rotation matrix (row-major 3x3) of a unit quaternion.
std::array<double, 9> rotation_matrix(std::span<const double, 4> q);

/// q <- exp(phi) q: q rotated by the rotation vector phi (angle |phi| about phi / |phi|, in the
/// lab frame), renormalized.
void rotate(std::span<double, 4> q, const double phi[3]);

/// The body-frame z axis in the lab frame, R(q) e_z (the third column of rotation_matrix).
std::array<double, 3> body_axis(std::span<const double, 4> q);

/// `count` orientations (4 count values, w x y z each) checked and normalized: empty gives the
/// identity for every object; otherwise the size must be 4 count, every value finite and no
/// quaternion zero. A quaternion already unit to 1e-14 is kept as it is (a saved state restarts
/// bit for bit); any other is divided by its norm. Errors (invalid_input) name `where` and the
/// object, e.g. "the orientation of body 3 is a zero quaternion" for object = "body".
std::vector<double> checked(std::vector<double> q, std::size_t count, const char* where, const char* object);

}  // namespace rpyfmm::bd::quaternion
