// PSE real-space pair cache (PseOptions::real_space_cache, rpy/src/pse/pair_cache.hpp): the first product after
// set_positions keeps every pair's block, the later ones read it. Against the same operator
// without the cache, for the AVX-512 half rows and the portable rows; every product applies the
// same operator; new positions refill it; the memory limit and the option turn it off.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <vector>

#include "ewald_reference.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "simd_levels.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

namespace {

/// Components uniform in [-1, 1).
std::vector<double> uniform_components(std::size_t n, unsigned seed) {
  auto f = pse_test::random_points(n, {2.0, 2.0, 2.0}, seed);
  for (auto& v : f) v -= 1.0;
  return f;
}

std::vector<double> real_product(const PseRpy& op, const std::vector<double>& f, std::size_t nrhs) {
  std::vector<double> u(f.size());
  op.real_space_operator().apply(f, u, nrhs);
  return u;
}

PseOptions cached(double tolerance, bool cache) {
  PseOptions o;
  o.tolerance = tolerance;
  o.xi = 0.6;
  o.real_space_cache = cache;
  return o;
}

const std::array<double, 3> kBox = {30.0, 26.0, 34.0};  // 3+ cells of r_cut along every axis

/// The real-space kernels to run: the AVX-512 half rows (half-list chunk cache) and the portable
/// rows (row cache, as on a CPU without AVX-512), at each level the machine has.
std::vector<rpyfmm::SimdLevel> kernel_choices() {
  return rpyfmm::test::available_simd_levels();
}

}  // namespace

TEST(PsePairCache, CachedProductsMatchEvaluatedPairs) {
  // Tolerance 1e-3: float grids and a float cache; 1e-6: double. The cache stores F - F(0),
  // G - G(0) and the unit vector, rounded to its precision: float's unit round-off 6e-8 relative
  // per block, well below the table's own error (tolerance / 10), bound 1e-6; double: round-off,
  // bound 1e-13. The first product after set_positions fills the cache and applies the blocks as
  // kept; the later ones (1 or 2 threads) read them: the same rounded blocks, so every product
  // agrees bit for bit with the first, whatever was called in between.
  auto x = pse_test::random_points(2000, kBox, 81);
  for (int d = 0; d < 3; ++d) x[3 * 7 + d] = x[3 * 900 + d];  // a coincident pair
  const std::size_t n = x.size() / 3, nrhs = 3;
  const auto f = uniform_components(n * nrhs, 82);
  for (const rpyfmm::SimdLevel level : kernel_choices())
    for (const auto& [eps, bound] : {std::pair{1e-3, 1e-6}, std::pair{1e-6, 1e-13}}) {
      SCOPED_TRACE(rpyfmm::simd_level_name(level));
      const rpyfmm::ScopedSimdLevel kernels(level);
      PseRpy with(Geometry::periodic(kBox[0], kBox[1], kBox[2]), 1.0, cached(eps, true));
      PseRpy without(Geometry::periodic(kBox[0], kBox[1], kBox[2]), 1.0, cached(eps, false));
      with.set_positions(x, 1.0);
      without.set_positions(x, 1.0);
      const std::size_t value = with.parameters().wave_single ? sizeof(float) : sizeof(double);
      // Five values per pair, pairs in chunks of eight per half row: at least 5 x (pairs) values.
      EXPECT_GE(with.parameters().real_space_cache_bytes, 5 * value * 2000);
      EXPECT_EQ(without.parameters().real_space_cache_bytes, 0u);
      const auto reference = real_product(without, f, nrhs);
      const int saved = omp_get_max_threads();
      omp_set_num_threads(1);
      const auto first = real_product(with, f, nrhs);
      const auto fill = real_product(with, f, nrhs);
      const auto again = real_product(with, f, nrhs);
      omp_set_num_threads(std::max(2, saved));
      const auto two_threads = real_product(with, f, nrhs);
      omp_set_num_threads(saved);
      EXPECT_LT(pse_test::rel_l2(first, reference), bound) << "tolerance " << eps;
      EXPECT_GT(pse_test::rel_l2(first, reference), 0.0) << "tolerance " << eps << ": was the cache used?";
      EXPECT_EQ(first, fill) << "tolerance " << eps;
      EXPECT_EQ(fill, again) << "tolerance " << eps;
      EXPECT_EQ(fill, two_threads) << "tolerance " << eps;
      // The whole operator and the split sampler (Lanczos on M_r in slot order) likewise.
      std::vector<double> u_with(3 * n), u_without(3 * n), w_with(3 * n), w_without(3 * n);
      with.apply(std::span<const double>(f.data(), 3 * n), u_with);
      without.apply(std::span<const double>(f.data(), 3 * n), u_without);
      EXPECT_LT(pse_test::rel_l2(u_with, u_without), bound) << "tolerance " << eps;
      const auto r_with = with.sample(5, 1, w_with);
      const auto r_without = without.sample(5, 1, w_without);
      EXPECT_EQ(r_with.iterations, r_without.iterations);
      EXPECT_LT(pse_test::rel_l2(w_with, w_without), 10 * bound) << "tolerance " << eps;
    }
}

