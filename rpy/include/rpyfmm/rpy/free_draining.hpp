// rpyfmm::rpy — the free-draining "mobility" (no hydrodynamic interactions):
// M = diag(1 / (6 pi eta a_i)), Stokes drag on each sphere (docs/theory/bd.md). It is a
// MobilityOperator like every HI solver, so BD with and without HI runs the
// same code path; its square root is exact and costs O(N).
#pragma once

#include <string>
#include <vector>

#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::rpy {

class FreeDrainingMobility final : public MobilityOperator {
 public:
  explicit FreeDrainingMobility(Geometry geometry = Geometry::open(), double viscosity = 1.0);
  /// "none" — the method name used in configs and the factory.
  [[nodiscard]] std::string name() const override { return "none"; }
  /// The exact diagonal square root (do_apply_sqrt).
  [[nodiscard]] SqrtMethod native_sampler() const override { return SqrtMethod::cholesky; }

 protected:
  void on_positions_set() override;
  void do_apply(const double* forces, double* velocities, std::size_t nrhs) const override;
  /// Exact: w_i = z_i / sqrt(6 pi eta a_i) for every method (reported as cholesky,
  /// no operator products).
  SqrtReport do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                           const SqrtOptions& options) const override;

 private:
  std::vector<double> mobility_;       // 1 / (6 pi eta a_i)
  std::vector<double> sqrt_mobility_;  // its square root
};

}  // namespace rpyfmm::rpy
