// Test-only reference mobility: the RPY tensor for equal radii written plainly
// from docs/theory/rpy.md (Guan eq. 3.1), assembled densely, with an exact
// square root by Cholesky (Eigen). Independent of the library's solvers, so the
// BD tests do not depend on the direct/FMM operators or on Lanczos.
#pragma once

#include <Eigen/Dense>
#include <cmath>
#include <numbers>
#include <string>

#include "rpyfmm/rpy/mobility.hpp"

namespace bdtest {

class DenseRpy final : public rpyfmm::rpy::MobilityOperator {
 public:
  explicit DenseRpy(double eta = 1.0) : MobilityOperator(rpyfmm::rpy::Geometry::open(), eta, "DenseRpy") {}
  std::string name() const override { return "dense-test"; }
  rpyfmm::rpy::SqrtMethod native_sampler() const override { return rpyfmm::rpy::SqrtMethod::cholesky; }
  int applications = 0;

  /// 3x3 block M_ij (i != j) for equal radii a at separation d = x_i - x_j.
  static Eigen::Matrix3d pair(const Eigen::Vector3d& d, double a, double eta) {
    const double r = d.norm();
    const Eigen::Vector3d e = d / r;
    if (r > 2 * a) {
      const double c = 1.0 / (8 * std::numbers::pi * eta * r);
      return c * ((1 + 2 * a * a / (3 * r * r)) * Eigen::Matrix3d::Identity() +
                  (1 - 2 * a * a / (r * r)) * e * e.transpose());
    }
    const double c = 1.0 / (6 * std::numbers::pi * eta * a);
    return c * ((1 - 9 * r / (32 * a)) * Eigen::Matrix3d::Identity() + (3 * r / (32 * a)) * e * e.transpose());
  }

 protected:
  void on_positions_set() override {
    const std::size_t n = size();
    const double a = radii()[0];
    m_.setZero(3 * n, 3 * n);
    for (std::size_t i = 0; i < n; ++i) {
      m_.block<3, 3>(3 * i, 3 * i) = Eigen::Matrix3d::Identity() / (6 * std::numbers::pi * viscosity() * a);
      for (std::size_t j = 0; j < n; ++j) {
        if (i == j) continue;
        Eigen::Vector3d d;
        for (int c = 0; c < 3; ++c) d[c] = positions()[3 * i + c] - positions()[3 * j + c];
        m_.block<3, 3>(3 * i, 3 * j) = pair(d, a, viscosity());
      }
    }
    llt_.compute(m_);
  }
  void do_apply(const double* f, double* u, std::size_t nrhs) const override {
    const auto n = static_cast<Eigen::Index>(3 * size());
    for (std::size_t k = 0; k < nrhs; ++k) {
      Eigen::Map<const Eigen::VectorXd> fk(f + k * n, n);
      Eigen::Map<Eigen::VectorXd> uk(u + k * n, n);
      uk = m_ * fk;
    }
    const_cast<DenseRpy*>(this)->applications += static_cast<int>(nrhs);
  }
  rpyfmm::rpy::SqrtReport do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                        const rpyfmm::rpy::SqrtOptions&) const override {
    const auto n = static_cast<Eigen::Index>(3 * size());
    for (std::size_t k = 0; k < nrhs; ++k) {
      Eigen::Map<const Eigen::VectorXd> zk(z.data() + k * n, n);
      Eigen::Map<Eigen::VectorXd> wk(w.data() + k * n, n);
      wk = llt_.matrixL() * zk;  // L L^T = M: cov(L z) = M
    }
    rpyfmm::rpy::SqrtReport r;
    r.method = rpyfmm::rpy::SqrtMethod::cholesky;
    return r;
  }

 private:
  Eigen::MatrixXd m_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
};

}  // namespace bdtest
