// rpyfmm — PseRpy: the CPU PSE operator (plan, products, split sampler).
#include "rpyfmm/rpy/pse/pse_rpy.hpp"

#include <algorithm>
#include <vector>

#include "noise_hash.hpp"
#include "real_space_sqrt.hpp"
#include "real_space_sum.hpp"
#include "rotation_real_space_sum.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "wave_space.hpp"

namespace rpyfmm::rpy::pse {

std::uint64_t noise_hash(std::span<const double> z) {
  // splitmix64 finaliser chained over the 64-bit patterns of z (noise_hash.hpp).
  return detail::noise_hash_extend(detail::noise_hash_start(z.size()), z);
}

namespace {

/// z1 = normal3(seed, step, stream 1, i) for every particle i (fill_normal, vectorized).
void real_noise(std::vector<double>& z, std::uint64_t seed, std::uint64_t step) {
  fill_normal(z, seed, step, detail::kStreamReal);
}

}  // namespace

struct PseRpy::Impl {
  PseOptions options;
  PseParameters params;
  bool planned = false;
  std::size_t planned_n = 0;
  std::unique_ptr<detail::RealSpaceSum> real;
  std::unique_ptr<detail::WaveSpace> wave;
  // The rotational real-space blocks: built on the first product with torques (their table).
  mutable std::unique_ptr<detail::RotationRealSpaceSum> rotation;
  mutable StageTimes times;

  const detail::RotationRealSpaceSum& rotation_sum(const std::array<double, 3>& box, double viscosity) const {
    if (!rotation) {
      StopWatch sw;
      rotation = std::make_unique<detail::RotationRealSpaceSum>(params, box, viscosity);
      times["plan"] += sw.seconds();
    }
    return *rotation;
  }

