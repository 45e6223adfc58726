// PSE: M_r and M_w are each symmetric positive (semi)definite for every
// configuration, overlapping pairs included ([PSE] Sec. II.A, App. B), checked
// by dense assembly and Eigen's symmetric eigensolver.
#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Dense>
#include <utility>

#include "ewald_reference.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

namespace {

Eigen::MatrixXd assemble(const LinearOperatorView& op) {
  const auto n = static_cast<Eigen::Index>(op.n);
  Eigen::MatrixXd unit = Eigen::MatrixXd::Identity(n, n);
  Eigen::MatrixXd cols(n, n);
  op.apply(std::span<const double>(unit.data(), op.n * op.n), std::span<double>(cols.data(), op.n * op.n), op.n);
  return cols;  // column j = M e_j (column-major)
}

/// Configuration with pairs at r = 0, 0.1a, 1a, 1.99a, 2a, 2.01a, and across the boundary.
std::vector<double> overlapping_configuration(const std::array<double, 3>& L, bool coincident) {
  // One pair per row.
  // clang-format off
  std::vector<double> x = {1.0, 1.0, 1.0,  1.0, 1.0, coincident ? 1.0 : 1.3,  // coincident (or 0.3a)
                           4.0, 4.0, 4.0,  4.1, 4.0, 4.0,         // 0.1a
                           7.0, 2.0, 3.0,  7.0, 3.0, 3.0,         // 1a
                           2.0, 7.0, 2.0,  2.0, 7.0, 3.99,        // 1.99a
                           5.0, 8.0, 6.0,  7.0, 8.0, 6.0,         // 2a
                           8.0, 5.0, 8.0,  8.0, 7.01, 8.0,        // 2.01a
                           0.2, 6.0, 6.0,  L[0] - 0.5, 6.0, 6.0}; // across the x boundary, 0.7a
  // clang-format on
  const auto extra = pse_test::random_points(10, L, 21);
  x.insert(x.end(), extra.begin(), extra.end());
  return x;
}

}  // namespace

TEST(PseSpd, RealAndWavePartsAreSymmetricPositive) {
  const std::array<double, 3> L = {10.0, 9.0, 11.0};
  for (const bool coincident : {false, true}) {
    const auto x = overlapping_configuration(L, coincident);
    for (double xa : {1.0, 2.0}) {
      // Double-precision wave grids: symmetric and PSD to double round-off. Single-precision ones
      // (the automatic choice at this tolerance): to float round-off (test_pse_precision.cpp).
      for (const auto& [precision, roundoff] :
           {std::pair{WavePrecision::double_precision, 1e-12}, std::pair{WavePrecision::single_precision, 1e-6}}) {
        PseOptions o;
        o.tolerance = 1e-3;
        o.xi = xa;
        o.wave_precision = precision;
        PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
        op.set_positions(x, 1.0);
        const Eigen::MatrixXd Mr = assemble(op.real_space_operator());
        const Eigen::MatrixXd Mw = assemble(op.wave_space_operator());
        const double scale_r = Mr.cwiseAbs().maxCoeff(), scale_w = Mw.cwiseAbs().maxCoeff();
        EXPECT_LE((Mr - Mr.transpose()).cwiseAbs().maxCoeff(), 1e-12 * scale_r) << "M_r asymmetric, xi a " << xa;
        EXPECT_LE((Mw - Mw.transpose()).cwiseAbs().maxCoeff(), roundoff * scale_w) << "M_w asymmetric, xi a " << xa;
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> er(0.5 * (Mr + Mr.transpose()));
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ew(0.5 * (Mw + Mw.transpose()));
        // Coincident particles make M_r (like RPY itself) exactly singular: PSD, not PD, then.
        if (coincident) {
          EXPECT_GE(er.eigenvalues().minCoeff(), -1e-12 * er.eigenvalues().maxCoeff()) << "M_r not PSD, xi a " << xa;
        } else {
          EXPECT_GT(er.eigenvalues().minCoeff(), 1e-6 * er.eigenvalues().maxCoeff()) << "M_r not PD, xi a " << xa;
        }
        EXPECT_GE(ew.eigenvalues().minCoeff(), -roundoff * ew.eigenvalues().maxCoeff()) << "M_w not PSD, xi a " << xa;
        // The full operator: M = M_r + M_w, SPD.
        const auto dense = op.assemble_dense();
        const Eigen::Map<const Eigen::MatrixXd> M(dense.data(), Mr.rows(), Mr.cols());
        EXPECT_LE((M - (Mr + Mw)).cwiseAbs().maxCoeff(), roundoff * (scale_r + scale_w));
      }
    }
  }
}

TEST(PseSpd, ResultDoesNotDependOnThreadCount) {
  const std::array<double, 3> L = {14.0, 14.0, 14.0};
  const auto x = pse_test::random_points(300, L, 31);
  const auto f = pse_test::random_points(300, {1.0, 1.0, 1.0}, 32);
  PseOptions o;
  o.xi = 0.5;
  PseRpy op(Geometry::periodic(14.0), 1.0, o);
  op.set_positions(x, 1.0);
  std::vector<double> u1(f.size()), u2(f.size()), s1(f.size()), s2(f.size());
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  op.apply(f, u1);
  op.sample(7, 3, s1);
  omp_set_num_threads(std::max(2, saved));
  op.apply(f, u2);
  op.sample(7, 3, s2);
  omp_set_num_threads(saved);
  // FFTW's threaded transforms may reorder sums: agreement to round-off, not bitwise.
  EXPECT_LT(pse_test::rel_l2(u1, u2), 1e-13);
  EXPECT_LT(pse_test::rel_l2(s1, s2), 1e-13);
}
