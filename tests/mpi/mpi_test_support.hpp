// Helpers shared by the MPI tests: the world's rank and size, particle sets, their split over the
// ranks, and the check that an error was thrown on every rank with one message.
#pragma once

#include <gtest/gtest.h>
#include <mpi.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "rpyfmm/core/error.hpp"

namespace rpyfmm_mpi_test {

inline int world_rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

inline int world_size() {
  int s = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &s);
  return s;
}

/// Rank 0's string, on every rank.
inline std::string broadcast_from_root(std::string s) {
  int length = static_cast<int>(s.size());
  MPI_Bcast(&length, 1, MPI_INT, 0, MPI_COMM_WORLD);
  s.resize(static_cast<std::size_t>(length));
  MPI_Bcast(s.data(), length, MPI_CHAR, 0, MPI_COMM_WORLD);
  return s;
}

/// Collective: runs `f` on every rank and expects rpyfmm::Error with `code` on every rank, with the
/// same message on all of them, containing `needle`. Returns the message.
template <class F>
std::string expect_collective_error(F&& f, rpyfmm::ErrorCode code, const std::string& needle) {
  std::string message;
  bool thrown = false;
  try {
    f();
  } catch (const rpyfmm::Error& e) {
    thrown = true;
    message = e.what();
    EXPECT_EQ(e.code(), code) << message;
  }
  EXPECT_TRUE(thrown) << "rank " << world_rank() << " did not throw (expected '" << needle << "')";
  EXPECT_NE(message.find(needle), std::string::npos) << message;
  const std::string root = broadcast_from_root(message);
  EXPECT_EQ(message, root) << "rank " << world_rank() << " threw a different message than rank 0";
  return message;
}

/// N particles: 3N positions, N radii, 3N forces (one set, the same on every rank for one seed).
struct Particles {
  std::vector<double> x, a, f;
  [[nodiscard]] std::size_t size() const { return a.size(); }
};

/// Uniform in a cube of side `side`, radii in [a_lo, a_hi] (equal when a_lo == a_hi).
inline Particles uniform_particles(std::size_t n, double side, double a_lo, double a_hi, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Particles p;
  for (std::size_t i = 0; i < n; ++i) {
    for (int d = 0; d < 3; ++d) p.x.push_back(side * u(rng));
    p.a.push_back(a_lo + (a_hi - a_lo) * u(rng));
    for (int d = 0; d < 3; ++d) p.f.push_back(2.0 * u(rng) - 1.0);
  }
  return p;
}

/// `n_cluster` spheres of radii 0.5 ... 2 overlapping in a ball of radius 3 (some pairs closer than
/// |a_i - a_j|, one pair coincident), then `n_far` spread over a cube of side 1000 far away.
inline Particles clustered_particles(std::size_t n_cluster, std::size_t n_far, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Particles p;
  for (std::size_t i = 0; i < n_cluster; ++i) {
    double v[3];
    do {
      for (double& c : v) c = u(rng);
    } while (v[0] * v[0] + v[1] * v[1] + v[2] * v[2] > 1.0);
    for (double c : v) p.x.push_back(3.0 * c);
    p.a.push_back(1.25 + 0.75 * u(rng));
    for (int d = 0; d < 3; ++d) p.f.push_back(u(rng));
  }
  if (n_cluster >= 2) {  // a coincident pair
    for (int d = 0; d < 3; ++d) p.x[3 + d] = p.x[d];
  }
  for (std::size_t i = 0; i < n_far; ++i) {
    for (int d = 0; d < 3; ++d) p.x.push_back(5000.0 + 500.0 * u(rng));
    p.a.push_back(1.0);
    for (int d = 0; d < 3; ++d) p.f.push_back(u(rng));
  }
  return p;
}

