#include "rpyfmm/bd/integrator.hpp"

#include <atomic>
#include <cmath>
#include <limits>
#include <sstream>

#include "device/device_stepper.hpp"
#include "rpyfmm/bd/quaternion.hpp"
#include "rpyfmm/bd/rotation_sampling.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "thermal_energy.hpp"

namespace rpyfmm::bd {

namespace {
NeighbourList make_list(const rpy::MobilityOperator* m, const ForceField& f, const NeighbourOptions& o) {
  require(m != nullptr, ErrorCode::invalid_argument, "Integrator", "no mobility operator given");
  return NeighbourList(m->geometry(), f.max_cutoff(), o);
}

double norm3(const double* v) {
  return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}
}  // namespace

Integrator::Integrator(Unstarted, std::unique_ptr<rpy::MobilityOperator> mobility, ForceField forces,
                       IntegratorOptions options, std::vector<double> positions, std::vector<std::uint32_t> types,
                       const NeighbourOptions& neighbours, std::uint64_t first_step)
    : mobility_(std::move(mobility)),
      forces_(std::move(forces)),
      options_(options),
      x_(std::move(positions)),
      types_(std::move(types)),
      list_(make_list(mobility_.get(), forces_, neighbours)),
      step_(first_step) {
  const char* where = "Integrator";
  require_positive(options_.dt, where, "dt");
  require_thermal_energy(options_.kT, 2.0 * options_.kT * options_.dt, where, "2 kT dt");
  require_positive(options_.max_displacement, where, "max_displacement");
  const std::size_t n = types_.size();
  require(n >= 1, ErrorCode::invalid_input, where, "no particles (N = 0)");
  require(x_.size() == 3 * n, ErrorCode::invalid_input, where,
          "positions has " + std::to_string(x_.size()) + " entries, expected 3N = " + std::to_string(3 * n));
  require_finite(x_, where, "positions", 3);
  forces_.check(types_);
  // Each interaction kind lists its pairs within its own cut-off + skin (same forces, shorter rows).
  if (forces_.has_pairs()) list_.set_pair_cutoffs(types_, forces_.pair_cutoffs(), forces_.types().size());
  radii_.resize(n);
  for (std::size_t i = 0; i < n; ++i) radii_[i] = forces_.types()[types_[i]].radius;
  for (const char* part : {"neighbours", "forces", "plan", "drift", "sqrt", "update"}) totals_.seconds[part] = 0.0;
}

Integrator::Integrator(std::unique_ptr<rpy::MobilityOperator> mobility, ForceField forces, IntegratorOptions options,
                       std::vector<double> positions, std::vector<std::uint32_t> types, NeighbourOptions neighbours,
                       std::uint64_t first_step, std::vector<double> orientations, std::vector<double> velocities)
    : Integrator(Unstarted{}, std::move(mobility), std::move(forces), options, std::move(positions), std::move(types),
                 neighbours, first_step) {
  require(options_.engine != StepEngine::external, ErrorCode::invalid_argument, "Integrator",
          "StepEngine::external needs the constructor that takes the engine");
  if (options_.engine == StepEngine::cpu)
    start_cpu_engine(std::move(orientations), std::move(velocities));
  else
    start_device_engine(neighbours, !orientations.empty(), !velocities.empty());
}

Integrator::Integrator(std::unique_ptr<rpy::MobilityOperator> mobility, ForceField forces, IntegratorOptions options,
                       std::vector<double> positions, std::vector<std::uint32_t> types, NeighbourOptions neighbours,
                       std::uint64_t first_step, std::unique_ptr<Stepper> engine)
    : Integrator(Unstarted{}, std::move(mobility), std::move(forces), options, std::move(positions), std::move(types),
                 neighbours, first_step) {
  const char* where = "Integrator";
  require(options_.engine == StepEngine::external, ErrorCode::invalid_argument, where,
          "an engine given to the Integrator needs options.engine = StepEngine::external");
  require(engine != nullptr, ErrorCode::invalid_argument, where, "no engine given");
  // An engine across processes may hold the positions on one process alone (Stepper::positions).
  const std::size_t held = engine->positions().size();
  require(engine->step_count() == step_ && (held == x_.size() || held == 0), ErrorCode::invalid_argument, where,
          "the engine given holds other particles or another step than the Integrator's");
  device_ = std::move(engine);
  std::vector<double>().swap(x_);  // the engine holds the positions
}

Integrator::Integrator(Integrator&&) noexcept = default;
Integrator& Integrator::operator=(Integrator&&) noexcept = default;
Integrator::~Integrator() = default;

void Integrator::start_cpu_engine(std::vector<double> orientations, std::vector<double> velocities) {
  const char* where = "Integrator";
  const std::size_t n = types_.size();
  f_.assign(3 * n, 0.0);
  u_.assign(3 * n, 0.0);
  w_.assign(3 * n, 0.0);
  dx_.assign(3 * n, 0.0);
  if (options_.kT > 0.0) z_.assign(3 * n, 0.0);
  if (options_.rotation) {
    require(mobility_->supports_rotation(), ErrorCode::invalid_argument, where,
            "rotation needs a mobility that supports it (torques and angular velocities); '" + mobility_->name() +
                "' does not (docs/bd-config.md, system.rotation)");
    q_ = quaternion::checked(std::move(orientations), n, where, "particle");
    for (auto* v : {&torque_, &omega_, &phi_}) v->assign(3 * n, 0.0);
    if (options_.kT > 0.0) {
      zr_.assign(3 * n, 0.0);
      wr_.assign(3 * n, 0.0);
    }
  } else {
    require(orientations.empty(), ErrorCode::invalid_argument, where, "orientations given but rotation is off");
  }
  inertial_ = LangevinGroup(options_.inertia, types_);
  if (!inertial_.empty()) {
    check_inertia();
    inertial_.set_velocities(std::move(velocities), options_.kT, options_.seed);
  } else {
    require(velocities.empty(), ErrorCode::invalid_argument, where, "velocities given but no particle is inertial");
  }
  if (options_.sac.enabled) {
    require(!inertial_.empty(), ErrorCode::invalid_argument, where,
            "the SAC scheme (integrator.scheme = \"sac\") needs carriers, particles of a Langevin type; "
            "none of the particles has one");
    require(forces_.bonds().empty(), ErrorCode::invalid_argument, where, "the SAC scheme does not support bonds");
    // Its own list, always with the dynamic rebuild test (a fixed interval could miss adsorptions).
    complexes_ =
        Complexes(mobility_->geometry(), forces_.types(), options_.inertia, types_, options_.sac.adsorption_factor);
    complexes_.update(x_);
    groups_.assign(n, 0);
    f_within_.assign(3 * n, 0.0);
  }
}

void Integrator::check_inertia() const {
  const char* where = "Integrator";
  require(mobility_->name() == "none", ErrorCode::invalid_argument, where,
          "inertial (Langevin) particles need the free-draining mobility \"none\", not '" + mobility_->name() +
              "': hydrodynamic interactions with inertia are not supported");
  require(!options_.rotation, ErrorCode::invalid_argument, where,
          "inertial (Langevin) particles do not support rotation yet");
  require(!options_.keep_split_displacements, ErrorCode::invalid_argument, where,
          "split displacements (M F dt and the Brownian part) do not apply to inertial (Langevin) particles");
}

double Integrator::complex_forces() {
  // Algorithm 2 of Tran et al. (2015) (Sec. 4.2) in the complexes' internal coordinates
  // (docs/theory/bd.md Sec. 9). Each particle's group is its complex (named by its carrier) or,
  // when free, itself. f_ = the forces from outside the group (pair forces across groups, external
  // forces, trap, callbacks), f_within_ = the pair forces inside the group, in one pass over the
  // neighbour list. Step 1 moves a complex, carrier position X_c, under -dU/dX_c at fixed relative
  // positions: the sum of its members' forces from outside. Step 2 moves an adsorbed particle's
  // position relative to its carrier, r_a = x_a - X_c, under -dU/dr_a at fixed X_c: the whole
  // force on it. The paper evaluates step 2 after step 1 has moved the complexes; step 1
  // translates each complex rigidly, so the forces inside a complex are those at the start of the
  // step, and the forces from outside differ by the complexes' relative motion only, O(dt).
  const std::size_t n = size();
  const auto owner = complexes_.owner();
  for (std::size_t i = 0; i < n; ++i)
    groups_[i] = owner[i] == Complexes::kFree ? static_cast<std::uint32_t>(i) : owner[i];
  const double energy = forces_.compute(x_, types_, list_, step_, f_, groups_, f_within_);
  // A complex's force: the sum over its members (carrier first, then adsorbed particles in
  // ascending order: a fixed summation order). The forces between members cancel in the sum
  // (Newton's third law) and are left out; the carrier does not feel its adsorbed particles.
  const auto count = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(dynamic, 64) if (count >= 4096)
  for (std::int64_t cc = 0; cc < count; ++cc) {
    const auto c = static_cast<std::size_t>(cc);
    for (std::uint32_t a : complexes_.adsorbed(c))
      for (std::size_t k = 0; k < 3; ++k) f_[3 * c + k] += f_[3 * a + k];
  }
  // Adsorbed particles move relative to their carrier under the whole force on them.
#pragma omp parallel for schedule(static) if (count >= 4096)
  for (std::int64_t ii = 0; ii < count; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    if (owner[i] != Complexes::kFree && owner[i] != i)
      for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) f_[k] += f_within_[k];
  }
  return energy;
}

