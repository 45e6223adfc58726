// End-to-end accuracy at tight tolerances (label slow) of the adaptive plane-wave FMM against the plain direct sum:
// the contract is relative l2 error <= eps for potential, gradient and Hessian separately.
#include <gtest/gtest.h>

#include <functional>

#include "fmm_accuracy_util.hpp"
#include "fmm_test_util.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

using rpyfmm::fmm::FmmOptions;
using rpyfmm::fmm::LaplaceFmm;

using fmmtest::expect_within;
using fmmtest::run;

TEST(FmmAccuracyTight, UniformCube) {
  const auto x = fmmtest::cube(3000, 1);
  for (double eps : {1e-9, 1e-12}) expect_within(run(x, {}, 1, eps, 20), eps, "cube");
}

TEST(FmmAccuracyTight, SurfacesAndClusters) {
  const std::vector<std::pair<std::string, std::vector<double>>> cases = {
      {"sphere", fmmtest::sphere(3000, 2)},
      {"octant", fmmtest::sphere(3000, 3, true)},
      {"cylinder", fmmtest::cylinder(3000, 4)},
      {"plummer", fmmtest::plummer(3000, 5)},
      {"two_clusters", fmmtest::two_clusters(2000, 6)},
      {"line", fmmtest::line(2000, 7)}};
  for (const auto& [name, x] : cases)
    for (double eps : {1e-6, 1e-9, 1e-12}) {
      // Clusters of side 1e-4 at distance ~1 are conditioned to ~1e-12 by their coordinates alone:
      // at 1e-12 use clusters of side 1e-2 (still 7 tree levels apart from the root).
      if (name == "two_clusters" && eps < 1e-10) {
        expect_within(run(fmmtest::two_clusters(2000, 6, 1e-2), {}, 1, eps, 16), eps, "two_clusters_1e-2");
        continue;
      }
      expect_within(run(x, {}, 1, eps, 16), eps, name);
    }
}
