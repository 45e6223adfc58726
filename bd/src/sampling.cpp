#include "rpyfmm/bd/sampling.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/pse/pse_operator.hpp"

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
  if (options.method == SqrtMethod::lanczos) return true;
  if (options.method != SqrtMethod::automatic) return false;
  // Operators known to use the interface's default (Lanczos on products) for `automatic`.
  const std::string name = mobility.name();
  return name == "direct" || name == "fmm";
}

DriftNoiseReport drift_and_noise(const rpy::MobilityOperator& mobility, std::span<const double> forces,
                                 std::span<const double> z, std::span<double> u, std::span<double> w,
                                 const SqrtOptions& options) {
  const std::size_t n3 = 3 * mobility.size();
  require(forces.size() == n3 && u.size() == n3 && (z.empty() || (z.size() == n3 && w.size() == n3)),
          ErrorCode::invalid_input, "drift_and_noise", "forces, noise and outputs must have 3N entries");
  DriftNoiseReport report;
  const bool zero_force = std::all_of(forces.begin(), forces.end(), [](double f) { return f == 0.0; });
  StopWatch watch;
  if (z.empty()) {
    if (zero_force) {
      std::fill(u.begin(), u.end(), 0.0);
    } else {
      mobility.apply(forces, u);
      report.mobility_products = 1;
    }
    report.seconds_drift = watch.seconds();
    return report;
  }
  if (zero_force || !samples_by_lanczos(mobility, options)) {
    if (zero_force) {
      std::fill(u.begin(), u.end(), 0.0);
    } else {
      mobility.apply(forces, u);
      report.mobility_products = 1;
    }
    report.seconds_drift = watch.seconds();
    watch.restart();
    report.sqrt = mobility.apply_sqrt(z, w, options);
    report.mobility_products += report.sqrt.operator_applications;
    report.seconds_sqrt = watch.seconds();
    return report;
  }
  // Lanczos on A = M, or on A = G M G^T with the block preconditioner (w = G^{-1} A^{1/2} z;
  // rpyfmm/rpy/block_preconditioner.hpp). One block pass M [F, G^T z] gives the drift and the
  // first Krylov product A z (MATH.md §4: dx = M F dt + sqrt(2 kT dt) B z, B B^T = M).
  std::optional<rpy::BlockPreconditioner> preconditioner;
  if (options.preconditioner != rpy::SqrtPreconditioner::none) preconditioner.emplace(mobility, options);
  std::vector<double> rhs(2 * n3), out(2 * n3);
  std::copy(forces.begin(), forces.end(), rhs.begin());
  std::copy(z.begin(), z.end(), rhs.begin() + static_cast<std::ptrdiff_t>(n3));
  if (preconditioner) preconditioner->apply_g_transpose(rhs.data() + n3);
  mobility.apply_block(rhs, out, 2);
  std::copy(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(n3), u.begin());
  report.seconds_drift = watch.seconds();
  watch.restart();
  double* mz = out.data() + n3;  // A z
  if (preconditioner) preconditioner->apply_g(mz);
  double zz = 0.0;
  for (double v : z) zz += v * v;
  const rpy::LinearOperatorView base =
      preconditioner ? preconditioner->precondition(mobility.as_linear_operator()) : mobility.as_linear_operator();
  bool cached_available = zz > 0.0;
  int products = 0;
  int shared = 0;
  rpy::LinearOperatorView view;
  view.n = n3;
  view.apply = [&](std::span<const double> x, std::span<double> y, std::size_t nrhs) {
    if (cached_available && nrhs == 1) {
      cached_available = false;  // only the first product can be a multiple of z
      // Is x = c z? (Lanczos starts from z / |z|.) Sequential sums: bitwise reproducible.
      double xz = 0.0, xmax = 0.0;
      for (std::size_t i = 0; i < n3; ++i) {
        xz += x[i] * z[i];
        xmax = std::max(xmax, std::abs(x[i]));
      }
      const double c = xz / zz;
      double dev = 0.0;
      for (std::size_t i = 0; i < n3; ++i) dev = std::max(dev, std::abs(x[i] - c * z[i]));
      if (dev <= 1e-13 * xmax) {
        for (std::size_t i = 0; i < n3; ++i) y[i] = c * mz[i];
        shared = 1;
        return;
      }
    }
    base.apply(x, y, nrhs);
    ++products;
  };
  SqrtOptions resolved = options;
  resolved.method = SqrtMethod::lanczos;
  resolved.preconditioner = rpy::SqrtPreconditioner::none;  // applied here, around the solver
  report.sqrt = rpy::sqrt_apply(view, z, w, 1, resolved);
  if (preconditioner) {
    preconditioner->solve_g(w.data());
    report.sqrt.preconditioner_blocks = preconditioner->blocks();
  }
  report.mobility_products = 1 + products;
  report.shared_first_product = shared != 0;
  report.seconds_sqrt = watch.seconds();
  return report;
}

bool fuses_drift_and_noise(const rpy::MobilityOperator& mobility, const SqrtOptions& options) {
  const bool split = options.method == SqrtMethod::automatic || options.method == SqrtMethod::split;
  return split && dynamic_cast<const rpy::pse::PseOperator*>(&mobility) != nullptr;
}

DriftNoiseReport fused_drift_and_noise(const rpy::MobilityOperator& mobility, std::span<const double> forces,
                                       double noise_scale, std::uint64_t seed, std::uint64_t step,
                                       std::span<double> v, const SqrtOptions& options) {
  require(fuses_drift_and_noise(mobility, options), ErrorCode::not_supported, "fused_drift_and_noise",
          "operator '" + mobility.name() + "' has no fused drift-and-noise pass (use drift_and_noise)");
  DriftNoiseReport report;
  StopWatch watch;
  const auto& pse = dynamic_cast<const rpy::pse::PseOperator&>(mobility);
  report.sqrt = pse.apply_with_noise(forces, noise_scale, seed, step, v);
  report.mobility_products = report.sqrt.operator_applications;
  report.seconds_drift = watch.seconds();  // one pass: drift and noise are not timed apart
  return report;
}

}  // namespace rpyfmm::bd
