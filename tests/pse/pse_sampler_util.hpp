// Helpers shared by the PSE sampler tests (test_pse_sampler.cpp, test_pse_statistics.cpp):
// a small periodic system with overlapping and near pairs, and dense assembly as an Eigen matrix.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <vector>

#include "rpyfmm/rpy/mobility.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"

namespace pse_test {

struct SmallSystem {
  std::array<double, 3> L = {9.0, 9.0, 10.0};
  std::vector<double> x = {1.0, 1.0, 1.0, 2.5, 1.2, 1.0, 6.0, 5.0, 8.5, 6.2, 5.3, 0.4};  // overlap + near pairs
  rpyfmm::rpy::pse::PseOptions options() const {
    rpyfmm::rpy::pse::PseOptions o;
    o.tolerance = 1e-2;  // the covariance identity holds for the discrete operator at any eps;
    o.xi = 1.0;          // a coarse grid keeps the 5000-sample estimates fast
    o.lanczos_tolerance = 1e-8;
    // Double-precision wave grids: the dense square-root comparisons go to 1e-8 and below.
    o.wave_precision = rpyfmm::rpy::pse::WavePrecision::double_precision;
    return o;
  }
};

inline Eigen::MatrixXd dense(const rpyfmm::rpy::MobilityOperator& op) {
  const auto d = op.assemble_dense();
  const auto n = static_cast<Eigen::Index>(3 * op.size());
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(d.data(), n, n);
}

/// The 6N matrix of the grand mobility from products with unit vectors, [U; W] rows, [F; T] columns.
inline Eigen::MatrixXd grand_matrix(const rpyfmm::rpy::MobilityOperator& op) {
  const std::size_t n3 = 3 * op.size();
  Eigen::MatrixXd M(2 * n3, 2 * n3);
  std::vector<double> F(n3), T(n3), U(n3), W(n3);
  for (std::size_t c = 0; c < 2 * n3; ++c) {
    std::fill(F.begin(), F.end(), 0.0);
    std::fill(T.begin(), T.end(), 0.0);
    (c < n3 ? F[c] : T[c - n3]) = 1.0;
    op.apply(F, T, U, W);
    for (std::size_t r = 0; r < n3; ++r) {
      M(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = U[r];
      M(static_cast<Eigen::Index>(n3 + r), static_cast<Eigen::Index>(c)) = W[r];
    }
  }
  return M;
}

}  // namespace pse_test
