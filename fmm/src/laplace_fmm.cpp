// The adaptive plane-wave Laplace FMM driver (CGR 1999 §4 algorithm; dissertation 004 §2.4;
// PLANEWAVE.md §5.4 data flow): P2M, M2M, [L2L + X-list P2L + plane-wave M2L] per level,
// L2P + W-list M2P + U-list P2P at the leaves.
#include "rpyfmm/fmm/laplace_fmm.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "planewave_kernels.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/detail/expansions.hpp"
#include "rpyfmm/fmm/detail/octree.hpp"
#include "rpyfmm/fmm/detail/planewave.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/fmm/leaf_grid.hpp"

namespace rpyfmm::fmm {

using detail::cplx;
using detail::ncoef;

int fmm_order_for(double eps) {
  // Truncation bound of PLANEWAVE.md §1.5 (FMM3D l3dterms): sources within sqrt(3)/2, nearest
  // target at 1.5 (box units). Beyond some order the error saturates at the plane-wave table's own
  // error, so the bound is capped per table (docs/design-notes.md, "expansion order"). The caps
  // 8 / 18 / 32 / 42 for the 3 / 6 / 9 / 12-digit tables are the smallest orders that keep the
  // worst case within eps/2 (one source box with charges at its corners, every V-list offset:
  // FmmBlocks.PlaneWaveM2LAllOffsetsAllTables) and pass 200 coincident charges at 1e-9
  // (FmmFeatures.DuplicatedPoints); random distributions saturate earlier (p = 8/16/26/36).
  int p = 80;
  for (int q = 2; q < 80; ++q)
    if (std::pow(std::sqrt(3.0) / 2.0, q) / std::pow(1.5, q + 1) < eps) {
      p = q;
      break;
    }
  const int digits = fmm_table_digits_for(eps);
  const int cap = digits <= 3 ? 8 : digits <= 6 ? 18 : digits <= 9 ? 32 : 42;
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

int fmm_default_leaf_capacity(double eps) {
  // Measured (bench/fmm/RESULTS.md "Leaf capacity", pot+grad+Hessian, one thread). The best leaf
  // balances P2P against M2L, so it follows the P2P kernel's speed: with the AVX-512 kernels
  // (1/r by rsqrt14 + Newton, ~3x the pairs per second) larger leaves than FMM3D's
  // 100/200/400/600 pay off from 1e-6 on (uniform cube, N = 1e5, Intel machine); with sqrt and
  // division (AVX2 or baseline) the fastest capacities are 100/100/200 at 3/6/9 digits (cube and
  // sphere surface, N = 1e5 and 2e5, AMD Zen-1 machine), where 400/600 cost up to 2.1x more; 100 at
  // 6 digits since the half-node M2L (session 5: 1.15x over 150 on the sphere, cube trees equal).
  const int digits = fmm_table_digits_for(eps);
  if (simd_level() == SimdLevel::avx512) return digits <= 3 ? 100 : digits <= 6 ? 400 : digits <= 9 ? 600 : 800;
  return digits <= 3 ? 100 : digits <= 6 ? 100 : digits <= 9 ? 200 : 300;
}

namespace {
// Automatic leaves fitted to the cloud (fit_leaf_grid; bench/fmm/RESULTS.md "Fitted leaf grid"):
// where the bounding-cube tree's leaves hold well above the best occupancy (a uniform cube of 2e5
// points at 1e-6 and capacity 400: a partly split tree of 124 points per leaf, against a best of
// ~50), the root is enlarged so that leaves of the target occupancy span the cloud. Measured with
// the AVX-512 kernels (Intel machine, pot + grad + Hessian, 1 thread, cube and sphere surface,
// 1e4 ... 2e5 points, side by side): 1e-6 1.07-2.29x (2e5 cube), 1e-9 1.37-1.45x where it
// applies, 1e-12 0.97-1.20x, 1e-3 0.99-1.09x; N = 1e6 cube at 1e-6 11.1 -> 6.4 s.
// With the AVX2 / baseline kernels (AMD Zen-1 machine, session 8) the default capacities are
// already small and the best occupancies are ~16 / 25-49 / 50-110 / 60-110 points; there the grid
// is also fitted where a near-uniform cloud's bounding-cube tree is partly split (leaves on two
// levels: a uniform cube of 1e5 points at 1e-9 and capacity 200, 195 points per box at level 3,
// splits about half of them, and the W/X direct sums between the two levels cost 1.2 s of 4.5).

// fit_leaf_grid's fill (occupied fraction of ~8-point cells) above which a cloud counts as near-uniform.
constexpr double kUniformFill = 0.5;
// Leaf-level shares below which a near-uniform cloud's tree counts as partly split: measured with
// the AVX2 / baseline kernels at shares of ~0.5 (session 8); with the AVX-512 kernels (session 9)
// refitting gained 1.39-1.56x at shares 0.83-0.89, 1.15-1.28x at 0.93-0.96, 1.03x at 0.99, and
// lost up to 14% at 1 (one level).
constexpr double kPartialShare = 0.8;
constexpr double kPartialShareAvx512 = 0.97;

struct FittedGridRule {
  int occupancy = 0;  // 0: keep the bounding-cube tree
  std::size_t min_points = 0, max_points = 0;
  // Also fit near-uniform clouds whose cube tree is partly split: fewer than this share of the
  // points in its most populated leaf level (TreeStats::leaf_level_share); 0: never.
  double partial_split_share = 0.0;
  double min_fill = 0.0;  // fit only clouds that fill at least this much of their cube
};

FittedGridRule fitted_grid_rule(double eps) {
  if (simd_level() == SimdLevel::avx512) {
    // Best occupancies of the sweep (bench/fmm/leaf_grid_sweep.py): ~24 / 50-70 / 70-150 / 150-300
    // points at 3 / 6 / 9 / 12 digits. The upper size is the largest measured (1e6: errors 4.5e-8,
    // 7.8e-8, 1.3e-8 at 1e-6 and 2.5e-11, 5.5e-11, 1.0e-11 at 1e-9, potential/gradient/Hessian).
    // Partly split trees are refitted too (AMD Zen-4 machine, session 9: 1.16-1.85x, see above).
    switch (fmm_table_digits_for(eps)) {
      case 3:
        return {24, 20000, 1000000, kPartialShareAvx512};
      case 6:
        return {60, 10000, 1000000, kPartialShareAvx512};
      case 9:
        return {120, 10000, 1000000, kPartialShareAvx512};
      default:
        return {200, 10000, 1000000, kPartialShareAvx512};
    }
  }
  // Side by side (bench/fmm/fitted_grid.py): at 9 and 12 digits surfaces gained nothing (0.92-1.02x)
  // and 1e4 points at 12 digits neither (0.92x sphere, 0.99x cube): near-uniform clouds only there.
  switch (fmm_table_digits_for(eps)) {
    case 3:
      return {16, 10000, 1000000, kPartialShare, 0.0};
    case 6:
      return {36, 10000, 1000000, kPartialShare, 0.0};
    case 9:
      return {50, 10000, 1000000, kPartialShare, kUniformFill};
    default:
      return {70, 20000, 1000000, kPartialShare, kUniformFill};
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
}  // namespace

namespace {
// Loops over fewer boxes than this run on one thread: the fork/join (and, on a loaded machine, the
// barrier spin) costs more than the work. Results do not depend on it (each item is one thread's).
constexpr std::size_t kMinParallel = 32;

const detail::ChildTranslations& child_translations(int p) {
  static std::mutex mutex;
  static std::map<int, std::unique_ptr<detail::ChildTranslations>> cache;
  std::lock_guard lock(mutex);
  auto& slot = cache[p];
  if (!slot) slot = std::make_unique<detail::ChildTranslations>(p);
  return *slot;
}
}  // namespace

struct LaplaceFmm::Plan {
  detail::Octree tree;
  int p = 0, digits = 0, leaf_capacity = 0;
  double root_scale = 1.0;
  // W/X boxes with at most this many sources/targets are summed directly instead of by M2P/P2L;
  // with export_direct those direct sums are left to the caller (near_field() pairs).
  std::size_t direct_limit = 0;
  SimdLevel simd_level = SimdLevel::scalar;  // the level the parameters were chosen for
  bool export_direct = false;
  const detail::Harmonics* H = nullptr;
  const detail::ChildTranslations* ct = nullptr;
  const detail::PlaneWave* pw = nullptr;
  std::size_t n = 0, m = 0;
  std::vector<double> sx, sy, sz, tx, ty, tz;  // sorted coordinates, structure of arrays
};

LaplaceFmm::LaplaceFmm(const FmmOptions& options) : options_(options) {
  constexpr const char* where = "LaplaceFmm";
  require_in_range(options.tolerance, 1e-15, 1e-1, where, "tolerance");
  require(options.leaf_capacity >= 0, ErrorCode::invalid_argument, where,
          "leaf_capacity must be >= 0 (0 = automatic), got " + std::to_string(options.leaf_capacity));
  require(std::isfinite(options.min_leaf_side) && options.min_leaf_side >= 0.0, ErrorCode::invalid_argument, where,
          "min_leaf_side must be finite and >= 0, got " + std::to_string(options.min_leaf_side));
  require(options.root_scale >= 1.0 && options.root_scale <= 8.0, ErrorCode::invalid_argument, where,
          "root_scale must be in [1, 8], got " + std::to_string(options.root_scale));
  require(options.order == 0 || (options.order >= 2 && options.order <= 70), ErrorCode::invalid_argument, where,
          "order must be 0 (automatic) or in [2, 70], got " + std::to_string(options.order));
}

LaplaceFmm::~LaplaceFmm() = default;
LaplaceFmm::LaplaceFmm(LaplaceFmm&& o) noexcept
    : options_(o.options_), plan_(std::move(o.plan_)), timings_(std::move(o.timings_)), near_(std::move(o.near_)) {}
LaplaceFmm& LaplaceFmm::operator=(LaplaceFmm&& o) noexcept {
  options_ = o.options_;
  plan_ = std::move(o.plan_);
  timings_ = std::move(o.timings_);
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

}  // namespace

void LaplaceFmm::set_points(std::span<const double> sources, std::span<const double> targets) {
  constexpr const char* where = "LaplaceFmm::set_points";
  require(sources.size() % 3 == 0, ErrorCode::invalid_input, where,
          "sources has " + std::to_string(sources.size()) + " entries, not a multiple of 3");
  require(!sources.empty(), ErrorCode::invalid_input, where, "no sources (N = 0)");
  require(targets.size() % 3 == 0, ErrorCode::invalid_input, where,
          "targets has " + std::to_string(targets.size()) + " entries, not a multiple of 3");
  require_finite(sources, where, "sources", 3);
  require_finite(targets, where, "targets", 3);
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
  plan->digits = fmm_table_digits_for(options_.tolerance);
  plan->leaf_capacity =
      options_.leaf_capacity > 0 ? options_.leaf_capacity : fmm_default_leaf_capacity(options_.tolerance);
  // Direct W/X sums beat M2P/P2L below ~p^2/2 points by operation counts (CGR 1999 §4), with
  // pairs as dear as expansion terms. The AVX-512 P2P kernels make pairs ~3x cheaper, and there
  // the limit is 2 p^2 (measured on an AMD Zen-4 machine, session 9, bench/fmm/RESULTS.md "W/X
  // direct limit": surfaces 1.1-1.5x faster, one-level trees unchanged). A caller that takes them
  // over (export_direct_far) has a kernel cheaper than nd Laplace densities, and direct sums of
  // whole leaves then win even more (measured: FmmRpy, bench/rpy/RESULTS.md).
  detail::OctreeParams tp;
  tp.leaf_capacity = std::size_t(plan->leaf_capacity);
  tp.min_leaf_side = options_.min_leaf_side;
  tp.root_scale = options_.root_scale;
  plan->tree.build(sources, targets, tp);
  // Automatic leaves: the bounding-cube tree decides whether a fitted grid can pay, then the tree
  // is rebuilt on it (fitted_grid_rule).
  if (options_.leaf_capacity == 0 && options_.root_scale == 1.0) {
    const FittedGridRule rule = fitted_grid_rule(options_.tolerance);
    const std::size_t points = sources.size() / 3 + targets.size() / 3;
    const bool in_range = points >= rule.min_points && points <= rule.max_points;
    const bool pays = in_range && fitted_leaf_grid_pays(points, plan->tree.leaves().size(), rule.occupancy);
    const bool partial = in_range && !pays && leaf_level_share(plan->tree) < rule.partial_split_share;
    if (pays || partial) {
      const double min_fill = partial ? std::max(rule.min_fill, kUniformFill) : rule.min_fill;
      const LeafGrid grid = fit_leaf_grid(sources, targets, rule.occupancy, min_fill);
      if (grid.fitted()) {
        plan->leaf_capacity = grid.leaf_capacity;
        tp.leaf_capacity = std::size_t(grid.leaf_capacity);
        tp.root_scale = grid.root_scale;
        plan->tree.build(sources, targets, tp);
      }
    }
  }
  plan->root_scale = tp.root_scale;
  plan->export_direct = options_.export_direct_far && !options_.near_field;
  const std::size_t p2 = std::size_t(plan->p) * std::size_t(plan->p);
  plan->simd_level = simd_level();
  plan->direct_limit = plan->simd_level == SimdLevel::avx512 ? 2 * p2 : p2 / 2;
  if (plan->export_direct) plan->direct_limit = std::max(p2 / 2, std::size_t(plan->leaf_capacity));
  const double t_tree = sw.seconds();
  sw.restart();
  plan->H = &detail::Harmonics::cached(plan->p + 2);
  plan->ct = &child_translations(plan->p);
  plan->pw = &detail::PlaneWave::cached(plan->p, plan->digits);
  plan->n = sources.size() / 3;
  plan->m = targets.empty() ? plan->n : targets.size() / 3;
  auto soa = [](const std::vector<double>& xyz, std::vector<double>& x, std::vector<double>& y,
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
  };
  soa(plan->tree.sorted_sources(), plan->sx, plan->sy, plan->sz);
  soa(plan->tree.sorted_targets(), plan->tx, plan->ty, plan->tz);
  const double t_tables = sw.seconds();
  std::lock_guard lock(mutex_);
  plan_ = std::move(plan);
  near_.reset();
  timings_.clear();
  timings_["tree"] = t_tree;
  timings_["tables"] = t_tables;
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

const NearField& LaplaceFmm::near_field() const {
  require(plan_ != nullptr, ErrorCode::invalid_input, "LaplaceFmm::near_field", "set_points has not been called");
  std::lock_guard lock(mutex_);
  if (near_) return *near_;
  const auto& t = plan_->tree;
  auto nf = std::make_unique<NearField>();
  const auto& leaves = t.leaves();
  std::vector<int> leaf_id(t.boxes().size(), -1);
  for (std::size_t i = 0; i < leaves.size(); ++i) leaf_id[leaves[i]] = int(i);
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
  if (plan_->export_direct) {
    // The W/X sums evaluate() leaves to the caller: every leaf (with sources) under such a box.
    const auto& boxes = t.boxes();
    const std::size_t limit = plan_->direct_limit;
    std::vector<int> stack;
    auto add_leaves_under = [&](std::uint32_t target_leaf, int box) {
      stack.assign(1, box);
      while (!stack.empty()) {
        const int c = stack.back();
        stack.pop_back();
        if (boxes[c].nsrc() == 0) continue;
        if (boxes[c].leaf) {
          nf->pairs.emplace_back(target_leaf, std::uint32_t(leaf_id[c]));
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
  near_ = std::move(nf);
  return *near_;
}

void LaplaceFmm::evaluate(std::span<const double> charges, std::size_t nd, unsigned outputs,
                          std::span<double> results) const {
  std::vector<unsigned> flags(nd, outputs);
  evaluate(charges, nd, flags, results);
}

void LaplaceFmm::evaluate(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                          std::span<double> results) const {
  constexpr const char* where = "LaplaceFmm::evaluate";
  require(plan_ != nullptr, ErrorCode::invalid_input, where, "set_points has not been called");
  require(nd >= 1, ErrorCode::invalid_argument, where, "nd must be >= 1");
  const Plan& P = *plan_;
  const std::size_t N = P.n, M = P.m;
  require_size(charges, nd * N, where, "charges (nd x N)");
  require_finite(charges, where, "charges", N);
  require(outputs.size() == nd, ErrorCode::invalid_input, where,
          "outputs has " + std::to_string(outputs.size()) + " entries, expected nd = " + std::to_string(nd));
  for (std::size_t d = 0; d < nd; ++d)
    require(outputs[d] >= 1 && outputs[d] <= all_outputs, ErrorCode::invalid_argument, where,
            "outputs[" + std::to_string(d) + "] must be a non-empty subset of potential|gradient|hessian, got " +
                std::to_string(outputs[d]));
  require_size(results, nd * M * result_width, where, "results (nd x M x 10)");

  StageTimes times;
  StopWatch total, sw;
  const auto& tree = P.tree;
  const auto& boxes = tree.boxes();
  const int nb = int(boxes.size());
  const int p = P.p;
  const int nc = ncoef(p);
  const auto& H = *P.H;
  const auto& ct = *P.ct;
  const auto& pw = *P.pw;
  const auto& sxyz = tree.sorted_sources();
  const auto& txyz = tree.sorted_targets();
  unsigned any_flags = 0;
  for (unsigned f : outputs) any_flags |= f;
  const bool uniform_flags = std::all_of(outputs.begin(), outputs.end(), [&](unsigned f) { return f == outputs[0]; });

  // Sorted charges, nd x N.
  std::vector<double> qs(nd * N);
  const auto& sperm = tree.source_order();
#pragma omp parallel for if (N >= 4096) schedule(static)
  for (std::size_t j = 0; j < N; ++j)
    for (std::size_t d = 0; d < nd; ++d) qs[d * N + j] = charges[d * N + sperm[j]];
  std::vector<double> res(nd * M * result_width, 0.0);
  times["sort"] = sw.seconds();

  const std::size_t stride = nd * std::size_t(nc);
  std::vector<cplx> mp(std::size_t(nb) * stride), lp(std::size_t(nb) * stride);
  std::vector<char> has_local(nb, 0);
  const int nlev = tree.nlevels();

  // ---- P2M at the leaves (§6.3) ----
  sw.restart();
  const auto& leaves = tree.leaves();
#pragma omp parallel if (leaves.size() >= kMinParallel)
  {
    std::vector<double> scratch(2 * std::size_t(nc) * detail::kL2PLanes);
#pragma omp for schedule(dynamic, 8)
    for (std::size_t i = 0; i < leaves.size(); ++i) {
      const int b = leaves[i];
      const auto& bx = boxes[b];
      if (bx.nsrc() == 0 || bx.level < 2) continue;
      const auto c = tree.center(b);
      const double inv_s = 1.0 / tree.side(bx.level);
      for (std::size_t j0 = bx.src_begin; j0 < bx.src_end; j0 += detail::kL2PLanes) {
        const int np = int(std::min<std::size_t>(detail::kL2PLanes, bx.src_end - j0));
        double ux[detail::kL2PLanes], uy[detail::kL2PLanes], uz[detail::kL2PLanes];
        for (int t = 0; t < np; ++t) {
          ux[t] = (P.sx[j0 + t] - c[0]) * inv_s;
          uy[t] = (P.sy[j0 + t] - c[1]) * inv_s;
          uz[t] = (P.sz[j0 + t] - c[2]) * inv_s;
        }
        detail::p2m_block(p, H.regular_recurrence(), H.c_table(), np, ux, uy, uz, &qs[j0], N, nd,
                          &mp[std::size_t(b) * stride], scratch.data());
      }
    }
  }
  times["p2m"] = sw.seconds();

  // ---- M2M (§2.3), deepest level first ----
  sw.restart();
  for (int l = nlev - 2; l >= 2; --l) {
#pragma omp parallel if (std::size_t(tree.level_end(l) - tree.level_begin(l)) >= kMinParallel)
    {
      std::vector<cplx> work(2 * std::size_t(nc));
#pragma omp for schedule(dynamic, 8)
      for (int b = tree.level_begin(l); b < tree.level_end(l); ++b) {
        const auto& bx = boxes[b];
        if (bx.leaf || bx.nsrc() == 0) continue;
        for (int o = 0; o < 8; ++o) {
          const int c = bx.child[o];
          if (c < 0 || boxes[c].nsrc() == 0) continue;
          for (std::size_t d = 0; d < nd; ++d)
            ct.m2m(o, &mp[std::size_t(c) * stride + d * nc], &mp[std::size_t(b) * stride + d * nc], work.data());
        }
      }
    }
  }
  times["m2m"] = sw.seconds();

  // W and X lists: a box with few sources (W) or few targets (X) is cheaper by direct summation
  // than by M2P or P2L (CGR 1999 §4; PLANEWAVE.md §5.6). Threshold ~ p^2/2 by operation counts.
  const std::size_t direct_limit = P.direct_limit;
  const bool export_direct = P.export_direct;
  auto p2p = [&](const detail::Box& src_box, std::size_t tbeg, std::size_t tcount) {
    const PointsSoA tg{&P.tx[tbeg], &P.ty[tbeg], &P.tz[tbeg], tcount};
    const PointsSoA sr{&P.sx[src_box.src_begin], &P.sy[src_box.src_begin], &P.sz[src_box.src_begin], src_box.nsrc()};
    if (uniform_flags) {
      laplace_p2p_add(sr, &qs[src_box.src_begin], N, nd, tg, outputs[0], &res[tbeg * result_width], M * result_width);
    } else {
      for (std::size_t d = 0; d < nd; ++d)
        laplace_p2p_add(sr, &qs[d * N + src_box.src_begin], N, 1, tg, outputs[d], &res[(d * M + tbeg) * result_width],
                        M * result_width);
    }
  };

  // ---- downward pass ----
  double t_l2l = 0, t_x = 0, t_m2l = 0;
  const int sumM = pw.sum_physical(), sumK = pw.sum_fourier();
  const auto& groups = detail::merge_groups();
  for (int l = 1; l < nlev; ++l) {
    const int lb = tree.level_begin(l), le = tree.level_end(l);
    sw.restart();
    {
#pragma omp parallel if (std::size_t(le - lb) >= kMinParallel)
      {
        std::vector<cplx> work(2 * std::size_t(nc));
#pragma omp for schedule(dynamic, 8)
        for (int b = lb; b < le; ++b) {
          const auto& bx = boxes[b];
          if (bx.ntgt() == 0 || !has_local[bx.parent]) continue;
          int oct = 0;
          for (int o = 0; o < 8; ++o)
            if (boxes[bx.parent].child[o] == b) oct = o;
          for (std::size_t d = 0; d < nd; ++d)
            ct.l2l(oct, &lp[std::size_t(bx.parent) * stride + d * nc], &lp[std::size_t(b) * stride + d * nc],
                   work.data());
          has_local[b] = 1;
        }
      }
    }
    t_l2l += sw.seconds();
    sw.restart();
    // X list: P2L (§6.3, §5.6).
#pragma omp parallel if (std::size_t(le - lb) >= kMinParallel)
    {
      std::vector<cplx> scratch(ncoef(p + 2));
#pragma omp for schedule(dynamic, 8)
      for (int b = lb; b < le; ++b) {
        const auto& bx = boxes[b];
        if (bx.ntgt() <= direct_limit) continue;  // few targets: direct sum in the leaf pass
        const auto c = tree.center(b);
        for (int x : tree.xlist().of(b)) {
          const auto& xb = boxes[x];
          if (xb.nsrc() == 0) continue;
          detail::p2l(H, p, tree.side(l), c.data(), &sxyz[3 * xb.src_begin], &qs[xb.src_begin], N, nd, xb.nsrc(),
                      &lp[std::size_t(b) * stride], scratch.data());
          has_local[b] = 1;
        }
      }
    }
    t_x += sw.seconds();
    if (l < 2) continue;
    // Plane-wave M2L with merge-and-shift (§5.3, §5.4 step 3), one frame pair at a time.
    sw.restart();
    const double s = tree.side(l);
    const std::size_t wave_stride = std::size_t(sumM) * nd;  // one direction of one box
    std::vector<cplx> waves(std::size_t(le - lb) * 2 * wave_stride);
    for (int f = 0; f < 3; ++f) {
#pragma omp parallel if (std::size_t(le - lb) >= kMinParallel)
      {
        std::vector<cplx> Mt(nc), Mr(nc), Mw(nc), Fu(sumK), Fd(sumK);
        detail::PlaneWave::LaneWork lanes;
#pragma omp for schedule(dynamic, 16)
        for (int b = lb; b < le; ++b) {
          if (boxes[b].nsrc() == 0) continue;
          if (nd > 1) {  // densities in vector lanes (planewave_batch.cpp)
            cplx* W = &waves[std::size_t(b - lb) * 2 * wave_stride];
            for (std::size_t d0 = 0; d0 < nd; d0 += detail::PlaneWave::kDensityLanes) {
              const int nl = int(std::min<std::size_t>(detail::PlaneWave::kDensityLanes, nd - d0));
              pw.multipole_to_waves(f, &mp[std::size_t(b) * stride + d0 * nc], std::size_t(nc), nl, 1.0 / s,
                                    W + d0 * sumM, W + wave_stride + d0 * sumM, std::size_t(sumM), lanes);
            }
            continue;
          }
          const cplx* Mh = &mp[std::size_t(b) * stride];   // nd = 1
          for (int i = 0; i < nc; ++i) Mt[i] = Mh[i] / s;  // unit-frame multipole (§3.4, pitfall §9)
          pw.to_frame(f, Mt.data(), Mr.data(), Mw.data());
          pw.m2f(Mr.data(), Fu.data(), Fd.data());
          cplx* W = &waves[std::size_t(b - lb) * 2 * wave_stride];
          pw.f2p(Fu.data(), W);
          pw.f2p(Fd.data(), W + wave_stride);
        }
      }
      const int pb = tree.level_begin(l - 1), pe = tree.level_end(l - 1);
#pragma omp parallel if (std::size_t(pe - pb) >= kMinParallel)
      {
        struct Acc {
          int sign;
          unsigned mask;
          std::vector<cplx> v;
        };
        std::vector<Acc> accs;
        std::vector<cplx> V2(2 * wave_stride), Gu(sumK), Gd(sumK), Lf(nc), Lb(nc);  // G, L: nd = 1 path
        detail::PlaneWave::LaneWork lanes;
#pragma omp for schedule(dynamic, 4)
        for (int P0 = pb; P0 < pe; ++P0) {
          const auto& par = boxes[P0];
          if (par.leaf || par.ntgt() == 0) continue;
          std::size_t nacc = 0;
          for (int C : tree.colleagues().of(P0))
            for (int e : boxes[C].child) {
              if (e < 0 || boxes[e].nsrc() == 0) continue;
              const int ax = int(boxes[e].ix - 2 * par.ix), ay = int(boxes[e].iy - 2 * par.iy),
                        az = int(boxes[e].iz - 2 * par.iz);
              const detail::MergeGroup g = groups[detail::merge_position(ax, ay, az)][f];
              if (g.mask == 0) continue;
              std::size_t k = 0;
              while (k < nacc && !(accs[k].sign == g.sign && accs[k].mask == g.mask)) ++k;
              if (k == nacc) {
                if (accs.size() <= nacc) accs.push_back({0, 0, {}});
                accs[k].sign = g.sign;
                accs[k].mask = g.mask;
                accs[k].v.assign(wave_stride, cplx(0.0));
                ++nacc;
              }
              // Shift from the source center to the center of child 0 (offset d = -a).
              const auto dp = detail::PlaneWave::frame_offset(f, {-ax, -ay, -az});
              const cplx* sh = g.sign > 0 ? pw.shift(dp[0], dp[1], dp[2]) : pw.shift(-dp[0], -dp[1], -dp[2]);
              const cplx* W = &waves[std::size_t(e - lb) * 2 * wave_stride + (g.sign > 0 ? 0 : wave_stride)];
              detail::shift_accumulate(std::size_t(sumM), nd, sh, W, accs[k].v.data());
            }
          if (nacc == 0) continue;
          for (int o = 0; o < 8; ++o) {
            const int c = par.child[o];
            if (c < 0 || boxes[c].ntgt() == 0) continue;
            bool got[2] = {false, false};
            for (int sgn = 0; sgn < 2; ++sgn) {
              const int sign = sgn == 0 ? 1 : -1;
              cplx* V = V2.data() + sgn * wave_stride;
              std::fill(V, V + wave_stride, cplx(0.0));
              for (std::size_t k = 0; k < nacc; ++k) {
                if (accs[k].sign != sign || !(accs[k].mask & (1u << o))) continue;
                got[sgn] = true;
                detail::accumulate(wave_stride, accs[k].v.data(), V);
              }
              cplx* G = sgn == 0 ? Gu.data() : Gd.data();
              if (!got[sgn]) {
                if (nd == 1) std::fill(G, G + sumK, cplx(0.0));
                continue;
              }
              const auto dp = detail::PlaneWave::frame_offset(f, {o & 1, (o >> 1) & 1, (o >> 2) & 1});
              const cplx* sh = sign > 0 ? pw.shift(dp[0], dp[1], dp[2]) : pw.shift(-dp[0], -dp[1], -dp[2]);
              detail::shift_in_place(std::size_t(sumM), nd, sh, V);
              if (nd == 1) pw.p2f(V, G);
            }
            if (!got[0] && !got[1]) continue;
            has_local[c] = 1;
            if (nd > 1) {  // densities in vector lanes (planewave_batch.cpp)
              for (std::size_t d0 = 0; d0 < nd; d0 += detail::PlaneWave::kDensityLanes) {
                const int nl = int(std::min<std::size_t>(detail::PlaneWave::kDensityLanes, nd - d0));
                pw.waves_to_local(f, got[0] ? V2.data() + d0 * sumM : nullptr,
                                  got[1] ? V2.data() + wave_stride + d0 * sumM : nullptr, std::size_t(sumM), nl,
                                  &lp[std::size_t(c) * stride + d0 * nc], std::size_t(nc), lanes);
              }
              continue;
            }
            pw.f2l(Gu.data(), Gd.data(), Lf.data());  // nd = 1
            pw.from_frame(f, Lf.data(), Lb.data());
            cplx* out = &lp[std::size_t(c) * stride];
            for (int i = 0; i < nc; ++i) out[i] += Lb[i];
          }
        }
      }
    }
    t_m2l += sw.seconds();
  }
  times["l2l"] = t_l2l;
  times["x_p2l"] = t_x;
  times["m2l"] = t_m2l;

  // ---- leaves: L2P (§6.1) ----
  sw.restart();
#pragma omp parallel if (leaves.size() >= kMinParallel)
  {
    std::vector<cplx> bcoef(stride);
    std::vector<double> scratch(2 * std::size_t(nc) * detail::kL2PLanes);
    const double* rec = H.regular_recurrence();
#pragma omp for schedule(dynamic, 4)
    for (std::size_t i = 0; i < leaves.size(); ++i) {
      const int b = leaves[i];
      const auto& bx = boxes[b];
      if (bx.ntgt() == 0 || !has_local[b]) continue;
      const double s = tree.side(bx.level), inv_s = 1.0 / s;
      const auto c = tree.center(b);
      for (std::size_t d = 0; d < nd; ++d)
        detail::local_to_b(H, p, &lp[std::size_t(b) * stride + d * nc], &bcoef[d * nc]);
      for (std::size_t t0 = bx.tgt_begin; t0 < bx.tgt_end; t0 += detail::kL2PLanes) {
        const int nt = int(std::min<std::size_t>(detail::kL2PLanes, bx.tgt_end - t0));
        double ux[detail::kL2PLanes], uy[detail::kL2PLanes], uz[detail::kL2PLanes];
        for (int t = 0; t < nt; ++t) {
          ux[t] = (P.tx[t0 + t] - c[0]) * inv_s;
          uy[t] = (P.ty[t0 + t] - c[1]) * inv_s;
          uz[t] = (P.tz[t0 + t] - c[2]) * inv_s;
        }
        detail::l2p_block(p, s, rec, bcoef.data(), nd, outputs.data(), nt, ux, uy, uz, &res[t0 * result_width],
                          M * result_width, scratch.data());
      }
    }
  }
  times["l2p"] = sw.seconds();

  // ---- W list: M2P (§6.2) ----
  sw.restart();
  const int pS = p + ((any_flags & hessian) ? 2 : (any_flags & gradient) ? 1 : 0);
#pragma omp parallel if (leaves.size() >= kMinParallel)
  {
    std::vector<cplx> S(ncoef(p + 2)), acoef(stride);
#pragma omp for schedule(dynamic, 4)
    for (std::size_t i = 0; i < leaves.size(); ++i) {
      const int b = leaves[i];
      const auto& bx = boxes[b];
      if (bx.ntgt() == 0) continue;
      for (int w : tree.wlist().of(b)) {
        const auto& wb = boxes[w];
        if (wb.nsrc() == 0) continue;
        if (wb.nsrc() <= direct_limit) {
          if (!export_direct) p2p(wb, bx.tgt_begin, bx.ntgt());
          continue;
        }
        const double s = tree.side(wb.level);
        const auto c = tree.center(w);
        for (std::size_t d = 0; d < nd; ++d)
          detail::multipole_to_a(H, p, &mp[std::size_t(w) * stride + d * nc], &acoef[d * nc]);
        for (std::size_t t = bx.tgt_begin; t < bx.tgt_end; ++t) {
          const double inv_s = 1.0 / s;
          H.singular(pS, (txyz[3 * t] - c[0]) * inv_s, (txyz[3 * t + 1] - c[1]) * inv_s,
                     (txyz[3 * t + 2] - c[2]) * inv_s, S.data());
          for (std::size_t d = 0; d < nd; ++d)
            detail::m2p_eval(p, s, &acoef[d * nc], S.data(), outputs[d], &res[(d * M + t) * result_width]);
        }
      }
      // X lists of this leaf and its ancestors that were left to direct summation.
      for (int a = b; a >= 0 && !export_direct; a = boxes[a].parent) {
        if (boxes[a].ntgt() > direct_limit) continue;
        for (int x : tree.xlist().of(a))
          if (boxes[x].nsrc() > 0) p2p(boxes[x], bx.tgt_begin, bx.ntgt());
      }
    }
  }
  times["wx_far"] = sw.seconds();

  // ---- U list: P2P (§6.4) ----
  sw.restart();
  if (options_.near_field) {
#pragma omp parallel for if (leaves.size() >= kMinParallel) schedule(dynamic, 4)
    for (std::size_t i = 0; i < leaves.size(); ++i) {
      const int b = leaves[i];
      const auto& bx = boxes[b];
      if (bx.ntgt() == 0) continue;
      for (int u : tree.ulist().of(b))
        if (boxes[u].nsrc() > 0) p2p(boxes[u], bx.tgt_begin, bx.ntgt());
    }
  }
  times["p2p"] = sw.seconds();

  // ---- back to the caller's order ----
  sw.restart();
  const auto& tperm = tree.target_order();
#pragma omp parallel for if (M >= 4096) schedule(static)
  for (std::size_t t = 0; t < M; ++t)
    for (std::size_t d = 0; d < nd; ++d)
      std::copy_n(&res[(d * M + t) * result_width], result_width, &results[(d * M + tperm[t]) * result_width]);
  times["sort"] += sw.seconds();
  times["total"] = total.seconds();

  std::lock_guard lock(mutex_);
  const double t_tree = timings_.count("tree") ? timings_["tree"] : 0.0;
  const double t_tab = timings_.count("tables") ? timings_["tables"] : 0.0;
  timings_ = times;
  timings_["tree"] = t_tree;
  timings_["tables"] = t_tab;
}

}  // namespace rpyfmm::fmm
