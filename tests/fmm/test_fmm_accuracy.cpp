// End-to-end accuracy of the adaptive plane-wave FMM against the plain direct sum:
// the contract is relative l2 error <= eps for potential, gradient and Hessian separately.
#include <gtest/gtest.h>

#include <functional>

#include "fmm_test_util.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

using rpyfmm::fmm::FmmOptions;
using rpyfmm::fmm::LaplaceFmm;

namespace {

struct Errors {
  double pot, grad, hess;
};

Errors run(const std::vector<double>& src, const std::vector<double>& tgt, std::size_t nd, double eps,
           int leaf = 0, std::size_t nsample = 400) {
  const std::size_t n = src.size() / 3, m = tgt.empty() ? n : tgt.size() / 3;
  FmmOptions o;
  o.eps = eps;
  o.leaf_capacity = leaf;
  LaplaceFmm fmm(o);
  fmm.set_points(src, tgt);
  const auto q = fmmtest::charges(n, nd, 7);
  std::vector<double> res(nd * m * 10);
  fmm.evaluate(q, nd, rpyfmm::fmm::all_outputs, res);
  const auto which = fmmtest::sample(m, nsample, 3);
  const auto ref = fmmtest::direct(src, q, nd, tgt, which);
  Errors e{0, 0, 0};
  for (std::size_t d = 0; d < nd; ++d) {
    e.pot = std::max(e.pot, fmmtest::rel_l2(res, m, ref, which, d, 0, 1));
    e.grad = std::max(e.grad, fmmtest::rel_l2(res, m, ref, which, d, 1, 4));
    e.hess = std::max(e.hess, fmmtest::rel_l2(res, m, ref, which, d, 4, 10));
  }
  return e;
}

void expect_within(const Errors& e, double eps, const std::string& what) {
  EXPECT_LE(e.pot, eps) << what << " potential";
  EXPECT_LE(e.grad, eps) << what << " gradient";
  EXPECT_LE(e.hess, eps) << what << " Hessian";
  std::printf("%-28s eps=%.0e  pot %.2e  grad %.2e  hess %.2e\n", what.c_str(), eps, e.pot, e.grad, e.hess);
}

}  // namespace

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
