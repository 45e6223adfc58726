// rpyfmm::rpy — the free-draining "mobility" (no hydrodynamic interactions):
// M = diag(1 / (6 pi eta a_i)), Stokes drag on each sphere (docs/theory/bd.md), and with
// rotation W_i = T_i / (8 pi eta a_i^3), the Stokes torque on a sphere (the r = 0 limits of
// docs/theory/rpy.md section 7, no coupling). It is a MobilityOperator like every HI solver, so BD
// with and without HI runs the same code path; its square roots are exact and cost O(N).
#pragma once

#include <string>
#include <vector>

#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::rpy {

/// The free-draining mobilities of one sphere of radius a in a solvent of viscosity eta: the
/// Stokes drag's 1 / (6 pi eta a), the Stokes torque's 1 / (8 pi eta a^3), and their square roots
/// (docs/theory/bd.md). FreeDrainingMobility and the engines that tabulate them per particle type
/// take them from here, so their values agree bit for bit.
struct SphereMobility {
  double translation = 0.0;
  double sqrt_translation = 0.0;
  double rotation = 0.0;
  double sqrt_rotation = 0.0;
};
[[nodiscard]] SphereMobility sphere_mobility(double radius, double viscosity);

class FreeDrainingMobility final : public MobilityOperator {
 public:
  explicit FreeDrainingMobility(Geometry geometry = Geometry::open(), double viscosity = 1.0);
  /// "none" — the method name used in configs and the factory.
  [[nodiscard]] std::string name() const override { return "none"; }
  /// The exact diagonal square root (do_apply_sqrt).
  [[nodiscard]] SqrtMethod native_sampler() const override { return SqrtMethod::cholesky; }
  /// U = F / (6 pi eta a), W = T / (8 pi eta a^3) per sphere.
  [[nodiscard]] bool supports_rotation() const override { return true; }

 protected:
  void on_positions_set() override;
  void do_apply(const double* forces, double* velocities, std::size_t nrhs) const override;
  /// Exact: w_i = z_i / sqrt(6 pi eta a_i) for every method (reported as cholesky,
  /// no operator products).
  SqrtReport do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                           const SqrtOptions& options) const override;
  void do_apply_rotation(const double* forces, const double* torques, double* velocities,
                         double* angular_velocities) const override;
  /// Exact: w_t,i = z_t,i / sqrt(6 pi eta a_i), w_r,i = z_r,i / sqrt(8 pi eta a_i^3) for every
  /// method (reported as cholesky, no operator products); M^{1/2} z, the principal root.
  SqrtReport do_apply_sqrt_rotation(std::span<const double> z_translation, std::span<const double> z_rotation,
                                    std::span<double> w_translation, std::span<double> w_rotation,
                                    const SqrtOptions& options) const override;

 private:
  std::vector<double> mobility_;                // 1 / (6 pi eta a_i)
  std::vector<double> sqrt_mobility_;           // its square root
  std::vector<double> rotation_mobility_;       // 1 / (8 pi eta a_i^3)
  std::vector<double> sqrt_rotation_mobility_;  // its square root
};

}  // namespace rpyfmm::rpy
