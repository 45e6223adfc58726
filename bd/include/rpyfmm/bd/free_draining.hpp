// rpyfmm::bd — the free-draining "mobility" (no hydrodynamic interactions):
// M = diag(1 / (6 pi eta a_i)) (paper 001, eq. 3; MATH.md §6). It is a
// MobilityOperator like every HI solver, so BD with and without HI runs the
// same code path; its square root is exact and costs O(N).
#pragma once

#include <string>
#include <vector>

#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::bd {

class FreeDrainingMobility final : public rpy::MobilityOperator {
 public:
  explicit FreeDrainingMobility(rpy::Geometry geometry = rpy::Geometry::open(), double viscosity = 1.0);
  /// "none" — the method name used in configs and the factory.
  [[nodiscard]] std::string name() const override { return "none"; }

 protected:
  void on_positions_set() override;
  void do_apply(const double* forces, double* velocities, std::size_t nrhs) const override;
  /// Exact: w_i = z_i / sqrt(6 pi eta a_i) for every method (reported as cholesky,
  /// no operator products).
  rpy::SqrtReport do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                const rpy::SqrtOptions& options) const override;

 private:
  std::vector<double> mobility_;       // 1 / (6 pi eta a_i)
  std::vector<double> sqrt_mobility_;  // its square root
};

}  // namespace rpyfmm::bd