  /// y = M_r^{1/2} z (nrhs vectors in input order) by Lanczos on the real-space part ([PSE]
  /// Sec. II.B; docs/theory/pse.md, split sampler), iterated in slot order: z is permuted once, the products then
  /// need no gather from and scatter to input order (the Krylov result is the same up to
  /// round-off: Lanczos commutes with a permutation of the unknowns).
  SqrtReport real_sqrt(std::span<const double> z, std::span<double> y, std::size_t nrhs) const {
    const std::size_t n3 = z.size() / nrhs;
    std::vector<double> zs(z.size()), ys(z.size());
    for (std::size_t r = 0; r < nrhs; ++r) real->to_slots(z.data() + r * n3, zs.data() + r * n3);
    LinearOperatorView slots;
    slots.n = n3;
    slots.apply = [this](std::span<const double> x, std::span<double> out, std::size_t k) {
      real->apply_slots(x.data(), out.data(), k);
    };
    StopWatch sw;
    SqrtReport rep = sqrt_apply(slots, zs, ys, nrhs, detail::real_space_sqrt_options(params.lanczos_tolerance));
    times["lanczos"] += sw.seconds();
    for (std::size_t r = 0; r < nrhs; ++r) real->from_slots(ys.data() + r * n3, y.data() + r * n3);
    return rep;
  }
};

PseRpy::PseRpy(Geometry geometry, double viscosity, const PseOptions& options)
    : PseOperator(geometry, viscosity, "PseRpy"), impl_(std::make_unique<Impl>()) {
  require(geometry.is_periodic(), ErrorCode::not_supported, "PseRpy",
          "PSE needs a periodic box (Geometry::periodic); use the direct or FMM operator for open geometry");
  impl_->options = options;
  if (!(std::isfinite(options.tolerance) && options.tolerance >= 1e-8 && options.tolerance < 0.1)) {
    fail(ErrorCode::invalid_argument, "PseRpy",
         "tolerance must lie in [1e-8, 0.1), got " + format_number(options.tolerance));
  }
  require(std::isfinite(options.xi) && options.xi >= 0.0, ErrorCode::invalid_argument, "PseRpy",
          "xi must be >= 0 (0 = automatic), got " + format_number(options.xi));
}

PseRpy::~PseRpy() = default;

const PseOptions& PseRpy::options() const {
  return impl_->options;
}

const PseParameters& PseRpy::parameters() const {
  require_positions("parameters");
  return impl_->params;
}

void PseRpy::on_positions_set() {
  require(equal_radii(), ErrorCode::not_supported, "PseRpy::set_positions",
          "PSE supports equal radii only (the paper's assumption); the radii given differ");
  require_radius_in_range("PseRpy::set_positions");
  const double a = radii().front();
  const std::size_t n = size();
  auto& im = *impl_;
  const bool replan = !im.planned || im.params.radius != a || (im.options.xi == 0.0 && im.planned_n != n);
  if (replan) {
    StopWatch sw;
    im.planned = false;
    im.real.reset();
    im.wave.reset();
    im.rotation.reset();
    // All checks (box vs r_cut, window, memory) happen here, before any allocation.
    PseParameters p = choose_parameters(im.options, a, geometry().box(), n);
    // Pair cache (pair_cache.hpp): float with float wave grids, else double; within what the
    // memory limit leaves beside the grids.
    const auto cache = !im.options.real_space_cache ? detail::PairCache::off
                       : p.wave_single              ? detail::PairCache::single_precision
                                                    : detail::PairCache::double_precision;
    auto real = std::make_unique<detail::RealSpaceSum>(p, geometry().box(), viscosity(), im.options.real_space_table,
                                                       cache, im.options.max_memory_bytes - p.memory_bytes);
    p.table_dr = im.options.real_space_table ? real->table().dr() : 0.0;
    p.table_size = im.options.real_space_table ? real->table().size() : 0;
    auto wave =
        detail::make_wave_space(p, geometry().box(), viscosity(), im.options.fft_threads, im.options.fft_measure);
    im.params = p;
    im.real = std::move(real);
    im.wave = std::move(wave);
    im.planned = true;
    im.planned_n = n;
    im.times["plan"] += sw.seconds();
  }
  StopWatch sw;
  im.real->set_positions(positions());
  im.params.real_space_cache_bytes = im.real->cache_bytes();
  im.times["positions_real"] += sw.seconds();
  sw.restart();
  im.wave->set_positions(positions());
  im.times["positions_wave"] += sw.seconds();
}

void PseRpy::do_apply(const double* forces, double* velocities, std::size_t nrhs) const {
  const std::size_t n3 = 3 * size();
  auto& im = *impl_;
  for (std::size_t r = 0; r < nrhs; ++r)
    im.wave->apply(forces + r * n3, velocities + r * n3, false, nullptr, 0.0, &im.times);
  StopWatch sw;
  im.real->apply(forces, velocities, nrhs, true);
  im.times["real_space"] += sw.seconds();
}

void PseRpy::do_apply_rotation(const double* forces, const double* torques, double* velocities,
                               double* angular_velocities) const {
  auto& im = *impl_;
  im.wave->apply_rotation(forces, torques, velocities, angular_velocities, false, nullptr, 0.0, &im.times);
  StopWatch sw;
  im.real->apply(forces, velocities, 1, true);
  im.rotation_sum(geometry().box(), viscosity())
      .apply(im.real->slot_lists(), positions(), forces, torques, velocities, angular_velocities);
  im.times["real_space"] += sw.seconds();
}

SqrtReport PseRpy::do_apply_sqrt_rotation(std::span<const double> z_translation, std::span<const double> z_rotation,
                                          std::span<double> w_translation, std::span<double> w_rotation,
                                          const SqrtOptions& options) const {
  if (options.method != SqrtMethod::automatic && options.method != SqrtMethod::split) {
    return MobilityOperator::do_apply_sqrt_rotation(z_translation, z_rotation, w_translation, w_rotation, options);
  }
  require(options.preconditioner != SqrtPreconditioner::block, ErrorCode::invalid_argument,
          "PseRpy::apply_sqrt_rotation",
          "the block preconditioner serves the Lanczos and Chebyshev samplers only, not the split sampler");
  auto& im = *impl_;
  const std::size_t n3 = 3 * size();
  const double a = im.params.radius;
  const auto& rotation = im.rotation_sum(geometry().box(), viscosity());
  // Real part: Lanczos on S M_r S, S = diag(I, a I), then [w_t; w_r] = S^-1 (S M_r S)^{1/2} z.
  LinearOperatorView scaled;
  scaled.n = 2 * n3;
  std::vector<double> torques(n3);
  scaled.apply = [&](std::span<const double> x, std::span<double> y, std::size_t nrhs) {
    for (std::size_t r = 0; r < nrhs; ++r) {
      const double* xr = x.data() + r * 2 * n3;
      double* yr = y.data() + r * 2 * n3;
      for (std::size_t k = 0; k < n3; ++k) torques[k] = a * xr[n3 + k];
      std::fill(yr + n3, yr + 2 * n3, 0.0);
      im.real->apply(xr, yr, 1, false);
      rotation.apply(im.real->slot_lists(), positions(), xr, torques.data(), yr, yr + n3);
      for (std::size_t k = 0; k < n3; ++k) yr[n3 + k] *= a;
    }
  };
  std::vector<double> z(2 * n3), w(2 * n3);
  std::copy(z_translation.begin(), z_translation.end(), z.begin());
  std::copy(z_rotation.begin(), z_rotation.end(), z.begin() + static_cast<std::ptrdiff_t>(n3));
  StopWatch sw;
  SqrtReport rep = sqrt_apply(scaled, z, w, 1, detail::real_space_sqrt_options(im.params.lanczos_tolerance));
  im.times["lanczos"] += sw.seconds();
  for (std::size_t k = 0; k < n3; ++k) {
    w_translation[k] = w[k];
    w_rotation[k] = w[n3 + k] / a;
  }
  // Wave part: the translational noise field keyed by the hash of z (as apply_sqrt).
  const detail::NoiseKey key{noise_hash(z), 0};
  im.wave->apply_rotation(nullptr, nullptr, w_translation.data(), w_rotation.data(), true, &key, 1.0, &im.times);
  rep.method = SqrtMethod::split;
  rep.operator_applications += 1;
  return rep;
}

void PseRpy::apply_real(std::span<const double> forces, std::span<double> velocities) const {
  require_positions("apply_real");
  require_size(forces, 3 * size(), "PseRpy::apply_real", "forces");
  require_size(std::span<const double>(velocities.data(), velocities.size()), 3 * size(), "PseRpy::apply_real",
               "velocities");
  require_finite(forces, "PseRpy::apply_real", "forces", 3);
  impl_->real->apply(forces.data(), velocities.data(), 1, false);
}

void PseRpy::apply_wave(std::span<const double> forces, std::span<double> velocities) const {
  require_positions("apply_wave");
  require_size(forces, 3 * size(), "PseRpy::apply_wave", "forces");
  require_size(std::span<const double>(velocities.data(), velocities.size()), 3 * size(), "PseRpy::apply_wave",
               "velocities");
  require_finite(forces, "PseRpy::apply_wave", "forces", 3);
  impl_->wave->apply(forces.data(), velocities.data(), false, nullptr, 0.0, &impl_->times);
}

LinearOperatorView PseRpy::real_space_operator() const {
  require_positions("real_space_operator");
  LinearOperatorView v;
  v.n = 3 * size();
  v.apply = [this](std::span<const double> x, std::span<double> y, std::size_t nrhs) {
    impl_->real->apply(x.data(), y.data(), nrhs, false);
  };
  return v;
}

LinearOperatorView PseRpy::wave_space_operator() const {
  require_positions("wave_space_operator");
  LinearOperatorView v;
  v.n = 3 * size();
  v.apply = [this](std::span<const double> x, std::span<double> y, std::size_t nrhs) {
    const std::size_t n3 = 3 * size();
    for (std::size_t r = 0; r < nrhs; ++r)
      impl_->wave->apply(x.data() + r * n3, y.data() + r * n3, false, nullptr, 0.0, &impl_->times);
  };
  return v;
}

SqrtReport PseRpy::do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                 const SqrtOptions& options) const {
  if (options.method != SqrtMethod::automatic && options.method != SqrtMethod::split) {
    return MobilityOperator::do_apply_sqrt(z, w, nrhs, options);  // generic solvers on the full M
  }
  require(options.preconditioner != SqrtPreconditioner::block, ErrorCode::invalid_argument, "PseRpy::apply_sqrt",
          "the block preconditioner serves the Lanczos and Chebyshev samplers only, not the split sampler");
  auto& im = *impl_;
  SqrtReport rep = im.real_sqrt(z, w, nrhs);
  const std::size_t n3 = 3 * size();
  for (std::size_t r = 0; r < nrhs; ++r) {
    const detail::NoiseKey key{noise_hash(z.subspan(r * n3, n3)), 0};
    im.wave->apply(nullptr, w.data() + r * n3, true, &key, 1.0, &im.times);
  }
  rep.method = SqrtMethod::split;
  rep.operator_applications += 1;
  return rep;
}