TEST(PsePairCache, NewPositionsRefillTheCache) {
  // After set_positions the cache holds the new pairs: products after a move match an operator
  // that never cached, for a move that changes the neighbour lists.
  for (const rpyfmm::SimdLevel level : kernel_choices()) {
    SCOPED_TRACE(rpyfmm::simd_level_name(level));
    const rpyfmm::ScopedSimdLevel kernels(level);
    auto x = pse_test::random_points(1500, kBox, 83);
    const auto f = uniform_components(x.size(), 84);
    PseRpy with(Geometry::periodic(kBox[0], kBox[1], kBox[2]), 1.0, cached(1e-3, true));
    with.set_positions(x, 1.0);
    for (int k = 0; k < 3; ++k) (void)real_product(with, f, 1);  // fills the cache, then reads it
    const auto step = uniform_components(x.size(), 85);
    for (std::size_t i = 0; i < x.size(); ++i) x[i] += 1.5 * step[i];
    with.set_positions(x, 1.0);  // particles leaving the box are wrapped
    PseRpy without(Geometry::periodic(kBox[0], kBox[1], kBox[2]), 1.0, cached(1e-3, false));
    without.set_positions(x, 1.0);
    const auto reference = real_product(without, f, 1);
    ASSERT_GT(with.parameters().real_space_cache_bytes, 0u);
    for (int k = 0; k < 3; ++k)  // filling, cached, cached
      EXPECT_LT(pse_test::rel_l2(real_product(with, f, 1), reference), 1e-6) << "product " << k;
  }
}

TEST(PsePairCache, MemoryLimitTurnsItOff) {
  // A cache that would not fit in max_memory_bytes beside the grids is not kept, and the products
  // are then those of the operator without it, bit for bit.
  for (const rpyfmm::SimdLevel level : kernel_choices()) {
    SCOPED_TRACE(rpyfmm::simd_level_name(level));
    const rpyfmm::ScopedSimdLevel kernels(level);
    const auto x = pse_test::random_points(1500, kBox, 86);
    const auto f = uniform_components(x.size(), 87);
    PseRpy probe(Geometry::periodic(kBox[0], kBox[1], kBox[2]), 1.0, cached(1e-3, true));
    probe.set_positions(x, 1.0);
    const PseParameters p = probe.parameters();
    ASSERT_GT(p.real_space_cache_bytes, 0u);
    PseOptions tight = cached(1e-3, true);
    tight.max_memory_bytes = p.memory_bytes + p.real_space_cache_bytes - 1;
    PseRpy limited(Geometry::periodic(kBox[0], kBox[1], kBox[2]), 1.0, tight);
    limited.set_positions(x, 1.0);
    EXPECT_EQ(limited.parameters().real_space_cache_bytes, 0u);
    tight.max_memory_bytes = p.memory_bytes + p.real_space_cache_bytes;
    PseRpy fits(Geometry::periodic(kBox[0], kBox[1], kBox[2]), 1.0, tight);
    fits.set_positions(x, 1.0);
    EXPECT_EQ(fits.parameters().real_space_cache_bytes, p.real_space_cache_bytes);
    PseRpy without(Geometry::periodic(kBox[0], kBox[1], kBox[2]), 1.0, cached(1e-3, false));
    without.set_positions(x, 1.0);
    const auto reference = real_product(without, f, 1);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(real_product(limited, f, 1), reference) << "product " << k;
  }
}

TEST(PsePairCache, KernelsSwitchedAfterSetPositions) {
  // The real-space plan (lists, cache layout, AVX-512 or portable rows) follows the level at
  // set_positions; after a switch of level (a test or benchmark changing it) the products keep
  // that plan, the portable rows run at the new level, and they stay correct (1e-6: the float
  // cache, as in CachedProductsMatchEvaluatedPairs).
  if (rpyfmm::detected_simd_level() == rpyfmm::SimdLevel::scalar) GTEST_SKIP() << "one level only";
  const auto x = pse_test::random_points(1500, kBox, 88);
  const auto f = uniform_components(x.size(), 89);
  PseRpy without(Geometry::periodic(kBox[0], kBox[1], kBox[2]), 1.0, cached(1e-3, false));
  without.set_positions(x, 1.0);
  const auto reference = real_product(without, f, 1);
  const std::vector<rpyfmm::SimdLevel> levels = kernel_choices();
  for (const rpyfmm::SimdLevel first : levels) {
    PseRpy op(Geometry::periodic(kBox[0], kBox[1], kBox[2]), 1.0, cached(1e-3, true));
    std::vector<double> u;
    {
      const rpyfmm::ScopedSimdLevel at_positions(first);
      op.set_positions(x, 1.0);
      u = real_product(op, f, 1);
    }
    EXPECT_LT(pse_test::rel_l2(u, reference), 1e-6) << "before the switch, first " << rpyfmm::simd_level_name(first);
    for (const rpyfmm::SimdLevel later : levels) {
      const rpyfmm::ScopedSimdLevel scope(later);
      EXPECT_LT(pse_test::rel_l2(real_product(op, f, 1), reference), 1e-6)
          << "planned at " << rpyfmm::simd_level_name(first) << ", run at " << rpyfmm::simd_level_name(later);
    }
  }
}
