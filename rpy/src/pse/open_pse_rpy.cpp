// rpyfmm — OpenPseRpy: PSE in free space (plan from the configuration's extent, the inner
// periodic PseRpy with the compactly supported kernel, the constant part and its noise).
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <numbers>
#include <vector>

#include "kernels_common.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/real_space.hpp"
#include "rpyfmm/rpy/random.hpp"

namespace rpyfmm::rpy::pse {

namespace {

constexpr const char* kWhere = "OpenPseRpy";

/// The smallest unit 2^(k/16) >= v (k integer): extents rounded up in 4.4% steps.
double round_up_extent(double v, double unit) {
  if (!(v > unit)) return unit;
  double k = std::ceil(16.0 * std::log2(v / unit));
  double r = unit * std::exp2(k / 16.0);
  while (r < v) r = unit * std::exp2(++k / 16.0);
  return r;
}

/// What the plan depends on: N, a and the rounded extents (bounding-sphere diameter D, box sides s).
struct Extent {
  std::size_t n = 0;
  double radius = 0.0;
  double diameter = 0.0;
  std::array<double, 3> sides = {0, 0, 0};
  bool operator==(const Extent&) const = default;
};

/// The configuration's centre (middle of its bounding box) and rounded extent.
Extent measure(std::span<const double> x, double a, std::array<double, 3>& centre) {
  const std::size_t n = x.size() / 3;
  std::array<double, 3> lo = {x[0], x[1], x[2]}, hi = lo;
  for (std::size_t i = 1; i < n; ++i)
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], x[3 * i + d]);
      hi[d] = std::max(hi[d], x[3 * i + d]);
    }
  for (int d = 0; d < 3; ++d) centre[d] = 0.5 * (lo[d] + hi[d]);
  double rho2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    double r2 = 0.0;
    for (int d = 0; d < 3; ++d) r2 += (x[3 * i + d] - centre[d]) * (x[3 * i + d] - centre[d]);
    rho2 = std::max(rho2, r2);
  }
  Extent e;
  e.n = n;
  e.radius = a;
  e.diameter = round_up_extent(2.0 * std::sqrt(rho2), a);
  for (int d = 0; d < 3; ++d) e.sides[d] = round_up_extent(hi[d] - lo[d], a);
  return e;
}

/// One candidate plan: the options for the inner PseRpy, its box and its parameters.
struct Candidate {
  PseOptions options;
  std::array<double, 3> box = {0, 0, 0};
  PseParameters params;
};

/// R = D + w and L_d = s_d + R + w with w = r_cut + 2a (docs/theory/pse.md, "Open boundaries"):
/// pairs within D see the free-space kernel, and no periodic image comes within R + w.
/// window_eta: the shape to use (0 = automatic, the cheapest of PseOptions' candidates).
Candidate candidate_for(const PseOptions& user, const Extent& e, double xi, double r_cut, double window_eta) {
  const double a = e.radius;
  const double reach = r_cut + 2.0 * a;
  Candidate c;
  c.options = user;
  c.options.xi = xi;
  c.options.window_eta = window_eta;
  c.options.open_truncation = e.diameter + reach;
  double volume = 1.0;
  for (int d = 0; d < 3; ++d) {
    c.box[d] = e.sides[d] + c.options.open_truncation + reach;
    volume *= std::max(e.sides[d], r_cut);
  }
  // The cost model counts real-space pairs at the particles' density, not the padded box's.
  c.options.pair_density = static_cast<double>(e.n) / volume;
  c.params = choose_parameters(c.options, a, c.box, e.n);
  return c;
}

/// xi a in [0.2, 8] as choose_parameters tries it for a periodic box: steps of 0.05 to 2.5, then 0.25.
std::vector<double> xi_a_values() {
  std::vector<double> v;
  for (double xa = 0.2; xa <= 8.0 + 1e-12; xa += (xa < 2.5 ? 0.05 : 0.25)) v.push_back(xa);
  return v;
}

/// Real-space cutoffs per xi a value of xi_a_values() for one radius and tolerance, computed when
/// first asked for (they do not depend on the configuration's extent).
struct CutoffMemo {
  double radius = 0.0;
  std::vector<double> r_cut;
  double at(const PseOptions& user, double a, std::size_t i, double xa) {
    if (user.r_cut > 0.0) return user.r_cut;
    if (radius != a) {
      radius = a;
      r_cut.assign(r_cut.size(), 0.0);
    }
    if (r_cut.size() <= i) r_cut.resize(i + 1, 0.0);
    if (r_cut[i] == 0.0) r_cut[i] = real_space_cutoff(0.5 * user.tolerance, xa / a, a);
    return r_cut[i];
  }
};

