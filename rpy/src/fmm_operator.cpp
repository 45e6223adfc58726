// rpyfmm — FmmRpy: RPY mobility from Laplace FMM calls plus the exact near field (docs/theory/rpy.md;
// Guan, dissertation, §3.1 and Algorithm 2).
#include "rpyfmm/rpy/fmm_operator.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <span>
#include <string>

#include "fmm_far_field.hpp"
#include "fmm_near_kernels.hpp"
#include "length_units.hpp"
#include "near_schedule.hpp"
#include "near_sources.hpp"
#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"

namespace rpyfmm::rpy {
namespace {

// Leaf capacity when the user leaves it at 0 (bench/rpy/RESULTS.md at commit 010249d "Leaf capacity", 1 thread).
// Four densities per product make the far field dearer relative to the near field than in one
// Laplace evaluation, so from 6 digits on the best leaves are larger than the Laplace default
// wherever the P2P runs without AVX-512: 400 / 600 / 800 points at 6 / 9 / 12 digits on both
// machines measured. At 3 digits the near-field kernel's speed decides: 200 points with the AVX-512
// kernels (random suspension N = 3e3 ... 2e5, Intel machine), 150 with AVX2 (AMD Zen-1 machine:
// suspension N = 1e3 ... 1e5 within 1.26x of the best of 100/150/200/400, 2x faster than 200 at
// N = 1e5; 100 is best from 1e4 up but 1.7x slower at N = 1e3).
int default_leaf_capacity(double eps) {
  switch (fmm::fmm_table_digits_for(eps)) {
    case 3:
      return simd_level() == SimdLevel::avx512 ? 200 : 150;
    case 6:
      return 400;
    case 9:
      return 600;
    default:
      return 800;
  }
}

// Automatic leaves fitted to the cloud (bench/rpy/RESULTS.md at commit 010249d "Fitted leaf grid"; fmm::fit_leaf_grid
// enlarges the root so that leaves of a chosen occupancy span the cloud, instead of the octree's
// factor-8 steps: a uniform N = 1e5 cloud gets 24 or 195 points per leaf, ~60 is best at 6 digits).
// Measured without AVX-512, 1 thread: at 1e-6, N = 1e5, uniform suspension 1.30x faster (195 -> 58
// points per leaf), cylinder surface 1.13x, eight spheres 1.25x; at 1e-3, spherical BD cloud,
// 1.0-1.28x from N = 2e3 to 1e5 and 1.33x at 2e5.
//
// The rule, per plane-wave table: the target occupancy and the point counts measured to gain. The
// upper end at 6 digits is set by accuracy: smaller leaves move work into the far field, whose
// 6-digit plane-wave error then weighs more (uniform suspension at 1e-6: 5.9e-7 -> 6.8e-7 at
// N = 1e5, but 9.8e-7 at 5e5 and 1.03e-6 at 1e6, where the bounding-cube tree gives 9.05e-7). At 3
// digits the errors stay near 3e-4; 2e5 is the largest size measured. With the AVX-512 kernels
// (Intel machine) leaves of 20-60 points at 1e-3, 40-150 at 1e-6 and 100-250 at 1e-9 were no faster
// than the bounding-cube tree's 200 / 400 / 600-point capacities on suspensions and cylinders of
// 1e4 ... 2e5 points, mostly slower (cylinder 1e5 at 1e-6: 0.82x at 60 points per leaf): the near
// field is cheap enough there that large leaves pay. The exception is a partly split tree (leaves
// on two levels): suspension 2e5 at 1e-6, share 0.67, 1.32x (Intel), 1.17-1.22x (AMD Zen-4).
//
// Large volume-filling clouds at 6 digits, with either kernel set: a uniform cloud's bounding-cube
// tree jumps from ~120 points per leaf at 5e5 points to ~240 at 1e6 (4096 leaves), where the
// near field outweighs the far field. Fitted leaves move work into the far field and here lower
// the error as well. Measured with these leaves forced on commit 1cc8359, 2026-12-06, Intel Xeon
// (AVX-512), 2 vCPUs, 1 thread, random suspension N = 1e6 at 1e-6, process CPU time of one product
// (the machine was shared, so wall times were not comparable), medians of 3 per run:
//  - AVX-512 kernels: bounding-cube tree 12.4-14.7 s (4 runs), 120 points per leaf (8000 leaves)
//    11.0-11.1 s (3 runs), 100 points 13.0 s, 140 points 12.3 s, 80 points 12.3 s;
//  - AVX2 level: bounding-cube tree 16.5 s, 120 points 15.3 s, 80 points (12167 leaves) 13.4 s;
//  - U's error at 200 sampled rows: 9.05e-7 (bounding cube), 7.99e-7 (120), 8.30e-7 (80),
//    9.33e-7 (100). Leaves of ~57 points exceeded eps at this size (1.03e-6, noted above).
constexpr std::size_t kLargeCloud = 500000;
constexpr double kVolumeFillingCloud = 0.5;  // fit_leaf_grid's fill above which a cloud counts as volume-filling

fmm::FittedGridRule fitted_grid_rule(double eps, std::size_t n) {
  if (fmm::fmm_table_digits_for(eps) == 6 && n >= kLargeCloud) {
    const int occupancy = simd_level() == SimdLevel::avx512 ? 120 : 80;
    return {occupancy, kLargeCloud, std::numeric_limits<std::size_t>::max(), kVolumeFillingCloud};
  }
  if (simd_level() == SimdLevel::avx512) {
    // At 6 digits, partly split trees of volume-filling clouds only (AMD Zen-4 machine,
    // bench/rpy/RESULTS.md at commit 010249d "Partly split trees with the AVX-512 kernels"): uniform suspensions
    // 1.17-1.22x (shares 0.67-0.69); balls (fill 0.58, share 0.82-0.94 from their curved edge)
    // lost 0.74-0.99x, and at 3 digits every refit lost (0.78-0.88x).
    if (fmm::fmm_table_digits_for(eps) == 6) return {60, 10000, 200000, 0.8, false, 0.97};
    return {};
  }
  switch (fmm::fmm_table_digits_for(eps)) {
    // Volume-filling clouds only: on surfaces (cylinder, eight spheres) leaves of 20 points were
    // 0.75-0.95x, their leaves have fewer neighbours and the near field costs less.
    case 3:
      return {20, 2000, 200000, 0.25};
    case 6:
      return {60, 5000, 200000, 0.0};  // cylinder 2.0x, eight 1.45x, BD cloud 1.13x at 5e3
    default:
      return {};  // 1e-9: 195 and 100 points per leaf tie
  }
}

// Trees with fewer leaves evaluate each directed leaf pair on its own (one colour, parallel over
// target leaves): with few leaves per colour the symmetric schedule would leave threads idle.
// A property of the tree only, never of the thread count, so results stay thread-invariant.
constexpr std::size_t kSymmetricMinLeaves = 64;

}  // namespace

FmmRpy::FmmRpy(Geometry geometry, double viscosity, FmmRpyOptions options)
    : MobilityOperator(geometry, viscosity, "FmmRpy"), options_(options) {
  require(geometry.is_open(), ErrorCode::not_supported, "FmmRpy",
          "periodic geometry is not supported by the free-space FMM operator (use the PSE operator)");
  ranges::require_in(ranges::kMobilityTolerance, options_.tolerance, "FmmRpy", "tolerance");
  require(options_.leaf_capacity >= 0, ErrorCode::invalid_argument, "FmmRpy",
          "leaf_capacity must be >= 0 (0 = automatic), got " + std::to_string(options_.leaf_capacity));
}

FmmRpy::~FmmRpy() = default;

StageTimes FmmRpy::last_timings() const {
  return timings_;
}

void FmmRpy::on_positions_set() {
  const auto x = positions();
  // Centred coordinates, or at extreme length scales units of the suspension's size
  // (length_units.hpp, to_fmm_frame).
  const detail::BoundingBox box = detail::bounding_box(x);
  const detail::LengthUnits units = detail::choose_length_units(box, radii(), "FmmRpy::set_positions");
  scale_exponent_ = units.exponent;
  detail::to_fmm_frame(units, box, x, radii(), centered_, scaled_radii_);
  const double eps = options_.tolerance;
  plan_ = options_.leaf_capacity > 0 ? make_plan(options_.leaf_capacity, {})
                                     : make_plan(default_leaf_capacity(eps), fitted_grid_rule(eps, size()));
}

FmmRpy::Plan FmmRpy::make_plan(int leaf_capacity, const fmm::FittedGridRule& fitted_grid) const {
  const std::span<const double> a = unit_radii();
  // The Laplace FMM runs at the requested tolerance: the far field combines up to 7 outputs with
  // partial cancellation (x_m E_k(F^m) - E_k(x.F)), and its errors measured on the test
  // configurations stay below the FMM's own eps (tests/rpy/test_fmm_operator.cpp holds the
  // contract). The expansion order follows from the tolerance.
  fmm::FmmOptions fo;
  fo.tolerance = options_.tolerance;
  fo.leaf_capacity = leaf_capacity;
  // Automatic leaves: the bounding-cube tree's mean leaf occupancy (or with AVX-512 its leaf-level
  // share) decides whether the fitted grid pays, within the one set_points.
  fo.fitted_grid = fitted_grid;
  fo.near_field = false;
  fo.export_direct_far = true;  // W/X pairs summed directly: one RPY pair block beats 4-7 Laplace densities
  // Overlapping pairs (r <= a_i + a_j) are always U-list pairs.
  fo.min_leaf_side = 2.0 * *std::max_element(a.begin(), a.end());
  Plan plan;
  plan.fmm = std::make_unique<fmm::LaplaceFmm>(fo);
  plan.fmm->set_points(centered_);
  // Near-field schedule: each adjacent leaf pair once for both directions where the tree has
  // enough leaves to keep every colour busy (see kSymmetricMinLeaves).
  const fmm::NearField& near = plan.fmm->near_field();
  plan.near_schedule = std::make_unique<detail::NearSchedule>(
      detail::make_near_schedule(near.pairs, near.num_leaves(), near.num_leaves() >= kSymmetricMinLeaves));
  return plan;
}

std::span<const double> FmmRpy::unit_radii() const {
  return scale_exponent_ == 0 ? radii() : std::span<const double>(scaled_radii_);
}

std::vector<double> FmmRpy::far_field_pass(const Plan& plan, const std::vector<double>& charges,
                                           const std::vector<unsigned>& outputs, double charge_seconds) const {
  timings_.clear();
  timings_["rpy_charges"] = charge_seconds;
  std::vector<double> results(outputs.size() * size() * 10);
  plan.fmm->evaluate(charges, outputs.size(), outputs, results);
  for (const auto& [stage, seconds] : plan.fmm->last_timings()) timings_[stage] = seconds;
  return results;
}

void FmmRpy::do_apply(const double* forces, double* velocities, std::size_t nrhs) const {
  StopWatch total;
  const std::size_t n = size();
  const bool equal = equal_radii();
  const std::size_t nd = detail::translation_densities(equal) * nrhs;
  const auto a = unit_radii();

  StopWatch watch;
  std::vector<double> charges(nd * n);
  std::vector<unsigned> outputs(nd);
  detail::far_field_charges(forces, n, nrhs, equal, centered_, a, charges, outputs);
  const std::vector<double> results = far_field_pass(plan_, charges, outputs, watch.seconds());

  watch.restart();
  detail::combine_far_field(results, n, nrhs, equal, centered_, a, viscosity(), velocities);
  timings_["rpy_far"] = watch.seconds();

  watch.restart();
  apply_near_field(forces, velocities, nrhs);
  // Back from the units of length_units.hpp: M(x, a) = 2^-e M(2^-e x, 2^-e a).
  if (scale_exponent_ != 0)
    for (std::size_t j = 0; j < 3 * n * nrhs; ++j) velocities[j] = std::ldexp(velocities[j], -scale_exponent_);
  timings_["rpy_near"] = watch.seconds();
  timings_["rpy_total"] = total.seconds();
}

namespace {

// Stored pair scalars of one target against gathered sources (block products).
struct PairScalars {
  std::vector<double> buf;
  double *dx = nullptr, *dy = nullptr, *dz = nullptr, *fs = nullptr, *gr = nullptr;
  void resize(std::size_t m) {
    buf.resize(5 * m);
    dx = buf.data();
    dy = dx + m;
    dz = dy + m;
    fs = dz + m;
    gr = fs + m;
  }
};

// What every near-field task reads and writes.
struct NearContext {
  const fmm::NearField& near;
  std::span<const double> x, a;
  const double* forces;
  double* velocities;
  std::size_t n, nrhs;
  double inv_eta;
  bool equal;

