// rpyfmm — DirectRpy: the exact O(N^2) Rotne-Prager-Yamakawa mobility operator.
//
// U_i = sum_j M_ij F_j with the pair blocks of rpy_kernel.hpp (docs/theory/rpy.md),
// including overlap regimes and the self term. It is the reference every fast
// operator (FMM, PSE) is checked against, and the right choice for small N
// (up to a few thousand particles). Open geometry only. Suspensions at extreme
// length scales (extent 1e137, or 1e-130) are evaluated in units of their size,
// exactly (M is homogeneous of degree -1 in its lengths).
//
// Work: 3N x 3N pair blocks per right-hand side, parallel over target
// particles with OpenMP; each velocity is summed by one thread in a fixed
// order, so results do not depend on the number of threads. Block products
// (apply_block) evaluate each pair block once for all right-hand sides.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::rpy {

class DirectRpy final : public MobilityOperator {
 public:
  /// Throws rpyfmm::Error (not_supported) for a periodic geometry and
  /// (invalid_argument) for a viscosity that is not finite and > 0.
  explicit DirectRpy(Geometry geometry = Geometry::open(), double viscosity = 1.0);

  [[nodiscard]] std::string name() const override { return "direct"; }
  /// The grand mobility with torques (rpy_rotation_kernel.hpp): apply(F, T, U, W).
  [[nodiscard]] bool supports_rotation() const override { return true; }

  /// The rows of particles [first, first + count) of U = M F: `forces` has 3N entries,
  /// `velocities` 3 count. Bit for bit the same rows as apply(): each target is summed over all
  /// sources in the same order, with the whole set's length units and load scaling; for callers
  /// that split the targets (rpyfmm::mpi::DistributedDirectRpy). Validation as apply(), plus
  /// first + count <= N.
  void apply_rows(std::size_t first, std::size_t count, std::span<const double> forces,
                  std::span<double> velocities) const;

 protected:
  void on_positions_set() override;
  void do_apply(const double* forces, double* velocities, std::size_t nrhs) const override;
  /// direct_rotation.cpp: every pair's four blocks, parallel over targets, fixed order per target.
  void do_apply_rotation(const double* forces, const double* torques, double* velocities,
                         double* angular_velocities) const override;

 private:
  // Structure-of-arrays copies of positions and radii (vectorizable inner loops), in units of
  // 2^scale_exponent_ (rpy/src/length_units.hpp; 0 for suspensions of ordinary lengths).
  std::vector<double> x_, y_, z_, a_, inv_a_;
  int scale_exponent_ = 0;

  /// Rows [first, first + count) of M F for nrhs right-hand sides (forces already load-scaled);
  /// right-hand side k's rows at velocities + 3 count k.
  void sum_rows(const double* forces, std::size_t nrhs, std::size_t first, std::size_t count, double* velocities) const;
};

}  // namespace rpyfmm::rpy