/// The candidate of least modelled cost over xi a in [0.2, 8] (as choose_parameters for a periodic
/// box, whose box here grows with the reach r_cut(xi)), or the user's xi. A plan is chosen whenever
/// the configuration's extent changes a step, so the search is kept short: xi is scanned with the
/// window shape of the user or eta* = 0.65 (every fourth value, then those around the cheapest),
/// and the shape is chosen for the xi found.
Candidate choose_plan(const PseOptions& user, const Extent& e, CutoffMemo& cutoffs) {
  const double a = e.radius;
  if (user.xi != 0.0) {
    const double r_cut = user.r_cut > 0.0 ? user.r_cut : real_space_cutoff(0.5 * user.tolerance, user.xi, a);
    return candidate_for(user, e, user.xi, r_cut, user.window_eta);
  }
  static const std::vector<double> values = xi_a_values();
  const double scan_eta = user.window_eta > 0.0 ? user.window_eta : 0.65;
  std::vector<double> cost(values.size(), std::numeric_limits<double>::infinity());
  std::vector<bool> done(values.size(), false);
  std::exception_ptr last;
  auto attempt = [&](std::size_t i) {
    if (done[i]) return;
    done[i] = true;
    try {
      cost[i] = candidate_for(user, e, values[i] / a, cutoffs.at(user, a, i, values[i]), scan_eta).params.modelled_cost;
    } catch (const Error&) {
      last = std::current_exception();
    }
  };
  auto cheapest = [&]() { return static_cast<std::size_t>(std::min_element(cost.begin(), cost.end()) - cost.begin()); };
  constexpr std::size_t kCoarse = 4;
  for (std::size_t i = 0; i < values.size(); i += kCoarse) attempt(i);
  if (!std::isfinite(cost[cheapest()])) {  // nothing feasible on the coarse values: try them all
    for (std::size_t i = 0; i < values.size(); ++i) attempt(i);
    if (!std::isfinite(cost[cheapest()])) std::rethrow_exception(last);
  }
  const std::size_t coarse_best = cheapest();
  const std::size_t lo = coarse_best >= kCoarse ? coarse_best - kCoarse + 1 : 0;
  for (std::size_t i = lo; i < std::min(values.size(), coarse_best + kCoarse); ++i) attempt(i);
  const std::size_t best = cheapest();
  Candidate c = candidate_for(user, e, values[best] / a, cutoffs.at(user, a, best, values[best]), user.window_eta);
  c.params.xi_automatic = true;
  return c;
}

void add_times(StageTimes& into, const StageTimes& from) {
  for (const auto& [stage, seconds] : from) into[stage] += seconds;
}

}  // namespace

/// Plans kept for extents met before (jitter of a small configuration across a rounding step
/// alternates between a few extents): at most kCachedPlans, and beyond the current one only while
/// their memory stays under kCachedBytes. A cache only saves planning: every plan is a function of
/// its extent, so results do not depend on which plans are kept.
constexpr std::size_t kCachedPlans = 16;
constexpr std::size_t kCachedBytes = std::size_t{256} << 20;

struct OpenPseRpy::Impl {
  struct Plan {
    Extent extent;
    std::unique_ptr<PseRpy> op;
    std::array<double, 3> box = {0, 0, 0};
    double constant = 0.0;  // c = 1 / (4 pi eta R)
    std::uint64_t last_used = 0;
    std::size_t bytes() const { return op->parameters().memory_bytes + op->parameters().real_space_cache_bytes; }
  };
  PseOptions options;
  std::vector<Plan> plans;
  std::size_t current = 0;  // index into plans (valid while positions are set)
  std::uint64_t uses = 0;
  PseParameters params;
  std::array<double, 3> shift = {0, 0, 0};  // inner position = position + shift
  std::vector<double> shifted;
  mutable StageTimes times;  // this operator's stages and those of evicted plans
  CutoffMemo cutoffs;

  const PseRpy& inner() const { return *plans[current].op; }
  double constant() const { return plans[current].constant; }

  /// The plan for `extent`: a kept one, or a new one (chosen, constructed, added to the cache).
  std::size_t plan_for(const Extent& extent, double viscosity) {
    for (std::size_t i = 0; i < plans.size(); ++i)
      if (plans[i].extent == extent) return i;
    StopWatch sw;
    Candidate c;
    try {
      c = choose_plan(options, extent, cutoffs);
    } catch (const Error& e) {
      if (e.code() != ErrorCode::out_of_memory) throw;
      // The grid grows with the configuration's extent: say so, and what suits spread-out particles.
      throw Error(e.code(), std::string(e.what()) + " (OpenPseRpy: the particles span " +
                                format_number(extent.diameter) +
                                " lengths; the grid covers twice that: use the FMM operator for spread-out "
                                "configurations)");
    }
    Plan p;
    p.extent = extent;
    p.op = std::make_unique<PseRpy>(Geometry::periodic(c.box[0], c.box[1], c.box[2]), viscosity, c.options);
    p.box = c.box;
    p.constant = 1.0 / (4.0 * std::numbers::pi * viscosity * c.options.open_truncation);
    plans.push_back(std::move(p));
    times["plan"] += sw.seconds();
    return plans.size() - 1;
  }