  [[nodiscard]] const double* force(std::size_t k, std::size_t i) const { return forces + 3 * n * k + 3 * i; }
  void add_velocity(std::size_t k, std::size_t i, const double u[3]) const {
    double* ui = velocities + 3 * n * k + 3 * i;
    ui[0] += inv_eta * u[0];
    ui[1] += inv_eta * u[1];
    ui[2] += inv_eta * u[2];
  }
};

// The targets of `leaf` against gathered sources, for every right-hand side.
//  - kBothWays = false: one-sided sources (the leaf itself among them: the self pair is skipped
//    inside the kernels), plus the self term M_ii = I / (6 pi eta a_i).
//  - kBothWays = true: the sources of the leaf's symmetric partners (other leaves). Each pair
//    block is evaluated once for both directions (M_ji = M_ij); the partners' velocities are
//    accumulated in src.u and added once at the end. (FmmRpy evaluates at its own points, so a
//    leaf's sources are its targets and src.id indexes velocities too.)
// Block products (nrhs > 1) compute the pair scalars once per target and accumulate them per
// rhs: the geometry is most of the work.
template <bool kBothWays>
void leaf_block(const NearContext& ctx, std::uint32_t leaf, detail::GatheredSources& src, PairScalars& ps) {
  const std::size_t m = src.size();
  const double* sa = ctx.equal ? nullptr : src.a.data();
  const bool block = ctx.nrhs > 1;
  if constexpr (kBothWays) src.u.assign(3 * m * ctx.nrhs, 0.0);
  if (block) ps.resize(m);
  for (std::size_t i : ctx.near.targets(leaf)) {
    const double xi = ctx.x[3 * i], yi = ctx.x[3 * i + 1], zi = ctx.x[3 * i + 2], ai = ctx.a[i];
    if (block) {
      detail::near_pair_scalars(m, src.x.data(), src.y.data(), src.z.data(), sa, src.id.data(), xi, yi, zi, ai, i,
                                ps.dx, ps.dy, ps.dz, ps.fs, ps.gr);
    }
    for (std::size_t k = 0; k < ctx.nrhs; ++k) {
      const double *fx = src.forces(k, 0), *fy = src.forces(k, 1), *fz = src.forces(k, 2);
      const double* fi = ctx.force(k, i);
      double u[3];
      if constexpr (kBothWays) {
        double *ux = src.velocities(k, 0), *uy = src.velocities(k, 1), *uz = src.velocities(k, 2);
        if (block) {
          detail::near_accumulate_symmetric(m, ps.dx, ps.dy, ps.dz, ps.fs, ps.gr, fx, fy, fz, fi, ux, uy, uz, u);
        } else {
          detail::near_pair_sum_symmetric(m, src.x.data(), src.y.data(), src.z.data(), sa, fx, fy, fz, xi, yi, zi, ai,
                                          fi, ux, uy, uz, u);
        }
      } else {
        if (block) {
          detail::near_accumulate(m, ps.dx, ps.dy, ps.dz, ps.fs, ps.gr, fx, fy, fz, u);
        } else {
          detail::near_pair_sum(m, src.x.data(), src.y.data(), src.z.data(), sa, src.id.data(), fx, fy, fz, xi, yi, zi,
                                ai, i, u);
        }
        const double self = rpy_self(ai);
        for (int c = 0; c < 3; ++c) u[c] += self * fi[c];
      }
      ctx.add_velocity(k, i, u);
    }
  }
  if constexpr (kBothWays) {
    for (std::size_t k = 0; k < ctx.nrhs; ++k) {
      const double *ux = src.velocities(k, 0), *uy = src.velocities(k, 1), *uz = src.velocities(k, 2);
      for (std::size_t q = 0; q < m; ++q) {
        const double u[3] = {ux[q], uy[q], uz[q]};
        ctx.add_velocity(k, src.id[q], u);
      }
    }
  }
}

}  // namespace

void FmmRpy::apply_near_field(const double* forces, double* velocities, std::size_t nrhs) const {
  // Unscaled, the exact input positions (the centred ones may be rounded); scaled, the exactly
  // translated and scaled ones of length_units.hpp.
  const std::span<const double> x = scale_exponent_ == 0 ? positions() : std::span<const double>(centered_);
  const NearContext ctx{
      plan_.fmm->near_field(), x, unit_radii(), forces, velocities, size(), nrhs, 1.0 / viscosity(), equal_radii()};
  struct ThreadState {
    detail::GatheredSources src;
    PairScalars ps;
  };
  detail::for_each_near_task<ThreadState>(
      *plan_.near_schedule, [&](ThreadState& state, std::uint32_t leaf, std::span<const std::uint32_t> one,
                                std::span<const std::uint32_t> partners) {
        state.src.gather(ctx.near, one, ctx.x, ctx.a, forces, ctx.n, nrhs);
        leaf_block<false>(ctx, leaf, state.src, state.ps);
        // All symmetric partners at once: one long pair loop per target.
        if (!partners.empty()) {
          state.src.gather(ctx.near, partners, ctx.x, ctx.a, forces, ctx.n, nrhs);
          leaf_block<true>(ctx, leaf, state.src, state.ps);
        }
      });
}

}  // namespace rpyfmm::rpy
