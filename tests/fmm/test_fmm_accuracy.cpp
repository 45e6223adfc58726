// End-to-end accuracy of the adaptive plane-wave FMM against the plain direct sum:
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

// Small leaves force deep trees, so every list and the plane-wave M2L are exercised at small N.
TEST(FmmAccuracy, UniformCube) {
  const auto x = fmmtest::cube(3000, 1);
  for (double eps : {1e-3, 1e-6}) expect_within(run(x, {}, 1, eps, 20), eps, "cube");
}

TEST(FmmAccuracy, SurfacesAndClusters) {
  const std::vector<std::pair<std::string, std::vector<double>>> cases = {
      {"sphere", fmmtest::sphere(2000, 2)},     {"octant", fmmtest::sphere(2000, 3, true)},
      {"cylinder", fmmtest::cylinder(2000, 4)}, {"plummer", fmmtest::plummer(2000, 5)},
      {"two_clusters", fmmtest::two_clusters(1500, 6)}, {"line", fmmtest::line(1500, 7)}};
  for (const auto& [name, x] : cases) expect_within(run(x, {}, 1, 1e-3, 16), 1e-3, name);
}