void Integrator::drift_and_noise_products(StepReport& rep, bool fused, bool brownian, double noise) {
  const double dt = options_.dt;
  StopWatch watch;
  if (brownian) rpy::fill_normal(z_, options_.seed, step_);
  if (brownian && options_.rotation) rpy::fill_normal(zr_, options_.seed, step_, kRotationNoiseStream);
  const double noise_seconds = watch.seconds();
  const DriftNoiseReport dn =
      options_.rotation ? rotational_products(brownian)
      : fused           ? fused_drift_and_noise(*mobility_, f_, noise / dt, options_.seed, step_, u_, options_.sqrt)
                        : drift_and_noise(*mobility_, f_, z_, u_, w_, options_.sqrt);
  totals_.seconds["drift"] += dn.seconds_drift;
  totals_.seconds["sqrt"] += dn.seconds_sqrt + noise_seconds;  // drawing z counts as Brownian work
  rep.sqrt_iterations = dn.sqrt.iterations;
  rep.preconditioner_blocks = dn.sqrt.preconditioner_blocks;
  rep.mobility_products = dn.mobility_products;
  rep.shared_first_product = dn.shared_first_product;
}

DriftNoiseReport Integrator::rotational_products(bool brownian) {
  // z_t keeps the draws of a step without rotation; z_r has its own stream (rotation_sampling.hpp).
  const std::span<const double> zt = brownian ? std::span<const double>(z_) : std::span<const double>();
  return rotational_drift_and_noise(*mobility_, {f_, torque_}, {zt, zr_}, {u_, omega_}, {w_, wr_}, options_.sqrt);
}