  /// Drops the least recently used plans other than `keep` beyond the cache's limits; returns
  /// keep's new index.
  std::size_t evict(std::size_t keep) {
    auto over = [&]() {
      if (plans.size() > kCachedPlans) return true;
      std::size_t bytes = 0;
      for (std::size_t i = 0; i < plans.size(); ++i)
        if (i != keep) bytes += plans[i].bytes();  // every kept plan has had its positions set
      return bytes > kCachedBytes;
    };
    while (plans.size() > 1 && over()) {
      std::size_t oldest = keep == 0 ? 1 : 0;
      for (std::size_t i = 0; i < plans.size(); ++i)
        if (i != keep && plans[i].last_used < plans[oldest].last_used) oldest = i;
      add_times(times, plans[oldest].op->stage_times());
      plans.erase(plans.begin() + static_cast<std::ptrdiff_t>(oldest));
      if (oldest < keep) --keep;
    }
    return keep;
  }

  /// velocities_k += c sum_i F_i (the constant part's product), for each of nrhs vectors.
  void add_constant_product(const double* forces, double* velocities, std::size_t n, std::size_t nrhs) const {
    const double c = constant();
    for (std::size_t r = 0; r < nrhs; ++r) {
      const double* f = forces + r * 3 * n;
      double* u = velocities + r * 3 * n;
      double total[3] = {0.0, 0.0, 0.0};
      for (std::size_t i = 0; i < n; ++i)
        for (int d = 0; d < 3; ++d) total[d] += f[3 * i + d];
      for (std::size_t i = 0; i < n; ++i)
        for (int d = 0; d < 3; ++d) u[3 * i + d] += c * total[d];
    }
  }

  /// w += scale sqrt(c) zeta on every particle, zeta = normal3(seed, step, stream 6, 0).
  void add_constant_noise(std::uint64_t seed, std::uint64_t step, double scale, double* w, std::size_t n) const {
    double zeta[3];
    normal3(seed, step, detail::kStreamOpenOffset, 0, zeta);
    const double amplitude = scale * std::sqrt(constant());
    for (std::size_t i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d) w[3 * i + d] += amplitude * zeta[d];
  }
};

OpenPseRpy::OpenPseRpy(double viscosity, const PseOptions& options)
    : PseOperator(Geometry::open(), viscosity, kWhere), impl_(std::make_unique<Impl>()) {
  if (!(std::isfinite(options.tolerance) && options.tolerance >= 1e-8 && options.tolerance < 0.1)) {
    fail(ErrorCode::invalid_argument, kWhere,
         "tolerance must lie in [1e-8, 0.1), got " + format_number(options.tolerance));
  }
  require(std::isfinite(options.xi) && options.xi >= 0.0, ErrorCode::invalid_argument, kWhere,
          "xi must be >= 0 (0 = automatic), got " + format_number(options.xi));
  require(options.open_truncation == 0.0 && options.pair_density == 0.0, ErrorCode::invalid_argument, kWhere,
          "PseOptions::open_truncation and pair_density are chosen by OpenPseRpy and must be 0");
  require(options.grid == std::array<int, 3>{0, 0, 0}, ErrorCode::invalid_argument, kWhere,
          "a grid override does not fit open boundaries (the box follows the particles); leave PseOptions::grid 0");
  impl_->options = options;
}

OpenPseRpy::~OpenPseRpy() = default;

const PseOptions& OpenPseRpy::options() const {
  return impl_->options;
}

const PseParameters& OpenPseRpy::parameters() const {
  require_positions("parameters");
  return impl_->params;
}

std::array<double, 3> OpenPseRpy::box() const {
  require_positions("box");
  return impl_->plans[impl_->current].box;
}

double OpenPseRpy::constant_part() const {
  require_positions("constant_part");
  return impl_->constant();
}

