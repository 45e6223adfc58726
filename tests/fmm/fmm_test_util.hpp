// Test helpers for the FMM: point distributions and an independent plain double-loop reference.
#pragma once

#include <cmath>
#include <cstddef>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace fmmtest {

/// Plain O(N M) reference: phi = sum q/r, g = grad phi, H = grad grad phi; pairs at distance 0 skipped.
/// Results nd x M x 10 as the FMM's.
inline std::vector<double> direct(const std::vector<double>& src, const std::vector<double>& q, std::size_t nd,
                                  const std::vector<double>& tgt_in, const std::vector<std::size_t>& which = {}) {
  const std::vector<double>& tgt = tgt_in.empty() ? src : tgt_in;
  const std::size_t n = src.size() / 3, m = tgt.size() / 3;
  std::vector<std::size_t> idx = which;
  if (idx.empty())
    for (std::size_t i = 0; i < m; ++i) idx.push_back(i);
  std::vector<double> out(nd * idx.size() * 10, 0.0);
  for (std::size_t ii = 0; ii < idx.size(); ++ii) {
    const std::size_t i = idx[ii];
    for (std::size_t j = 0; j < n; ++j) {
      const double dx = tgt[3 * i] - src[3 * j], dy = tgt[3 * i + 1] - src[3 * j + 1],
                   dz = tgt[3 * i + 2] - src[3 * j + 2];
      const double r2 = dx * dx + dy * dy + dz * dz;
      if (r2 == 0.0) continue;
      const double r = std::sqrt(r2), r3 = r * r2, r5 = r3 * r2;
      for (std::size_t d = 0; d < nd; ++d) {
        const double qj = q[d * n + j];
        double* o = &out[(d * idx.size() + ii) * 10];
        o[0] += qj / r;
        o[1] -= qj * dx / r3;
        o[2] -= qj * dy / r3;
        o[3] -= qj * dz / r3;
        o[4] += qj * (3 * dx * dx / r5 - 1 / r3);
        o[5] += qj * (3 * dy * dy / r5 - 1 / r3);
        o[6] += qj * (3 * dz * dz / r5 - 1 / r3);
        o[7] += qj * 3 * dx * dy / r5;
        o[8] += qj * 3 * dx * dz / r5;
        o[9] += qj * 3 * dy * dz / r5;
      }
    }
  }
  return out;
}

/// Relative l2 error of one output block (columns [c0, c1)) of density d, FMM rows picked by `which`.
inline double rel_l2(const std::vector<double>& fmm, std::size_t m_total, const std::vector<double>& ref,
                     const std::vector<std::size_t>& which, std::size_t d, int c0, int c1) {
  double num = 0, den = 0;
  const std::size_t k = which.size();
  for (std::size_t ii = 0; ii < k; ++ii)
    for (int c = c0; c < c1; ++c) {
      const double a = fmm[(d * m_total + which[ii]) * 10 + c], b = ref[(d * k + ii) * 10 + c];
      num += (a - b) * (a - b);
      den += b * b;
    }
  return den > 0 ? std::sqrt(num / den) : std::sqrt(num);
}

inline std::vector<double> cube(std::size_t n, unsigned seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> x(3 * n);
  for (auto& v : x) v = u(g);
  return x;
}
inline std::vector<double> sphere(std::size_t n, unsigned seed, bool octant = false) {
  std::mt19937_64 g(seed);
  std::normal_distribution<double> nd(0.0, 1.0);
  std::vector<double> x(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    double v[3] = {nd(g), nd(g), nd(g)};
    const double r = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int k = 0; k < 3; ++k) x[3 * i + k] = (octant ? std::abs(v[k]) : v[k]) / r;
  }
  return x;
}
inline std::vector<double> cylinder(std::size_t n, unsigned seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> x(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double a = 2 * std::numbers::pi * u(g);
    x[3 * i] = std::cos(a);
    x[3 * i + 1] = std::sin(a);
    x[3 * i + 2] = 4.0 * u(g);
  }
  return x;
}
/// Plummer sphere (scale radius 1), radii truncated at 50.
inline std::vector<double> plummer(std::size_t n, unsigned seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(1e-6, 1.0);
  std::normal_distribution<double> nd(0.0, 1.0);
  std::vector<double> x(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    double r;
    do {
      r = 1.0 / std::sqrt(std::pow(u(g), -2.0 / 3.0) - 1.0);
    } while (r > 50.0);
    double v[3] = {nd(g), nd(g), nd(g)};
    const double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int k = 0; k < 3; ++k) x[3 * i + k] = r * v[k] / l;
  }
  return x;
}
/// Two cubes of side `size` at (0,0,0) and (1,1,1). Note: coordinates near 1 carry relative positions
/// inside the cluster to only ~1e-16/size, which bounds the accuracy of any method (the direct sum too).
inline std::vector<double> two_clusters(std::size_t n, unsigned seed, double size = 1e-4) {
  auto x = cube(n, seed);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) x[3 * i + k] = x[3 * i + k] * size + (i % 2 ? 1.0 : 0.0);
  return x;
}
inline std::vector<double> line(std::size_t n, unsigned seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> x(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const double t = u(g);
    x[3 * i] = t;
    x[3 * i + 1] = 2 * t;
    x[3 * i + 2] = -t;
  }
  return x;
}
inline std::vector<double> charges(std::size_t n, std::size_t nd, unsigned seed) {
  std::mt19937_64 g(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> q(n * nd);
  for (auto& v : q) v = u(g);
  return q;
}
inline std::vector<std::size_t> sample(std::size_t m, std::size_t k, unsigned seed) {
  std::vector<std::size_t> w;
  if (m <= k) {
    for (std::size_t i = 0; i < m; ++i) w.push_back(i);
    return w;
  }
  std::mt19937_64 g(seed);
  std::uniform_int_distribution<std::size_t> u(0, m - 1);
  for (std::size_t i = 0; i < k; ++i) w.push_back(u(g));
  return w;
}

}  // namespace fmmtest
