// rpyfmm — bead-shell spheres: subdivided icosahedra (see rigid_bodies.hpp).
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

namespace rpyfmm::rpy {
namespace {

struct Mesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> faces;
};

Mesh subdivided_icosahedron(int subdivisions) {
  require(subdivisions >= 0 && subdivisions <= 6, ErrorCode::invalid_argument, "icosphere_beads",
          "subdivisions must lie in [0, 6], got " + std::to_string(subdivisions));
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;  // golden ratio: the icosahedron's vertices
  std::vector<Eigen::Vector3d> v = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                                    {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  for (auto& p : v) p.normalize();
  std::vector<std::array<int, 3>> faces = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                           {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                           {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                           {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int level = 0; level < subdivisions; ++level) {
    std::map<std::pair<int, int>, int> midpoints;  // edge -> its new vertex
    auto midpoint = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      if (const auto it = midpoints.find(key); it != midpoints.end()) return it->second;
      v.push_back((v[static_cast<std::size_t>(a)] + v[static_cast<std::size_t>(b)]).normalized());
      return midpoints[key] = static_cast<int>(v.size() - 1);
    };
    std::vector<std::array<int, 3>> next;
    next.reserve(4 * faces.size());
    for (const auto& f : faces) {
      const int a = midpoint(f[0], f[1]), b = midpoint(f[1], f[2]), c = midpoint(f[2], f[0]);
      next.insert(next.end(), {{f[0], a, c}, {f[1], b, a}, {f[2], c, b}, {a, b, c}});
    }
    faces = std::move(next);
  }
  return {std::move(v), std::move(faces)};
}

}  // namespace

std::vector<double> icosphere_beads(int subdivisions) {
  const auto v = subdivided_icosahedron(subdivisions).vertices;
  std::vector<double> out;
  out.reserve(3 * v.size());
  for (const auto& p : v) out.insert(out.end(), {p.x(), p.y(), p.z()});
  return out;
}

double icosphere_bead_radius(int subdivisions) {
  const Mesh mesh = subdivided_icosahedron(subdivisions);
  double d = 4.0;  // squared; the closest beads are neighbours on the mesh: the shortest edge
  for (const auto& f : mesh.faces)
    for (int e = 0; e < 3; ++e)
      d = std::min(
          d, (mesh.vertices[static_cast<std::size_t>(f[e])] - mesh.vertices[static_cast<std::size_t>(f[(e + 1) % 3])])
                 .squaredNorm());
  return std::sqrt(d) / 2.0;
}

}  // namespace rpyfmm::rpy