void Integrator::checked_displacements(double dt, double noise, bool brownian) {
  const std::size_t n = size();
  constexpr std::size_t none = std::numeric_limits<std::size_t>::max();
  std::atomic<std::size_t> bad{none};
  const double frac2 = options_.max_displacement * options_.max_displacement;
  const bool rotation = options_.rotation;
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (std::size_t i = 0; i < n; ++i) {
    double d2 = 0.0, turn2 = 0.0;
    // x + dx overflows: the next step would meet infinite positions.
    bool escapes = false;
    const bool inertial = inertial_.contains(i);  // dx_ holds its Langevin step already
    for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
      const double d = inertial ? dx_[k] : u_[k] * dt + (brownian ? noise * w_[k] : 0.0);
      dx_[k] = d;
      d2 += d * d;
      escapes = escapes || !std::isfinite(x_[k] + d);
      if (!rotation) continue;
      phi_[k] = omega_[k] * dt + (brownian ? noise * wr_[k] : 0.0);
      turn2 += phi_[k] * phi_[k];
    }
    if (!(d2 <= frac2 * radii_[i] * radii_[i]) || !(turn2 <= frac2) || escapes) {  // also catches NaN
      std::size_t cur = bad.load(std::memory_order_relaxed);
      while (i < cur && !bad.compare_exchange_weak(cur, i, std::memory_order_relaxed)) {
      }
    }
  }
  if (bad.load() != none) fail_blow_up(bad.load());
}

void Integrator::fail_blow_up(std::size_t i) const {
  const double* dx = dx_.data() + 3 * i;
  const double d = norm3(dx);
  std::ostringstream msg;
  msg << "blow-up at step " << step_ << ": particle " << i;
  const double* x = x_.data() + 3 * i;
  if (!std::isfinite(x[0] + dx[0]) || !std::isfinite(x[1] + dx[1]) || !std::isfinite(x[2] + dx[2])) {
    msg << " at (" << x[0] << ", " << x[1] << ", " << x[2] << ") would move by " << d
        << " beyond the largest double (|force| = " << norm3(f_.data() + 3 * i) << ")";
  } else if (!q_.empty() && !(norm3(phi_.data() + 3 * i) <= options_.max_displacement) &&
             d <= options_.max_displacement * radii_[i]) {
    msg << " would turn by " << norm3(phi_.data() + 3 * i) << " rad > max_displacement (" << options_.max_displacement
        << ") in one step (|torque| = " << norm3(torque_.data() + 3 * i) << ")";
  } else {
    msg << " would move " << d << " > max_displacement (" << options_.max_displacement << ") x radius " << radii_[i]
        << " in one step (|force| = " << norm3(f_.data() + 3 * i) << ")";
  }
  msg << "; reduce dt or check the forces. State kept at the last good step";
  fail(ErrorCode::numerical_failure, "bd", msg.str());
}

