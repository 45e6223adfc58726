#include "rpyfmm/bd/sampling.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"

namespace rpyfmm::bd {

SqrtReport brownian_displacement(const rpy::MobilityOperator& mobility, double kT, double dt, std::uint64_t seed,
                                 std::uint64_t step, std::span<double> displacement, const SqrtOptions& options) {
  require_positive(kT, "brownian_displacement", "kT");
  require_positive(dt, "brownian_displacement", "dt");
  std::vector<double> z(3 * mobility.size());
  rpy::fill_normal(z, seed, step);
  const SqrtReport report = mobility.apply_sqrt(z, displacement, options);
  const double scale = std::sqrt(2.0 * kT * dt);
  for (double& d : displacement) d *= scale;
  return report;
}

bool samples_by_lanczos(const rpy::MobilityOperator& mobility, const SqrtOptions& options) {
  return options.method == SqrtMethod::lanczos ||
         (options.method == SqrtMethod::automatic && mobility.native_sampler() == SqrtMethod::lanczos);
}

namespace {

bool all_zero(std::span<const double> forces) {
  return std::all_of(forces.begin(), forces.end(), [](double f) { return f == 0.0; });
}

/// u = M F, or zeros without a product when every force is zero. Returns the products made.
int drift(const rpy::MobilityOperator& mobility, std::span<const double> forces, bool zero_force, std::span<double> u) {
  if (zero_force) {
    std::fill(u.begin(), u.end(), 0.0);
    return 0;
  }
  mobility.apply(forces, u);
  return 1;
}

/// u = M F, then w = M^{1/2} z by the operator's own sampler (z may be empty: no sample).
DriftNoiseReport drift_then_sample(const rpy::MobilityOperator& mobility, std::span<const double> forces,
                                   bool zero_force, std::span<const double> z, std::span<double> u, std::span<double> w,
                                   const SqrtOptions& options) {
  DriftNoiseReport report;
  StopWatch watch;
  report.mobility_products = drift(mobility, forces, zero_force, u);
  report.seconds_drift = watch.seconds();
  if (z.empty()) return report;
  watch.restart();
  report.sqrt = mobility.apply_sqrt(z, w, options);
  report.mobility_products += report.sqrt.operator_applications;
  report.seconds_sqrt = watch.seconds();
  return report;
}

/// Lanczos on A = M, or on A = G M G^T with the block preconditioner (w = G^{-1} A^{1/2} z;
/// rpyfmm/rpy/block_preconditioner.hpp). One block pass M [F, G^T z] gives the drift u = M F and
/// A z, which the sampler takes as its first product (docs/theory/bd.md, docs/theory/samplers.md).
DriftNoiseReport drift_and_lanczos_in_one_pass(const rpy::MobilityOperator& mobility, std::span<const double> forces,
                                               std::span<const double> z, std::span<double> u, std::span<double> w,
                                               const SqrtOptions& options) {
  const std::size_t n3 = 3 * mobility.size();
  const auto n3d = static_cast<std::ptrdiff_t>(n3);
  DriftNoiseReport report;
  StopWatch watch;
  std::optional<rpy::BlockPreconditioner> preconditioner;
  if (options.preconditioner != rpy::SqrtPreconditioner::none) preconditioner.emplace(mobility, options);
  std::vector<double> rhs(2 * n3), out(2 * n3);
  std::copy(forces.begin(), forces.end(), rhs.begin());
  std::copy(z.begin(), z.end(), rhs.begin() + n3d);
  if (preconditioner) preconditioner->apply_g_transpose(rhs.data() + n3);
  mobility.apply_block(rhs, out, 2);
  std::copy(out.begin(), out.begin() + n3d, u.begin());
  report.seconds_drift = watch.seconds();
  watch.restart();
  const std::span<double> az(out.data() + n3, n3);  // A z
  if (preconditioner) preconditioner->apply_g(az.data());
  const rpy::LinearOperatorView a =
      preconditioner ? preconditioner->precondition(mobility.as_linear_operator()) : mobility.as_linear_operator();
  SqrtOptions resolved = options;
  resolved.method = SqrtMethod::lanczos;
  resolved.preconditioner = rpy::SqrtPreconditioner::none;  // applied here, around the solver
  report.sqrt = rpy::sqrt_apply(a, z, w, 1, resolved, az);
  if (preconditioner) {
    preconditioner->solve_g(w.data());
    report.sqrt.preconditioner_blocks = preconditioner->blocks();
  }
  report.mobility_products = 1 + report.sqrt.operator_applications;
  report.shared_first_product = report.sqrt.iterations > 0;  // z = 0 needs no Lanczos product
  report.seconds_sqrt = watch.seconds();
  return report;
}

}  // namespace

DriftNoiseReport drift_and_noise(const rpy::MobilityOperator& mobility, std::span<const double> forces,
                                 std::span<const double> z, std::span<double> u, std::span<double> w,
                                 const SqrtOptions& options) {
  const std::size_t n3 = 3 * mobility.size();
  require(forces.size() == n3 && u.size() == n3 && (z.empty() || (z.size() == n3 && w.size() == n3)),
          ErrorCode::invalid_input, "drift_and_noise", "forces, noise and outputs must have 3N entries");
  const bool zero_force = all_zero(forces);
  if (z.empty() || zero_force || !samples_by_lanczos(mobility, options)) {
    return drift_then_sample(mobility, forces, zero_force, z, u, w, options);
  }
  return drift_and_lanczos_in_one_pass(mobility, forces, z, u, w, options);
}

bool fuses_drift_and_noise(const rpy::MobilityOperator& mobility, const SqrtOptions& options) {
  const bool split = options.method == SqrtMethod::automatic || options.method == SqrtMethod::split;
  return split && mobility.fuses_drift_and_noise();
}

DriftNoiseReport fused_drift_and_noise(const rpy::MobilityOperator& mobility, std::span<const double> forces,
                                       double noise_scale, std::uint64_t seed, std::uint64_t step, std::span<double> v,
                                       const SqrtOptions& options) {
  require(fuses_drift_and_noise(mobility, options), ErrorCode::not_supported, "fused_drift_and_noise",
          "operator '" + mobility.name() + "' has no fused drift-and-noise pass (use drift_and_noise)");
  DriftNoiseReport report;
  StopWatch watch;
  report.sqrt = mobility.apply_with_noise(forces, noise_scale, seed, step, v);
  report.mobility_products = report.sqrt.operator_applications;
  report.seconds_drift = watch.seconds();  // one pass: drift and noise are not timed apart
  return report;
}

}  // namespace rpyfmm::bd