/// n pairs with centres uniform in a cube of side `side`: particle k + n at distance
/// `gap` x (a_k + a_{k+n}) from particle k in a random direction (gap 1: touching), radii in
/// [0.5, 1.5]. With the even split, the partners lie on different ranks.
inline Particles pairs_at(std::size_t n, double side, double gap, std::uint64_t seed) {
  Particles p = uniform_particles(2 * n, side, 0.5, 1.5, seed);
  std::mt19937_64 rng(seed + 1);
  std::normal_distribution<double> normal;
  for (std::size_t k = 0; k < n; ++k) {
    double d[3] = {normal(rng), normal(rng), normal(rng)};
    const double norm = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const double r = gap * (p.a[k] + p.a[k + n]);
    for (std::size_t c = 0; c < 3; ++c) p.x[3 * (k + n) + c] = p.x[3 * k + c] + r * d[c] / norm;
  }
  return p;
}

/// How N particles are split over P ranks (contiguous shares in rank order).
enum class Split {
  even,         // N / P each, the remainder on the lowest ranks
  first_empty,  // rank 0 has none, the rest even
  last_only,    // all on the last rank
  geometric,    // rank r gets about half of what is left, the last rank the rest
};
/// Every split, for the tests that run each.
inline constexpr Split kSplits[] = {Split::even, Split::first_empty, Split::last_only, Split::geometric};
/// The solvent viscosity of the tests of the distributed RPY operators.
inline constexpr double kViscosity = 0.7;

inline std::vector<std::size_t> split_counts(std::size_t n, std::size_t ranks, Split split) {
  std::vector<std::size_t> c(ranks, 0);
  switch (split) {
    case Split::even:
      for (std::size_t r = 0; r < ranks; ++r) c[r] = n / ranks + (r < n % ranks ? 1 : 0);
      break;
    case Split::first_empty: {
      if (ranks == 1) {
        c[0] = n;
        break;
      }
      for (std::size_t r = 1; r < ranks; ++r) c[r] = n / (ranks - 1) + (r - 1 < n % (ranks - 1) ? 1 : 0);
      break;
    }
    case Split::last_only:
      c[ranks - 1] = n;
      break;
    case Split::geometric: {
      std::size_t left = n;
      for (std::size_t r = 0; r + 1 < ranks; ++r) {
        c[r] = left / 2;
        left -= c[r];
      }
      c[ranks - 1] = left;
      break;
    }
  }
  return c;
}

/// This rank's share of N particles split by `split`: its first global index and its count.
struct Partition {
  std::size_t offset = 0, n = 0;
};

inline Partition partition_of(std::size_t n_total, Split split) {
  const std::vector<std::size_t> counts = split_counts(n_total, static_cast<std::size_t>(world_size()), split);
  Partition p;
  const auto rank = static_cast<std::size_t>(world_rank());
  for (std::size_t r = 0; r < rank; ++r) p.offset += counts[r];
  p.n = counts[rank];
  return p;
}

/// The entries [per * offset, per * (offset + count)) of v.
inline std::vector<double> share(const std::vector<double>& v, std::size_t per, std::size_t offset, std::size_t count) {
  return std::vector<double>(v.begin() + static_cast<std::ptrdiff_t>(per * offset),
                             v.begin() + static_cast<std::ptrdiff_t>(per * (offset + count)));
}

/// Number of entries whose bits differ (EXPECT_EQ on doubles would accept -0 == +0).
inline std::size_t bitwise_mismatches(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size()) return a.size() + b.size();
  std::size_t bad = 0;
  for (std::size_t i = 0; i < a.size(); ++i) bad += std::memcmp(&a[i], &b[i], sizeof(double)) != 0 ? 1 : 0;
  return bad;
}

/// Collective: ||a - b|| / ||b|| over all ranks' shares (scaled by the largest |b_i|: no overflow
/// for velocities near 1e300).
inline double global_relative_error(const std::vector<double>& a, const std::vector<double>& b) {
  double largest = 0.0, scale = 0.0;
  for (double v : b) largest = std::max(largest, std::abs(v));
  MPI_Allreduce(&largest, &scale, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
  double local[2] = {0.0, 0.0}, global[2] = {0.0, 0.0};
  for (std::size_t i = 0; i < a.size(); ++i) {
    const double d = (a[i] - b[i]) / scale, v = b[i] / scale;
    local[0] += d * d;
    local[1] += v * v;
  }
  MPI_Allreduce(local, global, 2, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
  return std::sqrt(global[0] / global[1]);
}

}  // namespace rpyfmm_mpi_test
