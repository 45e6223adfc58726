// rpyfmm — tensor Chebyshev nodes and anterpolation of a cell's charges (chebyshev.hpp).
#include "chebyshev.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

namespace rpyfmm::mpi::detail {
namespace {

double chebyshev_point(int m, int p) {
  return std::cos((2.0 * m + 1.0) * std::numbers::pi / (2.0 * p));
}

// The p weights S_p(t_m, u), m = 0..p-1, of a coordinate u in [-1, 1] (Fong & Darve 2009, Sec. 2):
// T_k(u) by the three-term recurrence, T_k(t_m) = cos(k (2m + 1) pi / (2p)).
void weights(double u, int p, std::span<const double> t_km, double* w) {
  std::vector<double> tk(static_cast<std::size_t>(p));
  tk[0] = 1.0;
  if (p > 1) tk[1] = u;
  for (int k = 2; k < p; ++k) tk[static_cast<std::size_t>(k)] = 2.0 * u * tk[k - 1] - tk[k - 2];
  for (int m = 0; m < p; ++m) {
    double s = 0.0;
    for (int k = 1; k < p; ++k) s += t_km[static_cast<std::size_t>(k * p + m)] * tk[static_cast<std::size_t>(k)];
    w[m] = (1.0 + 2.0 * s) / p;
  }
}

// The coordinate of y in the cube's axis scaled to [-1, 1] (0 for a cube of side 0).
double scaled(double y, double center, double half) {
  if (!(half > 0.0)) return 0.0;
  return std::clamp((y - center) / half, -1.0, 1.0);
}

}  // namespace

void chebyshev_nodes(const Cube& cube, int p, std::span<double> nodes) {
  std::size_t i = 0;
  for (int a = 0; a < p; ++a) {
    for (int b = 0; b < p; ++b) {
      for (int c = 0; c < p; ++c, i += 3) {
        nodes[i] = cube.center[0] + cube.half * chebyshev_point(a, p);
        nodes[i + 1] = cube.center[1] + cube.half * chebyshev_point(b, p);
        nodes[i + 2] = cube.center[2] + cube.half * chebyshev_point(c, p);
      }
    }
  }
}

void anterpolate(const Cube& cube, int p, std::span<const double> positions, const double* q, std::size_t ldq,
                 std::size_t nd, std::span<double> out) {
  const auto pp = static_cast<std::size_t>(p);
  const std::size_t nodes = pp * pp * pp;
  std::vector<double> t_km(pp * pp);
  for (int k = 0; k < p; ++k) {
    for (int m = 0; m < p; ++m)
      t_km[static_cast<std::size_t>(k * p + m)] = std::cos(k * (2.0 * m + 1.0) * std::numbers::pi / (2.0 * p));
  }
  std::fill(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(nd * nodes), 0.0);
  std::vector<double> w(3 * pp), wxy(pp * pp);
  for (std::size_t j = 0; j < positions.size() / 3; ++j) {
    for (std::size_t d = 0; d < 3; ++d)
      weights(scaled(positions[3 * j + d], cube.center[d], cube.half), p, t_km, &w[d * pp]);
    for (std::size_t a = 0; a < pp; ++a) {
      for (std::size_t b = 0; b < pp; ++b) wxy[a * pp + b] = w[a] * w[pp + b];
    }
    for (std::size_t d = 0; d < nd; ++d) {
      const double qj = q[d * ldq + j];
      double* o = out.data() + d * nodes;
      for (std::size_t ab = 0; ab < pp * pp; ++ab) {
        const double s = qj * wxy[ab];
        for (std::size_t c = 0; c < pp; ++c) o[ab * pp + c] += s * w[2 * pp + c];
      }
    }
  }
}

}  // namespace rpyfmm::mpi::detail
