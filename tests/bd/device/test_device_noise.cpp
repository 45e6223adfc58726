// The Brownian noise of the BD device stages against the CPU engine's: brownian_normals(seed,
// step, particle) equals rpy::fill_normal's z (stream 0) bit for bit (random.hpp: the same
// Philox4x32-10 words and the same Box-Muller operations; fill_normal's file is built without
// contraction), for steps past 2^32; where this file's build may fuse multiply-adds, to 16 ulps.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "compare.hpp"
#include "device/brownian_noise.hpp"
#include "rpyfmm/rpy/random.hpp"

TEST(DeviceNoise, SameDrawsAsCpu) {
  const std::size_t n = 5000;
  for (const std::uint64_t seed : {1ull, 0xDEADBEEFCAFEull}) {
    for (const std::uint64_t step : {0ull, 7ull, (1ull << 32) + 3}) {
      std::vector<double> z(3 * n);
      rpyfmm::rpy::fill_normal(z, seed, step);
      std::vector<double> d(3 * n);
      for (std::uint64_t i = 0; i < n; ++i) rpyfmm::bd::device::brownian_normals(seed, step, i, &d[3 * i]);
      std::vector<double> bound(3 * n);
      for (std::size_t k = 0; k < bound.size(); ++k)
        bound[k] = 16.0 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(z[k]));
      device_test::expect_close(d, z, bound, !device_test::kMayContract, "noise");
    }
  }
}

TEST(DeviceNoise, KeyedByStepAndParticle) {
  // Different steps, particles and seeds give different draws (the key is used at all).
  double a[3], b[3], c[3], e[3];
  rpyfmm::bd::device::brownian_normals(5, 10, 3, a);
  rpyfmm::bd::device::brownian_normals(5, 11, 3, b);
  rpyfmm::bd::device::brownian_normals(5, 10, 4, c);
  rpyfmm::bd::device::brownian_normals(6, 10, 3, e);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NE(a[k], b[k]);
    EXPECT_NE(a[k], c[k]);
    EXPECT_NE(a[k], e[k]);
  }
}