SqrtReport PseRpy::sample(std::uint64_t seed, std::uint64_t step, std::span<double> w) const {
  require_positions("sample");
  require_size(std::span<const double>(w.data(), w.size()), 3 * size(), "PseRpy::sample", "output");
  auto& im = *impl_;
  std::vector<double> z1(3 * size());
  real_noise(z1, seed, step);
  SqrtReport rep = im.real_sqrt(z1, w, 1);
  const detail::NoiseKey key{seed, step};
  im.wave->apply(nullptr, w.data(), true, &key, 1.0, &im.times);
  rep.method = SqrtMethod::split;
  rep.operator_applications += 1;
  return rep;
}

SqrtReport PseRpy::apply_with_noise(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                                    std::uint64_t step, std::span<double> velocities) const {
  require_positions("apply_with_noise");
  const char* where = "PseRpy::apply_with_noise";
  require_size(forces, 3 * size(), where, "forces");
  require_size(std::span<const double>(velocities.data(), velocities.size()), 3 * size(), where, "velocities");
  require_finite(forces, where, "forces", 3);
  require(std::isfinite(noise_scale) && noise_scale >= 0.0, ErrorCode::invalid_argument, where,
          "noise_scale must be finite and >= 0, got " + format_number(noise_scale));
  auto& im = *impl_;
  SqrtReport rep;
  rep.method = SqrtMethod::split;
  std::vector<double> y;
  if (noise_scale > 0.0) {
    std::vector<double> z1(3 * size());
    real_noise(z1, seed, step);
    y.resize(3 * size());
    rep = im.real_sqrt(z1, y, 1);
    rep.method = SqrtMethod::split;
  }
  // One wave-space pass for M_w F + noise_scale M_w^{1/2} z2 (shared FFTs).
  const detail::NoiseKey key{seed, step};
  im.wave->apply(forces.data(), velocities.data(), false, noise_scale > 0.0 ? &key : nullptr, noise_scale, &im.times);
  StopWatch sw;
  im.real->apply(forces.data(), velocities.data(), 1, true);
  im.times["real_space"] += sw.seconds();
  for (std::size_t i = 0; i < y.size(); ++i) velocities[i] += noise_scale * y[i];
  rep.operator_applications += 1;
  return rep;
}

StageTimes PseRpy::stage_times() const {
  return impl_->times;
}
void PseRpy::reset_stage_times() const {
  impl_->times.clear();
}

}  // namespace rpyfmm::rpy::pse
