// rpyfmm — FmmRpy's grand mobility with rotation, [U; W] = M [F; T] (docs/theory/rpy.md, section 7).
//
// One Laplace FMM pass carries the translational densities and the three torque components:
// U = (far translational field) + curl Phi_T / (8 pi eta), W = curl Phi_F / (8 pi eta) +
// grad div Phi_T / (16 pi eta) over the far pairs, where the rotational blocks are exactly these
// harmonic fields (no a^2 corrections for any radii). Every near-field pair (the FMM's U list and
// the W/X pairs it hands back) is summed with the exact translational and rotational blocks in one
// fused pass (rotation_pair_sums.hpp), all overlap regimes included, in the colour schedule of
// the translational near field: each velocity receives its contributions in a fixed order, so
// results do not depend on the thread count.
//
// The products with torques run on the force-only plan (leaves and plane-wave table); the torque
// densities ask the FMM for curl Phi_T and grad div Phi_T only (fmm::curl_grad_div: six combined
// sums per target in L2P instead of three gradients and Hessians). Measured on 2026-12-06, Intel
// Xeon (AVX-512), 2 vCPUs shared with other work, 1 thread, random suspension N = 1e6 at 1e-6,
// process CPU time, medians of 6 alternating with d22dc43 (gradients and Hessians): torques /
// forces 1.88 with the AVX-512 kernels (19.1 s / 10.2 s; d22dc43 1.99) and 1.95 at the AVX2 level
// (23.8 s / 12.2 s; d22dc43 2.01). With the gradients and Hessians, plans of their own were slower
// at the AVX2 level: leaves of 120 points 2.05, the 9-digit table with leaves of 100 points 2.57;
// leaves of 60 points left U's error at 1.02e-6. Errors on the force-only plan: U 8.0e-7 (8.3e-7
// at the AVX2 level), W 1.2e-7 (1.6e-7).
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "fmm_far_field.hpp"
#include "fmm_near_field.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::rpy {
void FmmRpy::apply_grand_near_field(const Plan& plan, const double* loads, double* u, double* w) const {
  const std::span<const double> x = scale_exponent_ == 0 ? positions() : std::span<const double>(centered_);
  const detail::NearPoints points{
      plan.fmm->near_field(), *plan.near_schedule, x, unit_radii(), size(), equal_radii(), true};
  detail::add_grand_near_field(points, loads, u, w);
}

void FmmRpy::do_apply_rotation(const double* forces, const double* torques, double* velocities,
                               double* angular_velocities) const {
  StopWatch total;
  const std::size_t n = size();
  const bool equal = equal_radii();
  const std::size_t nd = detail::rotation_densities(equal);
  const auto a = unit_radii();
  // In the units 2^e of length_units.hpp the blocks carry 1/L (tt), 1/L^2 (ut, wf) and 1/L^3 (rr):
  // with torques 2^-e T every sum below is 2^e U (velocities) or 2^(2e) W (angular velocities).
  const int e = scale_exponent_;
  std::vector<double> loads(forces, forces + 3 * n);
  for (std::size_t j = 0; j < 3 * n; ++j) loads.push_back(std::ldexp(torques[j], -e));
  const double* scaled_torques = loads.data() + 3 * n;

  StopWatch watch;
  std::vector<double> charges(nd * n);
  std::vector<unsigned> outputs(nd);
  detail::rotation_far_field_charges(forces, scaled_torques, n, equal, centered_, a, charges, outputs);
  const std::vector<double> results = far_field_pass(plan_, charges, outputs, watch.seconds());

  watch.restart();
  detail::combine_far_field(results, n, 1, equal, centered_, a, viscosity(), velocities);
  std::vector<double> ut(3 * n), wf(3 * n), rr(3 * n);
  detail::combine_rotation_far_field(results, n, equal, ut.data(), wf.data(), rr.data());
  timings_["rpy_far"] = watch.seconds();

  watch.restart();
  // Near field into ut (U) and wf (W), on top of the far field's rotational sums.
  for (std::size_t j = 0; j < 3 * n; ++j) wf[j] += rr[j];
  apply_grand_near_field(plan_, loads.data(), ut.data(), wf.data());
  const double inv_eta = 1.0 / viscosity();
  for (std::size_t j = 0; j < 3 * n; ++j) {
    velocities[j] = std::ldexp(velocities[j] + inv_eta * ut[j], -e);
    angular_velocities[j] = std::ldexp(inv_eta * wf[j], -2 * e);
  }
  timings_["rpy_near"] = watch.seconds();
  timings_["rpy_total"] = total.seconds();
}

}  // namespace rpyfmm::rpy
