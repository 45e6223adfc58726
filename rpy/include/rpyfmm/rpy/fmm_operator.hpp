// rpyfmm — FmmRpy: the free-space Rotne-Prager-Yamakawa mobility U = M F in
// O(N) from one multi-density Laplace FMM pass plus an exact near field.
//
// Far field (docs/theory/rpy.md; W. Guan, "Fast Algorithms for Brownian Dynamics with Hydrodynamic
// Interactions", PhD dissertation, UNC Chapel Hill, §3.1.1), for r > a_i + a_j:
//   U_i,k = C1 [ phi_i(F^(k)) + sum_m x_i,m E_k,i(F^(m)) - E_k,i(x.F) ]
//         + 1/(24 pi eta) [ a_i^2 sum_m T_km,i(F^(m)) + sum_m T_km,i(a^2 F^(m)) ],   C1 = 1/(8 pi eta)
// with phi the Laplace potential of a charge vector, E = -grad phi and
// T = -grad grad phi. Equal radii need four charge vectors per right-hand side
// (F^(1..3): potential, field, field gradient; x.F: field only); different
// radii add a^2 F^(1..3) (field gradient only): seven. All charge vectors of
// all right-hand sides travel one FMM pass together.
//
// Rotation (docs/theory/rpy.md, section 7): torques add three densities T^(1..3) to the same pass;
// U from T = curl Phi_T / (8 pi eta), W from F = curl Phi_F / (8 pi eta), W from T =
// grad div Phi_T / (16 pi eta) in the far field, exact pair couplings in the near field
// (fmm_rotation.cpp), on the force-only plan.
//
// Near field: the FMM runs in "far field only" mode; every pair of adjacent
// leaves (U list) is evaluated with the exact RPY pair block (rpy_kernel.hpp,
// both overlap regimes), plus the self term F_i / (6 pi eta a_i). Leaves are
// never smaller than 2 max_i a_i, so every overlapping pair (r <= a_i + a_j)
// lies in the near field and the far-field formula is only used where it is exact.
// Each pair of adjacent leaves is evaluated once for both directions (M_ji = M_ij)
// in trees of 64 leaves or more, in coloured parallel rounds whose results do not
// depend on the thread count (rpy/src/near_schedule.hpp).
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/rpy/mobility.hpp"

namespace rpyfmm::fmm {
class LaplaceFmm;
struct FittedGridRule;
}  // namespace rpyfmm::fmm

namespace rpyfmm::rpy {

namespace detail {
struct NearSchedule;
}

struct FmmRpyOptions {
  /// Requested relative l2 error of U against the exact (direct) product, in [1e-12, 1e-1].
  double tolerance = 1e-6;
  /// Points per FMM leaf; 0 = automatic: a capacity measured per tolerance and, where it pays,
  /// a root box fitted so that leaves hold a measured best occupancy (fmm_operator.cpp; with the
  /// AVX-512 kernels only at 6 digits, where the bounding-cube tree is partly split or a
  /// volume-filling cloud has 5e5 points or more).
  int leaf_capacity = 0;
};

class FmmRpy final : public MobilityOperator {
 public:
  /// Throws rpyfmm::Error: not_supported for a periodic geometry, invalid_argument for a
  /// tolerance outside [1e-12, 1e-1] or a viscosity that is not finite and > 0.
  explicit FmmRpy(Geometry geometry = Geometry::open(), double viscosity = 1.0, FmmRpyOptions options = {});
  ~FmmRpy() override;

  [[nodiscard]] std::string name() const override { return "fmm"; }
  /// The grand mobility with rotation (docs/theory/rpy.md, section 7): torques and angular
  /// velocities from the same Laplace pass, to the same tolerance.
  [[nodiscard]] bool supports_rotation() const override { return true; }
  [[nodiscard]] const FmmRpyOptions& options() const { return options_; }
  /// Tolerance handed to the Laplace FMM of laplace_plan(): options().tolerance. Within a factor 10
  /// above a plane-wave table's step (1e-3, 1e-6, 1e-9, 1e-12) the plan also takes more quadrature
  /// nodes and a higher order (docs/theory/rpy.md, Sec. 2; laplace_plan().stats()).
  [[nodiscard]] double laplace_eps() const { return options_.tolerance; }
  /// Stage times of the last apply: the FMM's stages plus "rpy_charges", "rpy_far", "rpy_near", "rpy_total".
  [[nodiscard]] StageTimes last_timings() const;
  /// The Laplace FMM plan of every product, with and without torques (tree statistics, near-field
  /// structure); null before set_positions.
  [[nodiscard]] const fmm::LaplaceFmm* laplace_plan() const { return plan_.fmm.get(); }

 protected:
  void on_positions_set() override;
  void do_apply(const double* forces, double* velocities, std::size_t nrhs) const override;
  void do_apply_rotation(const double* forces, const double* torques, double* velocities,
                         double* angular_velocities) const override;

 private:
  // A Laplace FMM plan on centered_ and the order of its near-field leaf pairs.
  struct Plan {
    std::unique_ptr<fmm::LaplaceFmm> fmm;
    std::unique_ptr<detail::NearSchedule> near_schedule;
  };
  [[nodiscard]] Plan make_plan(int leaf_capacity, const fmm::FittedGridRule& fitted_grid) const;
  // One FMM pass over the far-field densities (nd = outputs.size()); records the stage times.
  [[nodiscard]] std::vector<double> far_field_pass(const Plan& plan, const std::vector<double>& charges,
                                                   const std::vector<unsigned>& outputs, double charge_seconds) const;
  void apply_near_field(const double* forces, double* velocities, std::size_t nrhs) const;
  // Adds the near-field grand-mobility sums (times eta, self terms included) of the loads [F; T]
  // (6N) to u and w (3N each).
  void apply_grand_near_field(const Plan& plan, const double* loads, double* u, double* w) const;
  [[nodiscard]] std::span<const double> unit_radii() const;

  FmmRpyOptions options_;
  Plan plan_;
  std::vector<double> centered_;  // positions relative to the bounding-box centre (3N); scaled: see length_units.hpp
  // Clouds far outside the lengths 2^-150 ... 2^199 are evaluated in units of 2^e (length_units.hpp):
  // centered_ then holds 2^-e (x - shift), translated only where exact, and scaled_radii_ 2^-e a.
  int scale_exponent_ = 0;
  std::vector<double> scaled_radii_;
  mutable StageTimes timings_;
};

}  // namespace rpyfmm::rpy