const StepReport& Integrator::step() {
  // The noise is keyed by the step number: past 2^64 - 1 it would wrap to 0 and repeat the noise
  // of step 0 on (a first_step near the end of the range, e.g. from a restart).
  require(step_ != std::numeric_limits<std::uint64_t>::max(), ErrorCode::invalid_input, "Integrator::step",
          "the step counter is at 2^64-1, its largest value (the next step would wrap to 0 and repeat its noise)");
  if (device_) return device_step();
  const std::size_t n = size();
  StepReport rep;
  StopWatch watch;
  // 1. Neighbour list, rebuilt only when needed (Tran et al. (2015), Algorithm 1;
  //    docs/theory/bd.md).
  rep.neighbour_rebuild = list_.update(x_);
  totals_.seconds["neighbours"] += watch.seconds();
  watch.restart();
  // 2. Forces.
  rep.potential_energy = complexes_.empty() ? forces_.compute(x_, types_, list_, step_, f_) : complex_forces();
  if (options_.rotation) rep.potential_energy += forces_.torque_field().compute(q_, types_, torque_);
  totals_.seconds["forces"] += watch.seconds();
  watch.restart();
  // 3. Mobility plan, built once per step.
  mobility_->set_positions(x_, radii_);
  totals_.seconds["plan"] += watch.seconds();
  // 4. u = M F and w = M^{1/2} z (docs/theory/bd.md), z keyed by (seed, step, particle).
  const double dt = options_.dt;
  const double noise = std::sqrt(2.0 * options_.kT * dt);
  // PSE: u = M F + (noise / dt) M^{1/2} z in one pass whose wave-space parts share their FFTs
  // (w = 0 then), unless the drift and Brownian parts are asked for separately.
  const bool fused = options_.kT > 0.0 && !options_.keep_split_displacements && !options_.rotation &&
                     fuses_drift_and_noise(*mobility_, options_.sqrt);
  const bool brownian = options_.kT > 0.0 && !fused;
  drift_and_noise_products(rep, fused, brownian, noise);
  watch.restart();
  // 5. dx = M F dt + sqrt(2 kT dt) M^{1/2} z (with rotation also phi = W dt + sqrt(2 kT dt) w_r;
  //    for inertial particles the Langevin step from the same F_n, langevin.hpp), then the
  //    blow-up guard.
  if (!inertial_.empty())
    inertial_.displacements({.dt = dt, .kT = options_.kT, .seed = options_.seed, .step = step_}, f_, dx_);
  checked_displacements(dt, noise, brownian);
  inertial_.commit();
  if (!complexes_.empty()) {  // SAC: adsorbed particles also take their carrier's displacement
    const auto owner = complexes_.owner();
#pragma omp parallel for schedule(static) if (n >= 4096)
    for (std::size_t i = 0; i < n; ++i)
      if (owner[i] != Complexes::kFree && owner[i] != i)
        for (std::size_t k = 0; k < 3; ++k) dx_[3 * i + k] += dx_[3 * owner[i] + k];
  }
  if (options_.keep_split_displacements) {
    dx_det_.resize(3 * n);
    dx_brown_.resize(3 * n);
    for (std::size_t k = 0; k < 3 * n; ++k) {
      dx_det_[k] = u_[k] * dt;
      dx_brown_[k] = brownian ? noise * w_[k] : 0.0;
    }
  }
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (std::size_t k = 0; k < 3 * n; ++k) x_[k] += dx_[k];
  if (options_.rotation) {
#pragma omp parallel for schedule(static) if (n >= 4096)
    for (std::size_t i = 0; i < n; ++i) quaternion::rotate(std::span<double, 4>(q_.data() + 4 * i, 4), &phi_[3 * i]);
  }
  ++step_;
  totals_.seconds["update"] += watch.seconds();
  if (!complexes_.empty()) {  // the membership of the new positions (that of the next step)
    watch.restart();
    complexes_.update(x_);
    totals_.seconds["neighbours"] += watch.seconds();
  }
  ++totals_.steps;
  totals_.sqrt_iterations += static_cast<std::uint64_t>(rep.sqrt_iterations);
  totals_.mobility_products += static_cast<std::uint64_t>(rep.mobility_products);
  report_ = rep;
  return report_;
}

void Integrator::run(std::uint64_t count) {
  for (std::uint64_t k = 0; k < count; ++k) step();
}

}  // namespace rpyfmm::bd
