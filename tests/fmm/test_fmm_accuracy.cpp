// End-to-end accuracy of the adaptive plane-wave FMM against the plain direct sum:
// the contract is relative l2 error <= eps for potential, gradient and Hessian separately.
#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "fmm_accuracy_util.hpp"
#include "fmm_test_util.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "simd_levels.hpp"

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
      {"sphere", fmmtest::sphere(2000, 2)},
      {"octant", fmmtest::sphere(2000, 3, true)},
      {"cylinder", fmmtest::cylinder(2000, 4)},
      {"plummer", fmmtest::plummer(2000, 5)},
      {"two_clusters", fmmtest::two_clusters(1500, 6)},
      {"line", fmmtest::line(1500, 7)}};
  for (const auto& [name, x] : cases) expect_within(run(x, {}, 1, 1e-3, 16), 1e-3, name);
}

namespace {

// The particles of tests/mpi/cli_across_ranks.cmake, from the same linear congruential generator:
// 701 positions in [0, 40) (sources), charges in [0.5, 1.5), and the "forces" in [-1, 1] used as
// targets, of which those with x >= 0 are kept (one side of the sources' corner).
struct CliParticles {
  std::vector<double> sources, charges, targets;
};

CliParticles cli_particles() {
  unsigned long long seed = 12345;
  const auto next = [&seed](unsigned long long modulus) {
    seed = (seed * 1103515245ULL + 12345ULL) % 2147483648ULL;
    return static_cast<double>(seed % modulus);
  };
  CliParticles p;
  for (int i = 0; i <= 700; ++i) {
    double target[3];
    for (double& t : target) {
      p.sources.push_back(next(40000) / 1000.0);
      const double v = next(2001);
      t = v < 1000 ? -(1000 - v) / 1000.0 : (v - 1000) / 1000.0;
    }
    p.charges.push_back((next(1000) + 500) / 1000.0);
    if (target[0] >= 0.0) p.targets.insert(p.targets.end(), target, target + 3);
  }
  return p;
}

}  // namespace

// The 3-digit table's expansion order holds the Hessian's contract as well as the potential's
// (fmm_order_for: at order 8 this input's Hessian error was 1.58e-3 at the AVX2 level). Every
// instruction-set level the machine has: the levels build different trees (leaf capacities, direct
// limits), and the AVX2 level's put more of these targets' field through the expansions.
TEST(FmmAccuracy, HessianAtTheThreeDigitTable) {
  const CliParticles p = cli_particles();
  const std::size_t m = p.targets.size() / 3;
  const auto all = fmmtest::sample(m, m, 1);
  const auto ref = fmmtest::direct(p.sources, p.charges, 1, p.targets, all);
  for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels()) {
    const rpyfmm::ScopedSimdLevel scope(level);
    LaplaceFmm fmm(FmmOptions{.tolerance = 1e-3});
    fmm.set_points(p.sources, p.targets);
    std::vector<double> res(m * 10);
    fmm.evaluate(p.charges, 1, rpyfmm::fmm::all_outputs, res);
    const fmmtest::Errors e{fmmtest::rel_l2(res, m, ref, all, 0, 0, 1), fmmtest::rel_l2(res, m, ref, all, 0, 1, 4),
                            fmmtest::rel_l2(res, m, ref, all, 0, 4, 10)};
    expect_within(e, 1e-3, std::string("cli set at ") + rpyfmm::simd_level_name(level));
  }
}
