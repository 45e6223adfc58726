// The leaves of FmmRpy's Laplace FMM (fmm_leaf_rules.hpp): capacities and fitted grids measured
// with the exact RPY near field.
#include "fmm_leaf_rules.hpp"

#include <limits>

#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

namespace rpyfmm::rpy::detail {

// Leaf capacity when the user leaves it at 0 (bench/rpy/RESULTS.md at commit 010249d "Leaf capacity", 1 thread).
// Four densities per product make the far field dearer relative to the near field than in one
// Laplace evaluation, so from 6 digits on the best leaves are larger than the Laplace default
// wherever the P2P runs without AVX-512: 400 / 600 / 800 points at 6 / 9 / 12 digits on both
// machines measured. At 3 digits the near-field kernel's speed decides: 200 points with the AVX-512
// kernels (random suspension N = 3e3 ... 2e5, Intel machine), 150 with AVX2 (AMD Zen-1 machine:
// suspension N = 1e3 ... 1e5 within 1.26x of the best of 100/150/200/400, 2x faster than 200 at
// N = 1e5; 100 is best from 1e4 up but 1.7x slower at N = 1e3).
int default_leaf_capacity(double eps) {
  switch (fmm::fmm_table_digits_for(eps)) {
    case 3:
      return simd_level() == SimdLevel::avx512 ? 200 : 150;
    case 6:
      return 400;
    case 9:
      return 600;
    default:
      return 800;
  }
}

// Automatic leaves fitted to the cloud (bench/rpy/RESULTS.md at commit 010249d "Fitted leaf grid"; fmm::fit_leaf_grid
// enlarges the root so that leaves of a chosen occupancy span the cloud, instead of the octree's
// factor-8 steps: a uniform N = 1e5 cloud gets 24 or 195 points per leaf, ~60 is best at 6 digits).
// Measured without AVX-512, 1 thread: at 1e-6, N = 1e5, uniform suspension 1.30x faster (195 -> 58
// points per leaf), cylinder surface 1.13x, eight spheres 1.25x; at 1e-3, spherical BD cloud,
// 1.0-1.28x from N = 2e3 to 1e5 and 1.33x at 2e5.
//
// The rule, per plane-wave table: the target occupancy and the point counts measured to gain. The
// upper end at 6 digits is set by accuracy: smaller leaves move work into the far field, whose
// 6-digit plane-wave error then weighs more (uniform suspension at 1e-6: 5.9e-7 -> 6.8e-7 at
// N = 1e5, but 9.8e-7 at 5e5 and 1.03e-6 at 1e6, where the bounding-cube tree gives 9.05e-7). At 3
// digits the errors stay near 3e-4; 2e5 is the largest size measured. With the AVX-512 kernels
// (Intel machine) leaves of 20-60 points at 1e-3, 40-150 at 1e-6 and 100-250 at 1e-9 were no faster
// than the bounding-cube tree's 200 / 400 / 600-point capacities on suspensions and cylinders of
// 1e4 ... 2e5 points, mostly slower (cylinder 1e5 at 1e-6: 0.82x at 60 points per leaf): the near
// field is cheap enough there that large leaves pay. The exception is a partly split tree (leaves
// on two levels): suspension 2e5 at 1e-6, share 0.67, 1.32x (Intel), 1.17-1.22x (AMD Zen-4).
//
// Large volume-filling clouds at 6 digits, with either kernel set: a uniform cloud's bounding-cube
// tree jumps from ~120 points per leaf at 5e5 points to ~240 at 1e6 (4096 leaves), where the
// near field outweighs the far field. Fitted leaves move work into the far field and here lower
// the error as well. Measured with these leaves forced on commit 1cc8359, 2026-12-06, Intel Xeon
// (AVX-512), 2 vCPUs, 1 thread, random suspension N = 1e6 at 1e-6, process CPU time of one product
// (the machine was shared, so wall times were not comparable), medians of 3 per run:
//  - AVX-512 kernels: bounding-cube tree 12.4-14.7 s (4 runs), 120 points per leaf (8000 leaves)
//    11.0-11.1 s (3 runs), 100 points 13.0 s, 140 points 12.3 s, 80 points 12.3 s;
//  - AVX2 level: bounding-cube tree 16.5 s, 120 points 15.3 s, 80 points (12167 leaves) 13.4 s;
//  - U's error at 200 sampled rows: 9.05e-7 (bounding cube), 7.99e-7 (120), 8.30e-7 (80),
//    9.33e-7 (100). Leaves of ~57 points exceeded eps at this size (1.03e-6, noted above).
constexpr std::size_t kLargeCloud = 500000;
constexpr double kVolumeFillingCloud = 0.5;  // fit_leaf_grid's fill above which a cloud counts as volume-filling

fmm::FittedGridRule fitted_grid_rule(double eps, std::size_t n) {
  if (fmm::fmm_table_digits_for(eps) == 6 && n >= kLargeCloud) {
    const int occupancy = simd_level() == SimdLevel::avx512 ? 120 : 80;
    return {occupancy, kLargeCloud, std::numeric_limits<std::size_t>::max(), kVolumeFillingCloud};
  }
  if (simd_level() == SimdLevel::avx512) {
    // At 6 digits, partly split trees of volume-filling clouds only (AMD Zen-4 machine,
    // bench/rpy/RESULTS.md at commit 010249d "Partly split trees with the AVX-512 kernels"): uniform suspensions
    // 1.17-1.22x (shares 0.67-0.69); balls (fill 0.58, share 0.82-0.94 from their curved edge)
    // lost 0.74-0.99x, and at 3 digits every refit lost (0.78-0.88x).
    if (fmm::fmm_table_digits_for(eps) == 6) return {60, 10000, 200000, 0.8, false, 0.97};
    return {};
  }
  switch (fmm::fmm_table_digits_for(eps)) {
    // Volume-filling clouds only: on surfaces (cylinder, eight spheres) leaves of 20 points were
    // 0.75-0.95x, their leaves have fewer neighbours and the near field costs less.
    case 3:
      return {20, 2000, 200000, 0.25};
    case 6:
      return {60, 5000, 200000, 0.0};  // cylinder 2.0x, eight 1.45x, BD cloud 1.13x at 5e3
    default:
      return {};  // 1e-9: 195 and 100 points per leaf tie
  }
}

}  // namespace rpyfmm::rpy::detail