void OpenPseRpy::on_positions_set() {
  require(equal_radii(), ErrorCode::not_supported, "OpenPseRpy::set_positions",
          "PSE supports equal radii only (the paper's assumption); the radii given differ");
  require_radius_in_range("OpenPseRpy::set_positions");
  auto& im = *impl_;
  const auto x = positions();
  std::array<double, 3> centre{};
  const Extent extent = measure(x, radii().front(), centre);
  // Coordinates whose distances overflow (particles at -1e308 and 1e308) have no grid; the
  // periodic box's checks named the open truncation instead.
  require(std::isfinite(extent.diameter), ErrorCode::out_of_memory, "OpenPseRpy::set_positions",
          "the particles' distances overflow double precision, so no grid covers them: use the FMM operator "
          "for spread-out configurations");
  const std::size_t k = im.plan_for(extent, viscosity());
  StopWatch sw;
  im.shifted.resize(x.size());
  for (int d = 0; d < 3; ++d) im.shift[d] = 0.5 * im.plans[k].box[d] - centre[d];
  for (std::size_t i = 0; i < x.size(); ++i) im.shifted[i] = x[i] + im.shift[i % 3];
  im.times["shift"] += sw.seconds();
  try {
    im.plans[k].op->set_positions(im.shifted, radii().front());
  } catch (...) {
    add_times(im.times, im.plans[k].op->stage_times());
    im.plans.erase(im.plans.begin() + static_cast<std::ptrdiff_t>(k));  // unusable: chosen again next time
    throw;
  }
  im.plans[k].last_used = ++im.uses;
  im.current = im.evict(k);
  im.params = im.inner().parameters();
  im.params.xi_automatic = im.options.xi == 0.0;
}

void OpenPseRpy::do_apply(const double* forces, double* velocities, std::size_t nrhs) const {
  const std::size_t n3 = 3 * size();
  auto& im = *impl_;
  im.inner().apply_block({forces, n3 * nrhs}, {velocities, n3 * nrhs}, nrhs);
  im.add_constant_product(forces, velocities, size(), nrhs);
}

SqrtReport OpenPseRpy::do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                     const SqrtOptions& options) const {
  if (options.method != SqrtMethod::automatic && options.method != SqrtMethod::split) {
    return MobilityOperator::do_apply_sqrt(z, w, nrhs, options);  // generic solvers on the full M
  }
  auto& im = *impl_;
  SqrtReport rep = im.inner().apply_sqrt_block(z, w, nrhs, options);
  const std::size_t n3 = 3 * size();
  for (std::size_t r = 0; r < nrhs; ++r)
    im.add_constant_noise(noise_hash(z.subspan(r * n3, n3)), 0, 1.0, w.data() + r * n3, size());
  return rep;
}

void OpenPseRpy::do_apply_rotation(const double* forces, const double* torques, double* velocities,
                                   double* angular_velocities) const {
  const std::size_t n3 = 3 * size();
  auto& im = *impl_;
  im.inner().apply({forces, n3}, {torques, n3}, {velocities, n3}, {angular_velocities, n3});
  im.add_constant_product(forces, velocities, size(), 1);  // the constant has no curl: U only
}

SqrtReport OpenPseRpy::do_apply_sqrt_rotation(std::span<const double> z_translation, std::span<const double> z_rotation,
                                              std::span<double> w_translation, std::span<double> w_rotation,
                                              const SqrtOptions& options) const {
  if (options.method != SqrtMethod::automatic && options.method != SqrtMethod::split) {
    return MobilityOperator::do_apply_sqrt_rotation(z_translation, z_rotation, w_translation, w_rotation, options);
  }
  auto& im = *impl_;
  SqrtReport rep = im.inner().apply_sqrt_rotation(z_translation, z_rotation, w_translation, w_rotation, options);
  std::vector<double> z(z_translation.begin(), z_translation.end());
  z.insert(z.end(), z_rotation.begin(), z_rotation.end());
  im.add_constant_noise(noise_hash(z), 0, 1.0, w_translation.data(), size());
  return rep;
}

SqrtReport OpenPseRpy::sample(std::uint64_t seed, std::uint64_t step, std::span<double> w) const {
  require_positions("sample");
  require_size(std::span<const double>(w.data(), w.size()), 3 * size(), "OpenPseRpy::sample", "output");
  auto& im = *impl_;
  SqrtReport rep = im.inner().sample(seed, step, w);
  im.add_constant_noise(seed, step, 1.0, w.data(), size());
  return rep;
}

SqrtReport OpenPseRpy::apply_with_noise(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                                        std::uint64_t step, std::span<double> velocities) const {
  require_positions("apply_with_noise");
  auto& im = *impl_;
  SqrtReport rep = im.inner().apply_with_noise(forces, noise_scale, seed, step, velocities);
  im.add_constant_product(forces.data(), velocities.data(), size(), 1);
  if (noise_scale > 0.0) im.add_constant_noise(seed, step, noise_scale, velocities.data(), size());
  return rep;
}

StageTimes OpenPseRpy::stage_times() const {
  StageTimes t = impl_->times;
  for (const auto& p : impl_->plans) add_times(t, p.op->stage_times());
  return t;
}

void OpenPseRpy::reset_stage_times() const {
  impl_->times.clear();
  for (const auto& p : impl_->plans) p.op->reset_stage_times();
}

}  // namespace rpyfmm::rpy::pse
