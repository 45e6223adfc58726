// The adaptive plane-wave Laplace FMM: the plan (tree, order, tables) and the evaluate driver over
// the stages of fmm_stages.hpp (docs/theory/fmm.md; Guan, dissertation, Algorithm 1; Cheng,
// Greengard & Rokhlin, J. Comput. Phys. 155 (1999) §4).
#include "rpyfmm/fmm/laplace_fmm.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "fmm_stages.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/leaf_grid.hpp"

namespace rpyfmm::fmm {

namespace {

// Within a factor 10 above a table's step (1e-3 <= eps < 1e-2, 1e-6 <= eps < 1e-5, ...) the
// Hessian's error against its absolute field (the contract, docs/theory/fmm.md, Sec. 7) is set by
// the table's own error and, where the far field of a small cluster of targets runs through
// M2P/P2L (the W/X lists), by the order: with the tables' 12 / 20 / 29 / 37 nodes and the capped
// order the worst of 50 random layouts (3000 uniform sources in the unit cube, 1200 targets in the
// corner [0.95, 0.99]^3, 10 in [-20, 20]^3, two densities in [-1, 1], numpy's default_rng(10) to
// (59); 100 / 100 / 200 / 300-point
// leaves, AVX2 level) reached 1.23 / 4.5 / 1.62 / 3.2 eps at 1e-3 / 1e-6 / 1e-9 / 1e-12, and no
// order fixes it with 20 nodes at 1e-6 (4.4-4.5 eps at orders 18, 20, 22). These tables and orders bring
// it to 0.48 / 0.47 / 0.26 / 0.64 eps (potential and gradient: at most 0.03 eps); 10x above the
// steps the tables' own parameters reach 0.19 / 0.45 / 0.16 / 0.32 eps. The node counts are
// FmmRpy's (rpy/src/fmm_laplace_accuracy.cpp). Cost at N = 1e5 (uniform cube, one thread, commit 7a95a86,
// 2026-12-08, Intel Xeon with AVX-512, 2 cores shared with other jobs, load 2-3): 1.10-1.19x at
// 1e-3, 1.28-1.42x at 1e-6, 1.02-1.09x at 1e-9, 1.14-1.16x at 1e-12 (AVX-512 and AVX2 levels,
// potential + gradient and with the Hessian). The order is fixed when the plan is built, before
// the outputs are known, so these hold for every output.
struct NearStep {
  int nodes, order;
};

NearStep near_step_parameters(int digits) {
  switch (digits) {
    case 3:
      return {14, 10};
    case 6:
      return {23, 22};
    case 9:
      return {32, 32};
    default:
      return {39, 46};
  }
}

// True where eps lies within a factor 10 above the step of its table.
bool near_step(double eps) {
  const double slack = 1.0 - 1e-9;
  return eps < std::pow(10.0, 1 - fmm_table_digits_for(eps)) * slack;
}

}  // namespace

int fmm_order_for(double eps) {
  const int digits = fmm_table_digits_for(eps);
  if (near_step(eps)) return near_step_parameters(digits).order;
  // Truncation bound of the multipole expansion (Guan, Theorem 2.2.2; docs/theory/fmm.md, error
  // control; FMM3D's l3dterms): sources within sqrt(3)/2, nearest target at 1.5 (box units). Beyond
  // some order the error saturates at the plane-wave table's own error, so the bound is capped per
  // table. The caps 18 / 32 / 42 for the 6 / 9 / 12-digit tables are the smallest orders that keep
  // the potential's worst case within eps/2 (one source box with charges at its corners, every V-list
  // offset: FmmBlocks.PlaneWaveM2LAllOffsetsAllTables) and pass 200 coincident charges at 1e-9
  // (FmmFeatures.DuplicatedPoints); random distributions saturate earlier (p = 8/16/26/36). The
  // 3-digit cap is 9, one above the potential's 8, for the Hessian: at order 8 its relative error
  // reached 1.58e-3 at 1e-3 (701 sources, 350 targets on one side of them, AVX2 level; the targets
  // of tests/mpi/cli_across_ranks.cmake), 3.9e-4 at order 9; order 9 costs 4-12 % more than 8 at
  // 1e5 points. Near the steps the orders of near_step_parameters apply instead.
  int p = 80;
  for (int q = 2; q < 80; ++q)
    if (std::pow(std::sqrt(3.0) / 2.0, q) / std::pow(1.5, q + 1) < eps) {
      p = q;
      break;
    }
  const int cap = digits <= 3 ? 9 : digits <= 6 ? 18 : digits <= 9 ? 32 : 42;
  return std::min(p, cap);
}

int fmm_table_digits_for(double eps) {
  // Intermediate tolerances use the next tighter table.
  const double slack = 1.0 - 1e-9;
  if (eps >= 1e-3 * slack) return 3;
  if (eps >= 1e-6 * slack) return 6;
  if (eps >= 1e-9 * slack) return 9;
  return 12;
}

int fmm_planewave_nodes_for(double eps) {
  const int digits = fmm_table_digits_for(eps);
  if (near_step(eps)) return near_step_parameters(digits).nodes;
  switch (digits) {
    case 3:
      return 12;
    case 6:
      return 20;
    case 9:
      return 29;
    default:
      return 37;
  }
}

int fmm_default_leaf_capacity(double eps) {
  // Measured (bench/fmm/RESULTS.md at commit 010249d "Leaf capacity", pot+grad+Hessian, one thread). The best leaf
  // balances P2P against M2L, so it follows the P2P kernel's speed: with the AVX-512 kernels
  // (1/r by rsqrt14 + Newton, ~3x the pairs per second) larger leaves than FMM3D's
  // 100/200/400/600 pay off from 1e-6 on (uniform cube, N = 1e5, Intel machine); with sqrt and
  // division (AVX2 or baseline) the fastest capacities are 100/100/200 at 3/6/9 digits (cube and
  // sphere surface, N = 1e5 and 2e5, AMD Zen-1 machine), where 400/600 cost up to 2.1x more; 100 at
  // 6 digits with the half-node M2L (1.15x over 150 on the sphere, cube trees equal).
  const int digits = fmm_table_digits_for(eps);
  if (simd_level() == SimdLevel::avx512) return digits <= 3 ? 100 : digits <= 6 ? 400 : digits <= 9 ? 600 : 800;
  return digits <= 3 ? 100 : digits <= 6 ? 100 : digits <= 9 ? 200 : 300;
}

namespace {
// Automatic leaves fitted to the cloud (fit_leaf_grid; bench/fmm/RESULTS.md at commit 010249d "Fitted leaf grid"):
// where the bounding-cube tree's leaves hold well above the best occupancy (a uniform cube of 2e5
// points at 1e-6 and capacity 400: a partly split tree of 124 points per leaf, against a best of
// ~50), the root is enlarged so that leaves of the target occupancy span the cloud. Measured with
// the AVX-512 kernels (Intel machine, pot + grad + Hessian, 1 thread, cube and sphere surface,
// 1e4 ... 2e5 points, side by side): 1e-6 1.07-2.29x (2e5 cube), 1e-9 1.37-1.45x where it
// applies, 1e-12 0.97-1.20x, 1e-3 0.99-1.09x, and 1.7x for a cube of 1e6 points at 1e-6.
// With the AVX2 / baseline kernels (AMD Zen-1 machine) the default capacities are already small
// and the best occupancies are ~16 / 25-49 / 50-110 / 60-110 points; there the grid is also
// fitted where a near-uniform cloud's bounding-cube tree is partly split (leaves on two levels: a
// uniform cube of 1e5 points at 1e-9 and capacity 200, 195 points per box at level 3, splits about
// half of them, and the W/X direct sums between the two levels cost 1.2 s of 4.5).

// fit_leaf_grid's fill (occupied fraction of ~8-point cells) above which a cloud counts as near-uniform.
constexpr double kUniformFill = 0.5;
// Leaf-level shares below which a near-uniform cloud's tree counts as partly split: measured with
// the AVX2 / baseline kernels at shares of ~0.5; with the AVX-512 kernels (AMD Zen-4 machine)
// refitting gained 1.39-1.56x at shares 0.83-0.89, 1.15-1.28x at 0.93-0.96, 1.03x at 0.99, and
// lost up to 14% at 1 (one level).
constexpr double kPartialShare = 0.8;
constexpr double kPartialShareAvx512 = 0.97;

FittedGridRule automatic_fitted_grid_rule(double eps) {
  if (simd_level() == SimdLevel::avx512) {
    // Best occupancies of the sweep (bench/fmm/leaf_grid_sweep.py at commit 010249d): ~24 / 50-70 / 70-150 / 150-300
    // points at 3 / 6 / 9 / 12 digits. The upper size is the largest measured (1e6: errors 4.5e-8,
    // 7.8e-8, 1.3e-8 at 1e-6 and 2.5e-11, 5.5e-11, 1.0e-11 at 1e-9, potential/gradient/Hessian).
    // Partly split trees are refitted too (AMD Zen-4 machine: 1.16-1.85x, see above).
    switch (fmm_table_digits_for(eps)) {
      case 3:
        return {24, 20000, 1000000, 0.0, true, kPartialShareAvx512, kUniformFill};
      case 6:
        return {60, 10000, 1000000, 0.0, true, kPartialShareAvx512, kUniformFill};
      case 9:
        return {120, 10000, 1000000, 0.0, true, kPartialShareAvx512, kUniformFill};
      default:
        return {200, 10000, 1000000, 0.0, true, kPartialShareAvx512, kUniformFill};
    }
  }
  // Side by side (bench/fmm/fitted_grid.py at commit 010249d): at 9 and 12 digits surfaces gained nothing (0.92-1.02x)
  // and 1e4 points at 12 digits neither (0.92x sphere, 0.99x cube): near-uniform clouds only there.
  switch (fmm_table_digits_for(eps)) {
    case 3:
      return {16, 10000, 1000000, 0.0, true, kPartialShare, kUniformFill};
    case 6:
      return {36, 10000, 1000000, 0.0, true, kPartialShare, kUniformFill};
    case 9:
      return {50, 10000, 1000000, kUniformFill, true, kPartialShare, kUniformFill};
    default:
      return {70, 20000, 1000000, kUniformFill, true, kPartialShare, kUniformFill};
  }
}

// TreeStats::leaf_level_share of a tree.
double leaf_level_share(const detail::Octree& tree) {
  std::vector<std::size_t> per_level(std::size_t(tree.nlevels()) + 1, 0);
  std::size_t total = 0;
  for (const int b : tree.leaves()) {
    const auto& box = tree.boxes()[std::size_t(b)];
    const std::size_t k = box.nsrc() + (tree.targets_are_sources() ? 0 : box.ntgt());
    per_level[std::size_t(box.level)] += k;
    total += k;
  }
  return total > 0 ? double(*std::max_element(per_level.begin(), per_level.end())) / double(total) : 1.0;
}

// The M2M / L2L tables of order p, built once per process.
const detail::ChildTranslations& child_translations(int p) {
  static std::mutex mutex;
  static std::map<int, std::unique_ptr<detail::ChildTranslations>> cache;
  std::lock_guard lock(mutex);
  auto& slot = cache[p];
  if (!slot) slot = std::make_unique<detail::ChildTranslations>(p);
  return *slot;
}
}  // namespace

LaplaceFmm::LaplaceFmm(const FmmOptions& options) : options_(options) {
  constexpr const char* where = "LaplaceFmm";
  require_in_range(options.tolerance, 1e-15, 1e-1, where, "tolerance");
  require(options.leaf_capacity >= 0, ErrorCode::invalid_argument, where,
          "leaf_capacity must be >= 0 (0 = automatic), got " + std::to_string(options.leaf_capacity));
  require(std::isfinite(options.min_leaf_side) && options.min_leaf_side >= 0.0, ErrorCode::invalid_argument, where,
          "min_leaf_side must be finite and >= 0, got " + format_number(options.min_leaf_side));
  require(options.root_scale >= 1.0 && options.root_scale <= 8.0, ErrorCode::invalid_argument, where,
          "root_scale must be in [1, 8], got " + format_number(options.root_scale));
  require(options.order == 0 || (options.order >= 2 && options.order <= 70), ErrorCode::invalid_argument, where,
          "order must be 0 (automatic) or in [2, 70], got " + std::to_string(options.order));
  require(options.planewave_nodes == 0 ||
              (options.planewave_nodes >= kMinPlaneWaveNodes && options.planewave_nodes <= kMaxPlaneWaveNodes),
          ErrorCode::invalid_argument, where,
          "planewave_nodes must be 0 (automatic) or in [" + std::to_string(kMinPlaneWaveNodes) + ", " +
              std::to_string(kMaxPlaneWaveNodes) + "], got " + std::to_string(options.planewave_nodes));
  require(
      options.fitted_grid.occupancy >= 0, ErrorCode::invalid_argument, where,
      "fitted_grid.occupancy must be >= 0 (0 = no fitted grid), got " + std::to_string(options.fitted_grid.occupancy));
}

LaplaceFmm::~LaplaceFmm() = default;
LaplaceFmm::LaplaceFmm(LaplaceFmm&& o) noexcept
    : options_(o.options_),
      plan_(std::move(o.plan_)),
      timings_(std::move(o.timings_)),
      target_costs_(std::move(o.target_costs_)),
      near_(std::move(o.near_)) {}
LaplaceFmm& LaplaceFmm::operator=(LaplaceFmm&& o) noexcept {
  options_ = o.options_;
  plan_ = std::move(o.plan_);
  timings_ = std::move(o.timings_);
  target_costs_ = std::move(o.target_costs_);
  near_ = std::move(o.near_);
  return *this;
}

std::size_t LaplaceFmm::num_sources() const noexcept {
  return plan_ ? plan_->n : 0;
}
std::size_t LaplaceFmm::num_targets() const noexcept {
  return plan_ ? plan_->m : 0;
}

namespace {

// Clouds whose extent lies outside [kMinExtent, kMaxExtent] are refused. The expansions and the
// plane-wave translations take powers of the box sides up to the order (~20) and the outputs go
// as 1/r, 1/r^2, 1/r^3: a dyadic cloud of extent 2^406 lost its gradients to underflow (relative
// error 1), one of 2^606 its potentials, one of 2^-394 gave NaN gradients. What fails at the small
// end is the Hessian, once leaves are smaller than ~2^-200 (NaN for a 3-level tree of extent
// 2^-199 and for trees of 14 ... 31 levels at 2^-188); trees of 31 levels at 2^-149 and at 2^199
// matched the direct sums (tests/fmm/test_fmm_far_coordinates.cpp checks both ends, shallow and
// deep trees, 6 and 12 digits). The octree has at most 30 levels, so with extents >= 2^-150 every
// leaf is >= 2^-180. Translations do not matter (exact_shifts). Callers with other length scales
// scale by a power of two first (exact; FmmRpy does so).
constexpr double kMinExtent = 0x1p-150, kMaxExtent = 0x1p200;

std::string format_number(double v, int digits = 6) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

// Throws where the largest extent of sources and targets (over the axes) is outside the range above
// (all points coinciding is fine, and so is a cloud smaller than min_leaf_side: its root box is
// never split and every pair is summed directly), naming the two particles that span it.
// Returns the bounding box {lo, hi}.
std::array<std::array<double, 3>, 2> require_plain_extent(std::span<const double> sources,
                                                          std::span<const double> targets, double min_leaf_side,
                                                          const char* where) {
  std::array<std::array<double, 3>, 2> box{};
  struct End {
    double v;
    bool target;
    std::size_t i;
  };
  // The octree's root is a cube of the largest side: that side decides.
  std::array<End, 3> los{}, his{};
  int widest = 0;
  double half = 0.0;  // half the largest extent, without overflow
  for (int c = 0; c < 3; ++c) {
    End lo{sources[c], false, 0}, hi = lo;
    auto scan = [&](std::span<const double> pts, bool target) {
      for (std::size_t j = 0; j < pts.size() / 3; ++j) {
        const double v = pts[3 * j + c];
        if (v < lo.v) lo = {v, target, j};
        if (v > hi.v) hi = {v, target, j};
      }
    };
    scan(sources, false);
    scan(targets, true);
    box[0][c] = lo.v;
    box[1][c] = hi.v;
    los[c] = lo;
    his[c] = hi;
    if (0.5 * hi.v - 0.5 * lo.v > half) {
      half = 0.5 * hi.v - 0.5 * lo.v;
      widest = c;
    }
  }
  if (half == 0.0 || (half <= 0.5 * kMaxExtent && (half >= 0.5 * kMinExtent || 2.0 * half < min_leaf_side))) return box;
  const char axis = char('x' + widest);
  auto name = [&](const End& e) {
    return std::string(e.target ? "target " : "source ") + std::to_string(e.i) + " (" + axis + " = " +
           format_number(e.v, 17) + ")";
  };
  fail(ErrorCode::invalid_input, where,
       name(los[widest]) + " and " + name(his[widest]) + " span " + format_number(2.0 * half) + " along " + axis +
           ", outside the extents 2^-150 ... 2^200 (" + format_number(kMinExtent) + " ... " +
           format_number(kMaxExtent) + ") the FMM evaluates without underflow or overflow; scale the " +
           "coordinates by a power of two");
  return box;
}

// Shifts that bring a cloud far from the origin (its centre at least 4 extents out along an axis)
// next to it: the octree's box centres and the offsets x - c of the expansions are otherwise
// rounded to the ulp of the coordinates, not of the cloud (a dyadic grid of extent 64 at 2^46:
// errors 7e-5 at eps = 1e-6). There every x has x / mid in [7/8, 9/8] and x - mid is exact
// (Sterbenz), so the FMM sees the same pair differences; clouds nearer the origin are not moved,
// and their results stay those of the untranslated points bit for bit.
std::array<double, 3> exact_shifts(const std::array<std::array<double, 3>, 2>& box) {
  double extent = 0.0;
  for (int c = 0; c < 3; ++c) extent = std::max(extent, 0.5 * box[1][c] - 0.5 * box[0][c]);
  extent *= 2.0;  // finite: require_plain_extent bounds it
  std::array<double, 3> shift{};
  for (int c = 0; c < 3; ++c) {
    const double mid = 0.5 * box[0][c] + 0.5 * box[1][c];
    if (std::abs(mid) >= 4.0 * extent) shift[c] = mid;
  }
  return shift;
}

std::vector<double> shifted(std::span<const double> pts, const std::array<double, 3>& shift) {
  std::vector<double> out(pts.begin(), pts.end());
  for (std::size_t j = 0; j < out.size(); ++j) out[j] -= shift[j % 3];
  return out;
}

// Throws unless sources and targets are 3N (N >= 1) and 3M finite coordinates.
void require_points(std::span<const double> sources, std::span<const double> targets, const char* where) {
  require(sources.size() % 3 == 0, ErrorCode::invalid_input, where,
          "sources has " + std::to_string(sources.size()) + " entries, not a multiple of 3");
  require(!sources.empty(), ErrorCode::invalid_input, where, "no sources (N = 0)");
  require(targets.size() % 3 == 0, ErrorCode::invalid_input, where,
          "targets has " + std::to_string(targets.size()) + " entries, not a multiple of 3");
  require_finite(sources, where, "sources", 3);
  require_finite(targets, where, "targets", 3);
}

// The fitted-grid rule of these options: the automatic one for automatic leaves, the caller's
// (FmmOptions::fitted_grid) over a given capacity, none for a given root scale.
FittedGridRule fitted_grid_rule(const FmmOptions& options) {
  if (options.root_scale != 1.0) return {};
  return options.leaf_capacity == 0 ? automatic_fitted_grid_rule(options.tolerance) : options.fitted_grid;
}

// The plan's tree: the bounding-cube tree's boxes decide whether a fitted grid pays
// (choose_leaf_grid); where it does, the boxes are rebuilt on it. The lists are built once.
void build_plan_tree(LaplaceFmm::Plan& plan, const FmmOptions& options, std::span<const double> sources,
                     std::span<const double> targets) {
  detail::OctreeParams tp;
  tp.leaf_capacity = std::size_t(plan.leaf_capacity);
  tp.min_leaf_side = options.min_leaf_side;
  tp.root_scale = options.root_scale;
  plan.tree.build_boxes(sources, targets, tp);
  const FittedGridRule rule = fitted_grid_rule(options);
  if (rule.occupancy > 0) {
    const LeafGrid grid =
        choose_leaf_grid(rule, sources, targets, plan.tree.leaves().size(), leaf_level_share(plan.tree));
    if (grid.fitted()) {
      plan.leaf_capacity = grid.leaf_capacity;
      tp.leaf_capacity = std::size_t(grid.leaf_capacity);
      tp.root_scale = grid.root_scale;
      plan.tree.build_boxes(sources, targets, tp);
    }
  }
  plan.tree.finish_build(sources, targets);
  plan.root_scale = tp.root_scale;
}

// W/X boxes with at most this many points are summed directly. Direct sums beat M2P/P2L below
// ~p^2/2 points by operation counts (Cheng, Greengard & Rokhlin 1999 §4; Guan, Algorithm 1 step 3
// uses p^2), with pairs as dear as expansion terms. The AVX-512 P2P kernels make pairs ~3x
// cheaper, and there the limit is 2 p^2 (measured on an AMD Zen-4 machine, bench/fmm/RESULTS.md at commit 010249d
// "W/X direct limit": surfaces 1.1-1.5x faster, one-level trees unchanged). A caller that takes
// them over (export_direct_far) has a kernel cheaper than nd Laplace densities, and direct sums of
// whole leaves then win even more (measured: FmmRpy, bench/rpy/RESULTS.md at commit 010249d).
std::size_t direct_limit(const LaplaceFmm::Plan& plan) {
  const std::size_t p2 = std::size_t(plan.p) * std::size_t(plan.p);
  if (plan.export_direct) return std::max(p2 / 2, std::size_t(plan.leaf_capacity));
  return plan.simd_level == SimdLevel::avx512 ? 2 * p2 : p2 / 2;
}

// Interleaved xyz into structure-of-arrays x, y, z.
void split_coordinates(const std::vector<double>& xyz, std::vector<double>& x, std::vector<double>& y,
                       std::vector<double>& z) {
  const std::size_t k = xyz.size() / 3;
  x.resize(k);
  y.resize(k);
  z.resize(k);
  for (std::size_t j = 0; j < k; ++j) {
    x[j] = xyz[3 * j];
    y[j] = xyz[3 * j + 1];
    z[j] = xyz[3 * j + 2];
  }
}

}  // namespace

void LaplaceFmm::set_points(std::span<const double> sources, std::span<const double> targets) {
  constexpr const char* where = "LaplaceFmm::set_points";
  require_points(sources, targets, where);
  const auto shift = exact_shifts(require_plain_extent(sources, targets, options_.min_leaf_side, where));
  std::vector<double> shifted_sources, shifted_targets;
  if (shift != std::array<double, 3>{}) {
    shifted_sources = shifted(sources, shift);
    shifted_targets = shifted(targets, shift);
    sources = shifted_sources;
    targets = shifted_targets;
  }

  StopWatch sw;
  auto plan = std::make_unique<Plan>();
  plan->p = options_.order > 0 ? options_.order : fmm_order_for(options_.tolerance);
  plan->planewave_nodes =
      options_.planewave_nodes > 0 ? options_.planewave_nodes : fmm_planewave_nodes_for(options_.tolerance);
  plan->leaf_capacity =
      options_.leaf_capacity > 0 ? options_.leaf_capacity : fmm_default_leaf_capacity(options_.tolerance);
  build_plan_tree(*plan, options_, sources, targets);
  plan->export_direct = options_.export_direct_far && !options_.near_field;
  plan->simd_level = simd_level();
  plan->direct_limit = direct_limit(*plan);
  const double t_tree = sw.seconds();
  sw.restart();
  plan->H = &detail::Harmonics::cached(plan->p + 2);
  plan->ct = &child_translations(plan->p);
  plan->pw = &detail::PlaneWave::cached(plan->p, plan->planewave_nodes);
  plan->n = sources.size() / 3;
  plan->m = targets.empty() ? plan->n : targets.size() / 3;
  split_coordinates(plan->tree.sorted_sources(), plan->sx, plan->sy, plan->sz);
  split_coordinates(plan->tree.sorted_targets(), plan->tx, plan->ty, plan->tz);
  const double t_tables = sw.seconds();
  std::lock_guard lock(mutex_);
  plan_ = std::move(plan);
  near_.reset();
  timings_.clear();
  target_costs_.clear();
  timings_["tree"] = t_tree;
  timings_["tables"] = t_tables;
}

std::vector<double> LaplaceFmm::last_target_costs() const {
  std::lock_guard lock(mutex_);
  return target_costs_;
}

StageTimes LaplaceFmm::last_timings() const {
  std::lock_guard lock(mutex_);
  return timings_;
}

TreeStats LaplaceFmm::stats() const {
  TreeStats s;
  if (!plan_) return s;
  const auto& t = plan_->tree;
  s.levels = t.nlevels();
  s.boxes = t.boxes().size();
  s.leaves = t.leaves().size();
  s.order = plan_->p;
  s.nlams = plan_->pw->nlams();
  s.leaf_capacity = plan_->leaf_capacity;
  s.root_scale = plan_->root_scale;
  s.u_pairs = t.ulist().items.size();
  s.w_pairs = t.wlist().items.size();
  s.x_pairs = t.xlist().items.size();
  s.leaf_level_share = leaf_level_share(t);
  s.simd_level = plan_->simd_level;
  s.direct_limit = plan_->direct_limit;
  s.memory_bytes = t.memory_bytes() + (plan_->sx.size() + plan_->tx.size()) * 3 * sizeof(double);
  return s;
}

namespace {

// The leaves' sources and targets in the caller's numbering, and the U-list leaf pairs.
std::unique_ptr<NearField> near_field_of(const detail::Octree& t, const std::vector<int>& leaf_id) {
  auto nf = std::make_unique<NearField>();
  const auto& leaves = t.leaves();
  nf->source_begin.push_back(0);
  nf->target_begin.push_back(0);
  for (int b : leaves) {
    const auto& bx = t.boxes()[b];
    for (std::size_t j = bx.src_begin; j < bx.src_end; ++j) nf->source_index.push_back(t.source_order()[j]);
    for (std::size_t j = bx.tgt_begin; j < bx.tgt_end; ++j) nf->target_index.push_back(t.target_order()[j]);
    nf->source_begin.push_back(nf->source_index.size());
    nf->target_begin.push_back(nf->target_index.size());
  }
  for (std::size_t i = 0; i < leaves.size(); ++i)
    for (int u : t.ulist().of(leaves[i])) nf->pairs.emplace_back(std::uint32_t(i), std::uint32_t(leaf_id[u]));
  return nf;
}

// The W/X sums evaluate() leaves to the caller (export_direct_far), as leaf pairs: for every target
// leaf, every leaf (with sources) under such a W-list box or X-list box of the leaf and its ancestors.
void add_exported_far_pairs(NearField& nf, const detail::Octree& t, const std::vector<int>& leaf_id,
                            std::size_t limit) {
  const auto& boxes = t.boxes();
  const auto& leaves = t.leaves();
  std::vector<int> stack;
  auto add_leaves_under = [&](std::uint32_t target_leaf, int box) {
    stack.assign(1, box);
    while (!stack.empty()) {
      const int c = stack.back();
      stack.pop_back();
      if (boxes[c].nsrc() == 0) continue;
      if (boxes[c].leaf) {
        nf.pairs.emplace_back(target_leaf, std::uint32_t(leaf_id[c]));
      } else {
        for (int k : boxes[c].child)
          if (k >= 0) stack.push_back(k);
      }
    }
  };
  for (std::size_t i = 0; i < leaves.size(); ++i) {
    const int b = leaves[i];
    if (boxes[b].ntgt() == 0) continue;
    for (int w : t.wlist().of(b))
      if (boxes[w].nsrc() > 0 && boxes[w].nsrc() <= limit) add_leaves_under(std::uint32_t(i), w);
    for (int a = b; a >= 0; a = boxes[a].parent) {
      if (boxes[a].ntgt() > limit) continue;
      for (int x : t.xlist().of(a)) add_leaves_under(std::uint32_t(i), x);
    }
  }
}

}  // namespace

const NearField& LaplaceFmm::near_field() const {
  require(plan_ != nullptr, ErrorCode::invalid_input, "LaplaceFmm::near_field", "set_points has not been called");
  std::lock_guard lock(mutex_);
  if (near_) return *near_;
  const auto& t = plan_->tree;
  std::vector<int> leaf_id(t.boxes().size(), -1);
  for (std::size_t i = 0; i < t.leaves().size(); ++i) leaf_id[t.leaves()[i]] = int(i);
  auto nf = near_field_of(t, leaf_id);
  if (plan_->export_direct) add_exported_far_pairs(*nf, t, leaf_id, plan_->direct_limit);
  near_ = std::move(nf);
  return *near_;
}

void LaplaceFmm::evaluate(std::span<const double> charges, std::size_t nd, unsigned outputs,
                          std::span<double> results) const {
  std::vector<unsigned> flags(nd, outputs);
  evaluate(charges, nd, flags, results);
}

namespace {

static_assert(curl_grad_div == detail::kCurlGradDiv && (curl_grad_div & all_outputs) == 0);
static_assert(grad_div == detail::kGradDiv && (grad_div & (all_outputs | curl_grad_div)) == 0);

// A grad_div density's flags: grad_div with any of potential | gradient (laplace_fmm.hpp).
bool is_grad_div(unsigned flags) noexcept {
  return (flags & grad_div) && (flags & ~(grad_div | potential | gradient)) == 0;
}

void require_evaluation_arguments(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                                  std::span<double> results, std::size_t N, std::size_t M) {
  constexpr const char* where = "LaplaceFmm::evaluate";
  require(nd >= 1, ErrorCode::invalid_argument, where, "nd must be >= 1");
  require_size(charges, nd * N, where, "charges (nd x N)");
  require_finite(charges, where, "charges", N);
  require(outputs.size() == nd, ErrorCode::invalid_input, where,
          "outputs has " + std::to_string(outputs.size()) + " entries, expected nd = " + std::to_string(nd));
  require_valid_outputs(outputs, where);
  require_size(results, nd * M * result_width, where, "results (nd x M x 10)");
}

// Runs stage() and adds its time to times[name].
template <class Stage>
void timed(StageTimes& times, const char* name, Stage&& stage) {
  const StopWatch sw;
  stage();
  times[name] += sw.seconds();
}

}  // namespace

void require_valid_outputs(std::span<const unsigned> outputs, const char* where) {
  const std::size_t nd = outputs.size();
  for (std::size_t d = 0; d < nd; ++d) {
    if (outputs[d] == curl_grad_div) {  // a group of three (laplace_fmm.hpp)
      require(d + 2 < nd && outputs[d + 1] == curl_grad_div && outputs[d + 2] == curl_grad_div,
              ErrorCode::invalid_argument, where,
              "curl_grad_div must flag groups of three consecutive densities, from outputs[" + std::to_string(d) + "]");
      d += 2;
      continue;
    }
    if (outputs[d] & grad_div) {  // a group of three, each with its own potential | gradient
      require(d + 2 < nd && is_grad_div(outputs[d]) && is_grad_div(outputs[d + 1]) && is_grad_div(outputs[d + 2]),
              ErrorCode::invalid_argument, where,
              "grad_div (with potential|gradient only) must flag groups of three consecutive densities, from outputs[" +
                  std::to_string(d) + "]");
      d += 2;
      continue;
    }
    require(outputs[d] >= 1 && outputs[d] <= all_outputs, ErrorCode::invalid_argument, where,
            "outputs[" + std::to_string(d) +
                "] must be a non-empty subset of potential|gradient|hessian, curl_grad_div or grad_div, got " +
                std::to_string(outputs[d]));
  }
}

std::vector<std::vector<std::size_t>> filled_result_columns(std::span<const unsigned> outputs) {
  std::vector<std::vector<std::size_t>> columns(outputs.size());
  const auto own = [&](std::size_t d) {
    if (outputs[d] & potential) columns[d].push_back(col_pot);
    if (outputs[d] & gradient) columns[d].insert(columns[d].end(), {col_gx, col_gy, col_gz});
    if (outputs[d] & hessian)
      columns[d].insert(columns[d].end(), {col_hxx, col_hyy, col_hzz, col_hxy, col_hxz, col_hyz});
  };
  for (std::size_t d = 0; d < outputs.size(); ++d) {
    if (outputs[d] == curl_grad_div) {  // curl in 1..3, grad div in 4..6 of the first row
      columns[d] = {1, 2, 3, 4, 5, 6};
      d += 2;
    } else if (outputs[d] & grad_div) {  // each its own potential | gradient, grad div in the first row
      for (std::size_t g = d; g < d + 3; ++g) own(g);
      columns[d].insert(columns[d].end(), {4, 5, 6});
      d += 2;
    } else {
      own(d);
    }
  }
  return columns;
}

// The FMM in the order of Guan's Algorithm 1 (docs/theory/fmm.md): upward pass, downward pass
// level by level (L2L, X list, plane-wave M2L of the V list from level 2 on), then the leaves.
void LaplaceFmm::evaluate(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                          std::span<double> results) const {
  require(plan_ != nullptr, ErrorCode::invalid_input, "LaplaceFmm::evaluate", "set_points has not been called");
  require_evaluation_arguments(charges, nd, outputs, results, plan_->n, plan_->m);
  const StopWatch total;
  StageTimes times;
  detail::Evaluation ev(*plan_, nd, outputs);
  timed(times, "sort", [&] { detail::sort_charges(ev, charges); });
  timed(times, "p2m", [&] { detail::form_leaf_multipoles(ev); });
  timed(times, "m2m", [&] { detail::merge_child_multipoles(ev); });
  times["l2l"] = times["x_p2l"] = times["m2l"] = 0.0;
  for (int l = 1; l < ev.tree.nlevels(); ++l) {
    timed(times, "l2l", [&] { detail::shift_parent_locals(ev, l); });
    timed(times, "x_p2l", [&] { detail::x_list_to_locals(ev, l); });
    if (l >= 2) timed(times, "m2l", [&] { detail::plane_wave_m2l(ev, l); });
  }
  timed(times, "l2p", [&] { detail::evaluate_leaf_locals(ev); });
  timed(times, "wx_far", [&] { detail::w_list_and_direct_far(ev); });
  timed(times, "p2p", [&] {
    if (options_.near_field) detail::u_list_direct(ev);
  });
  timed(times, "l2p", [&] { detail::fold_combined_groups(ev); });
  timed(times, "sort", [&] { detail::unsort_results(ev, results); });
  times["total"] = total.seconds();

  std::vector<double> costs = detail::target_costs(ev);
  std::lock_guard lock(mutex_);
  target_costs_ = std::move(costs);
  const double t_tree = timings_.count("tree") ? timings_["tree"] : 0.0;
  const double t_tab = timings_.count("tables") ? timings_["tables"] : 0.0;
  timings_ = times;
  timings_["tree"] = t_tree;
  timings_["tables"] = t_tab;
}

}  // namespace rpyfmm::fmm
