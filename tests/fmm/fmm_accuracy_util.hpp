// End-to-end accuracy helpers shared by test_fmm_accuracy.cpp and test_fmm_accuracy_tight.cpp:
// run the FMM on a point set and measure the relative l2 error of each output against the
// plain direct sum at sampled targets.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "fmm_test_util.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

namespace fmmtest {

struct Errors {
  double pot, grad, hess;
};

inline Errors run(const std::vector<double>& src, const std::vector<double>& tgt, std::size_t nd, double eps,
                  int leaf = 0, std::size_t nsample = 400) {
  const std::size_t n = src.size() / 3, m = tgt.empty() ? n : tgt.size() / 3;
  rpyfmm::fmm::FmmOptions o;
  o.tolerance = eps;
  o.leaf_capacity = leaf;
  rpyfmm::fmm::LaplaceFmm fmm(o);
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

inline void expect_within(const Errors& e, double eps, const std::string& what) {
  EXPECT_LE(e.pot, eps) << what << " potential";
  EXPECT_LE(e.grad, eps) << what << " gradient";
  EXPECT_LE(e.hess, eps) << what << " Hessian";
  std::printf("%-28s eps=%.0e  pot %.2e  grad %.2e  hess %.2e\n", what.c_str(), eps, e.pot, e.grad, e.hess);
}

}  // namespace fmmtest
