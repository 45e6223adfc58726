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
#include "near_schedule.hpp"
#include "near_sources.hpp"
#include "rotation_pair_sums.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::rpy {
namespace {

// What every near-field task reads and writes. Sources are gathered with the loads [F; T]
// (two right-hand sides of GatheredSources: forces, then torques); u and w (3n each, times eta)
// receive the near-field sums.
struct GrandNearContext {
  const fmm::NearField& near;
  std::span<const double> x, a;
  const double* loads;  // 6n: F then T
  double *u, *w;
  std::size_t n;
  bool equal;

  [[nodiscard]] detail::GrandTarget target(std::size_t i) const {
    const double* f = loads + 3 * i;
    const double* t = loads + 3 * n + 3 * i;
    return {x[3 * i], x[3 * i + 1], x[3 * i + 2], a[i], i, {f[0], f[1], f[2]}, {t[0], t[1], t[2]}};
  }
  void add(std::size_t i, const detail::GrandSums& s) const {
    for (int c = 0; c < 3; ++c) {
      u[3 * i + c] += s.u[c];
      w[3 * i + c] += s.w[c];
    }
  }
};

detail::GrandSources view(const detail::GatheredSources& src, bool equal) {
  return {src.size(),       src.x.data(),     src.y.data(),     src.z.data(),     equal ? nullptr : src.a.data(),
          src.id.data(),    src.forces(0, 0), src.forces(0, 1), src.forces(0, 2), src.forces(1, 0),
          src.forces(1, 1), src.forces(1, 2)};
}

// The leaf's targets against one-sided sources (the leaf itself among them), plus the self terms
// F_i / (6 pi eta a_i) and T_i / (8 pi eta a_i^3).
void one_sided_block(const GrandNearContext& ctx, std::uint32_t leaf, const detail::GatheredSources& src) {
  const detail::GrandSources s = view(src, ctx.equal);
  for (std::size_t i : ctx.near.targets(leaf)) {
    const detail::GrandTarget t = ctx.target(i);
    detail::GrandSums sums{};
    detail::grand_pair_sum(s, t, sums);
    const double self_t = rpy_self(t.a), self_r = rpy_rotation_self(t.a);
    for (int c = 0; c < 3; ++c) {
      sums.u[c] += self_t * t.f[c];
      sums.w[c] += self_r * t.t[c];
    }
    ctx.add(i, sums);
  }
}

// The leaf's targets against the sources of its symmetric partners, both directions at once;
// the partners' sums are accumulated in src.u and added once at the end.
void symmetric_block(const GrandNearContext& ctx, std::uint32_t leaf, detail::GatheredSources& src) {
  const std::size_t m = src.size();
  src.u.assign(6 * m, 0.0);
  const detail::GrandSources s = view(src, ctx.equal);
  const detail::GrandAccumulators acc{{src.velocities(0, 0), src.velocities(0, 1), src.velocities(0, 2)},
                                      {src.velocities(1, 0), src.velocities(1, 1), src.velocities(1, 2)}};
  for (std::size_t i : ctx.near.targets(leaf)) {
    detail::GrandSums sums{};
    detail::grand_pair_sum_symmetric(s, ctx.target(i), acc, sums);
    ctx.add(i, sums);
  }
  for (std::size_t q = 0; q < m; ++q) {
    const detail::GrandSums back{{acc.u[0][q], acc.u[1][q], acc.u[2][q]}, {acc.w[0][q], acc.w[1][q], acc.w[2][q]}};
    ctx.add(src.id[q], back);
  }
}

}  // namespace

void FmmRpy::apply_grand_near_field(const Plan& plan, const double* loads, double* u, double* w) const {
  const std::span<const double> x = scale_exponent_ == 0 ? positions() : std::span<const double>(centered_);
  const GrandNearContext ctx{plan.fmm->near_field(), x, unit_radii(), loads, u, w, size(), equal_radii()};
  detail::for_each_near_task<detail::GatheredSources>(
      *plan.near_schedule, [&](detail::GatheredSources& src, std::uint32_t leaf, std::span<const std::uint32_t> one,
                               std::span<const std::uint32_t> partners) {
        src.gather(ctx.near, one, ctx.x, ctx.a, loads, ctx.n, 2);
        one_sided_block(ctx, leaf, src);
        if (!partners.empty()) {
          src.gather(ctx.near, partners, ctx.x, ctx.a, loads, ctx.n, 2);
          symmetric_block(ctx, leaf, src);
        }
      });
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
