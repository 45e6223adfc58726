// Particle configurations for the RPY operator tests (free space): random
// suspensions at a volume fraction, polydisperse mixtures, chains of touching
// beads, surfaces of the dissertation's Tables 3.1 (cylinder) and 3.4
// ("eight surface": here a tube around a lemniscate), and far-apart clusters.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace rpyfmm::testing {

struct Configuration {
  std::vector<double> x;  // 3N
  std::vector<double> a;  // N
};

/// N spheres of radius a uniformly in a cube sized for volume fraction phi (overlaps allowed).
inline Configuration random_suspension(std::size_t n, double a, double phi, unsigned seed) {
  const double volume = n * 4.0 / 3.0 * std::numbers::pi * a * a * a / phi;
  const double side = std::cbrt(volume);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, side);
  Configuration c;
  c.x.resize(3 * n);
  for (double& v : c.x) v = u(rng);
  c.a.assign(n, a);
  return c;
}

/// Bimodal mixture: a fraction of big spheres of radius ratio `ratio` to the small ones.
inline Configuration bimodal_suspension(std::size_t n, double a_small, double ratio, double phi, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::vector<double> a(n, a_small);
  const std::size_t big = std::max<std::size_t>(1, n / 50);
  for (std::size_t i = 0; i < big; ++i) a[(i * 37) % n] = a_small * ratio;
  double volume = 0.0;
  for (double r : a) volume += 4.0 / 3.0 * std::numbers::pi * r * r * r;
  const double side = std::cbrt(volume / phi);
  std::uniform_real_distribution<double> u(0.0, side);
  Configuration c;
  c.x.resize(3 * n);
  for (double& v : c.x) v = u(rng);
  c.a = a;
  return c;
}

/// Random chain of touching beads (each bond length exactly 2a), a random walk.
inline Configuration touching_chain(std::size_t n, double a, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  Configuration c;
  c.x.assign(3 * n, 0.0);
  for (std::size_t i = 1; i < n; ++i) {
    double d[3] = {g(rng), g(rng), g(rng)};
    const double norm = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int k = 0; k < 3; ++k) c.x[3 * i + k] = c.x[3 * (i - 1) + k] + 2.0 * a * d[k] / norm;
  }
  c.a.assign(n, a);
  return c;
}

/// Points uniformly on a cylinder surface of radius R and height H (dissertation §3.3.1).
inline Configuration cylinder_surface(std::size_t n, double a, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Configuration c;
  c.x.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = 2.0 * std::numbers::pi * u(rng);
    c.x[3 * i] = std::cos(t);
    c.x[3 * i + 1] = std::sin(t);
    c.x[3 * i + 2] = 4.0 * u(rng);
  }
  c.a.assign(n, a);
  return c;
}

/// Points on a figure-eight-like surface: a tube of radius 0.3 around the lemniscate of
/// Bernoulli (x, y) = (cos t, sin t cos t) / (1 + sin^2 t) scaled by 2 (dissertation §3.3.2).
inline Configuration eight_surface(std::size_t n, double a, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 2.0 * std::numbers::pi);
  Configuration c;
  c.x.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = u(rng), s = u(rng);
    const double den = 1.0 + std::sin(t) * std::sin(t);
    const double cx = 2.0 * std::cos(t) / den, cy = 2.0 * std::sin(t) * std::cos(t) / den;
    // Tangent by finite difference, normal in the plane, binormal = z.
    const double h = 1e-6, t2 = t + h, den2 = 1.0 + std::sin(t2) * std::sin(t2);
    double tx = 2.0 * std::cos(t2) / den2 - cx, ty = 2.0 * std::sin(t2) * std::cos(t2) / den2 - cy;
    const double tn = std::hypot(tx, ty);
    tx /= tn;
    ty /= tn;
    const double nx = -ty, ny = tx;
    c.x[3 * i] = cx + 0.3 * std::cos(s) * nx;
    c.x[3 * i + 1] = cy + 0.3 * std::cos(s) * ny;
    c.x[3 * i + 2] = 0.3 * std::sin(s);
  }
  c.a.assign(n, a);
  return c;
}

/// Two small dense clusters far apart (separation / cluster size = 1e3).
inline Configuration two_clusters(std::size_t n, double a, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  Configuration c;
  c.x.resize(3 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) c.x[3 * i + k] = g(rng) + (i < n / 2 ? 0.0 : (k == 0 ? 1000.0 : 0.0));
  c.a.assign(n, a);
  return c;
}

inline std::vector<double> random_vector(std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g;
  std::vector<double> v(n);
  for (double& x : v) x = g(rng);
  return v;
}

inline double relative_l2(const std::vector<double>& approx, const std::vector<double>& exact) {
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < exact.size(); ++i) {
    num += (approx[i] - exact[i]) * (approx[i] - exact[i]);
    den += exact[i] * exact[i];
  }
  return std::sqrt(num / den);
}

/// A named configuration.
struct Case {
  std::string name;
  Configuration config;
};

/// The accuracy tests' hard inputs: suspensions dilute and dense, radius ratio 16, mixed radii,
/// a touching chain, surfaces, far-apart clusters, overlapping beads.
inline std::vector<Case> accuracy_cases() {
  std::vector<Case> v;
  v.push_back({"suspension_phi005", random_suspension(1500, 1.0, 0.05, 1)});
  v.push_back({"suspension_phi03", random_suspension(1500, 1.0, 0.3, 2)});
  v.push_back({"bimodal_ratio16_phi01", bimodal_suspension(1500, 0.25, 16.0, 0.1, 3)});
  {
    auto c = random_suspension(1200, 1.0, 0.2, 4);
    for (std::size_t i = 0; i < c.a.size(); ++i) c.a[i] = 0.5 + 1.0 * ((i * 7919) % 100) / 100.0;  // mixed radii
    v.push_back({"polydisperse_phi02", c});
  }
  v.push_back({"touching_chain", touching_chain(1000, 1.0, 5)});
  v.push_back({"cylinder_surface", cylinder_surface(2000, 0.01, 6)});
  v.push_back({"eight_surface", eight_surface(2000, 0.01, 7)});
  v.push_back({"two_far_clusters", two_clusters(1000, 0.05, 8)});
  {
    auto c = random_suspension(800, 1.0, 0.6, 9);  // dense: many overlapping beads
    v.push_back({"overlapping_beads_phi06", c});
  }
  return v;
}

}  // namespace rpyfmm::testing
