// rpyfmm — MobilityOperator: validation (once, here) and generic fallbacks.
#include "rpyfmm/rpy/mobility.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>
#include <span>
#include <string>
#include <vector>

#include "load_scaling.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "wrap_into_box.hpp"

namespace rpyfmm::rpy {

using detail::load_scale_exponent;
using detail::require_finite_result;

namespace {

// The same for [F; T] (largest_rotation_load).
int rotation_load_scale_exponent(std::span<const double> forces, std::span<const double> torques,
                                 std::span<const double> radii) {
  double largest_radius = 0.0;
  for (double a : radii) largest_radius = std::max(largest_radius, a);
  const double largest = detail::largest_rotation_load(forces, torques, largest_radius);
  return load_scale_exponent({std::span<const double>(&largest, 1)});
}

/// One argument of a product or sample with rotation, by name.
struct NamedArray {
  const char* name;
  std::span<const double> values;
};

/// The two inputs and two outputs of a product or sample with rotation: n entries each, inputs finite.
void require_rotation_arguments(const std::string& where, std::size_t n, const std::array<NamedArray, 2>& inputs,
                                const std::array<NamedArray, 2>& outputs) {
  for (const NamedArray& a : inputs) require_size(a.values, n, where, a.name);
  for (const NamedArray& a : outputs) require_size(a.values, n, where, a.name);
  for (const NamedArray& a : inputs) require_finite(a.values, where, a.name, 3);
}

/// Whether the sampler in `options` (method already resolved) runs preconditioned. `block` serves
/// the Krylov samplers, Lanczos and Chebyshev, and is refused for the dense methods. `automatic`
/// means block for Lanczos, and for Chebyshev when its eigenvalue bounds are to be estimated
/// (bounds given in the options are M's, not those of the preconditioned G M G^T).
bool preconditioned(const SqrtOptions& options, const std::string& where) {
  const bool lanczos = options.method == SqrtMethod::lanczos;
  const bool chebyshev = options.method == SqrtMethod::chebyshev;
  switch (options.preconditioner) {
    case SqrtPreconditioner::none:
      return false;
    case SqrtPreconditioner::block:
      require(lanczos || chebyshev, ErrorCode::invalid_argument, where,
              std::string("the block preconditioner serves the Lanczos and Chebyshev samplers only, not ") +
                  to_string(options.method));
      return true;
    case SqrtPreconditioner::automatic:
      return lanczos || (chebyshev && options.lambda_min == 0.0 && options.lambda_max == 0.0);
  }
  return false;
}

// Multiplies column j (entries [j column, (j + 1) column)) of v by 2^(sign exponents[j]): exact
// unless it under- or overflows.
void scale_columns(std::span<double> v, std::size_t column, std::span<const int> exponents, int sign) {
  for (std::size_t j = 0; j < exponents.size(); ++j)
    for (double& x : v.subspan(j * column, column)) x = std::ldexp(x, sign * exponents[j]);
}

}  // namespace

MobilityOperator::MobilityOperator(Geometry geometry, double viscosity, const char* where)
    : geometry_(geometry), viscosity_(viscosity), where_(where) {
  require_positive(viscosity, where_, "viscosity");
}

void MobilityOperator::set_positions(std::span<const double> positions, double radius) {
  const std::string where = where_ + "::set_positions";
  require_positive(radius, where, "radius");
  require(positions.size() % 3 == 0, ErrorCode::invalid_input, where,
          "positions has " + std::to_string(positions.size()) + " entries, not a multiple of 3");
  store_positions(positions, std::span<const double>(&radius, 1), true);  // one radius for all
}

void MobilityOperator::set_positions(std::span<const double> positions, std::span<const double> radii) {
  const std::string where = where_ + "::set_positions";
  require(positions.size() % 3 == 0, ErrorCode::invalid_input, where,
          "positions has " + std::to_string(positions.size()) + " entries, not a multiple of 3");
  require_size(radii, positions.size() / 3, where, "radii");
  // As for one common radius: finite, > 0 and normal (a subnormal radius's mobility overflows).
  for (std::size_t i = 0; i < radii.size(); ++i)
    require_positive(radii[i], where, "radius of particle " + std::to_string(i));
  const bool equal = std::all_of(radii.begin(), radii.end(), [&](double a) { return a == radii.front(); });
  store_positions(positions, radii, equal);
}

void MobilityOperator::store_positions(std::span<const double> positions, std::span<const double> radii, bool equal) {
  const std::string where = where_ + "::set_positions";
  require(!positions.empty(), ErrorCode::invalid_input, where, "no particles (N = 0)");
  require_finite(positions, where, "positions", 3);
  positions_.assign(positions.begin(), positions.end());
  positions_moved_ = false;
  if (geometry_.is_periodic()) {
    // Into [0, L) per axis; most positions of a time step are inside already and stay bitwise.
    const auto& L = geometry_.box();
    const auto n = static_cast<long long>(positions_.size() / 3);
    double* x = positions_.data();
#pragma omp parallel for schedule(static) if (n > 100000)
    for (long long i = 0; i < n; ++i) {
      for (int d = 0; d < 3; ++d) x[3 * i + d] = detail::wrap_into_box(x[3 * i + d], L[d]);
    }
  }
  if (radii.size() == 1) {
    radii_.assign(positions.size() / 3, radii.front());
  } else {
    radii_.assign(radii.begin(), radii.end());
  }
  equal_radii_ = equal;
  try {
    on_positions_set();  // builds the plan: may throw (box too small, grid over memory, ...)
  } catch (...) {
    // No half-built plan may be used: the operator is unset until set_positions succeeds.
    positions_.clear();
    radii_.clear();
    throw;
  }
}

std::span<const double> MobilityOperator::positions() const {
  if (positions_moved_) {
    read_positions(positions_);
    positions_moved_ = false;
  }
  return positions_;
}

void MobilityOperator::read_positions(std::vector<double>&) const {
  fail(ErrorCode::not_supported, where_ + "::positions",
       "the operator marked its positions moved but cannot read them back");
}

void MobilityOperator::require_positions(const char* where) const {
  require(!radii_.empty(), ErrorCode::invalid_input, where_ + "::" + where,
          "positions not set (call set_positions first)");
}

void MobilityOperator::apply(std::span<const double> forces, std::span<double> velocities) const {
  apply_block(forces, velocities, 1);
}

void MobilityOperator::apply_block(std::span<const double> forces, std::span<double> velocities,
                                   std::size_t nrhs) const {
  require_positions("apply");
  const std::string where = where_ + "::apply";
  require(nrhs > 0, ErrorCode::invalid_argument, where, "number of right-hand sides must be > 0");
  const std::size_t n = 3 * size() * nrhs;
  require_size(forces, n, where, "forces");
  require_size(std::span<const double>(velocities.data(), velocities.size()), n, where, "velocities");
  require_finite(forces, where, "forces", 3);
  // Each right-hand side is scaled by its own power of two, as apply() scales it alone: a column of
  // loads near 1e-300 beside one near 1e300 keeps its digits instead of underflowing to zero.
  const std::size_t column = 3 * size();
  std::vector<int> exponents(nrhs);
  for (std::size_t j = 0; j < nrhs; ++j) exponents[j] = load_scale_exponent({forces.subspan(j * column, column)});
  if (std::ranges::all_of(exponents, [](int k) { return k == 0; })) {
    do_apply(forces.data(), velocities.data(), nrhs);
  } else {
    std::vector<double> scaled(forces.begin(), forces.end());
    scale_columns(scaled, column, exponents, -1);
    do_apply(scaled.data(), velocities.data(), nrhs);
    scale_columns(velocities, column, exponents, 1);
  }
  require_finite_result(velocities, where, "velocities", "forces");
}

void MobilityOperator::apply(std::span<const double> forces, std::span<const double> torques,
                             std::span<double> velocities, std::span<double> angular_velocities) const {
  require_positions("apply");
  const std::string where = where_ + "::apply";
  require(supports_rotation(), ErrorCode::not_supported, where,
          "operator '" + name() +
              "' has no rotational mobility (torques and angular velocities); use 'direct', 'fmm', 'pse' or 'none' "
              "(free draining)");
  require_rotation_arguments(where, 3 * size(), {{{"forces", forces}, {"torques", torques}}},
                             {{{"velocities", velocities}, {"angular velocities", angular_velocities}}});
  const int k = rotation_load_scale_exponent(forces, torques, radii());
  if (k == 0) {
    do_apply_rotation(forces.data(), torques.data(), velocities.data(), angular_velocities.data());
  } else {
    std::vector<double> f(forces.begin(), forces.end()), t(torques.begin(), torques.end());
    for (double& v : f) v = std::ldexp(v, -k);
    for (double& v : t) v = std::ldexp(v, -k);
    do_apply_rotation(f.data(), t.data(), velocities.data(), angular_velocities.data());
    for (double& v : velocities) v = std::ldexp(v, k);
    for (double& v : angular_velocities) v = std::ldexp(v, k);
  }
  require_finite_result(velocities, where, "velocities", "forces and torques");
  require_finite_result(angular_velocities, where, "angular velocities", "forces and torques");
}

void MobilityOperator::do_apply_rotation(const double*, const double*, double*, double*) const {
  fail(ErrorCode::not_supported, where_ + "::apply", "operator '" + name() + "' has no rotational mobility");
}

SqrtReport MobilityOperator::apply_sqrt(std::span<const double> z, std::span<double> w,
                                        const SqrtOptions& options) const {
  return apply_sqrt_block(z, w, 1, options);
}

SqrtReport MobilityOperator::apply_sqrt_block(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                              const SqrtOptions& options) const {
  require_positions("apply_sqrt");
  const std::string where = where_ + "::apply_sqrt";
  require(nrhs > 0, ErrorCode::invalid_argument, where, "number of right-hand sides must be > 0");
  const std::size_t n = 3 * size() * nrhs;
  require_size(z, n, where, "noise");
  require_size(std::span<const double>(w.data(), w.size()), n, where, "output");
  require_finite(z, where, "noise", 3);
  const SqrtReport report = do_apply_sqrt(z, w, nrhs, options);
  require_finite_result(w, where, "output", "noise");
  return report;
}

SqrtReport MobilityOperator::do_apply_sqrt(std::span<const double> z, std::span<double> w, std::size_t nrhs,
                                           const SqrtOptions& options) const {
  if (options.method == SqrtMethod::split) {
    fail(ErrorCode::not_supported, where_ + "::apply_sqrt", "the split sampler is only available for the PSE operator");
  }
  SqrtOptions resolved = options;
  if (resolved.method == SqrtMethod::automatic) resolved.method = SqrtMethod::lanczos;
  if (!preconditioned(resolved, where_ + "::apply_sqrt")) {
    resolved.preconditioner = SqrtPreconditioner::none;  // `automatic` where it does not apply
    return sqrt_apply(as_linear_operator(), z, w, nrhs, resolved);
  }
  const BlockPreconditioner preconditioner(*this, resolved);
  return preconditioner.sample(as_linear_operator(), z, w, nrhs, resolved);
}

SqrtReport MobilityOperator::apply_sqrt_rotation(std::span<const double> z_translation,
                                                 std::span<const double> z_rotation, std::span<double> w_translation,
                                                 std::span<double> w_rotation, const SqrtOptions& options) const {
  require_positions("apply_sqrt_rotation");
  const std::string where = where_ + "::apply_sqrt_rotation";
  require(supports_rotation(), ErrorCode::not_supported, where,
          "operator '" + name() + "' has no rotational mobility (torques and angular velocities) to sample");
  require_rotation_arguments(where, 3 * size(),
                             {{{"translational noise", z_translation}, {"rotational noise", z_rotation}}},
                             {{{"translational output", w_translation}, {"rotational output", w_rotation}}});
  const SqrtReport report = do_apply_sqrt_rotation(z_translation, z_rotation, w_translation, w_rotation, options);
  require_finite_result(w_translation, where, "translational output", "noise");
  require_finite_result(w_rotation, where, "rotational output", "noise");
  return report;
}

SqrtReport MobilityOperator::do_apply_sqrt_rotation(std::span<const double> z_translation,
                                                    std::span<const double> z_rotation, std::span<double> w_translation,
                                                    std::span<double> w_rotation, const SqrtOptions& options) const {
  const std::string where = where_ + "::apply_sqrt_rotation";
  if (options.method == SqrtMethod::split) {
    fail(ErrorCode::not_supported, where, "the split sampler is only available for the PSE operator's translations");
  }
  SqrtOptions resolved = options;
  if (resolved.method == SqrtMethod::automatic) resolved.method = SqrtMethod::lanczos;
  // w' = (S M S)^{1/2} z on z = [z_t; z_r], then [w_t; w_r] = S^{-1} w' (apply_sqrt_rotation).
  const std::size_t n = 3 * size();
  std::vector<double> z(2 * n), w(2 * n);
  std::copy(z_translation.begin(), z_translation.end(), z.begin());
  std::copy(z_rotation.begin(), z_rotation.end(), z.begin() + static_cast<std::ptrdiff_t>(n));
  const LinearOperatorView scaled = scaled_grand_operator();
  SqrtReport report;
  if (!preconditioned(resolved, where)) {
    resolved.preconditioner = SqrtPreconditioner::none;  // `automatic` where it does not apply
    report = sqrt_apply(scaled, z, w, 1, resolved);
  } else {
    const BlockPreconditioner preconditioner(*this, resolved, PreconditionedMatrix::scaled_grand);
    report = preconditioner.sample(scaled, z, w, 1, resolved);
  }
  const auto a = radii();
  for (std::size_t k = 0; k < n; ++k) {
    w_translation[k] = w[k];
    w_rotation[k] = w[n + k] / a[k / 3];
  }
  return report;
}

SqrtReport MobilityOperator::apply_with_noise(std::span<const double>, double, std::uint64_t, std::uint64_t,
                                              std::span<double>) const {
  fail(ErrorCode::not_supported, where_ + "::apply_with_noise",
       "operator '" + name() + "' has no fused drift-and-noise pass (compute M F and M^{1/2} z apart)");
}

void MobilityOperator::divergence(std::span<double> out) const {
  require_positions("divergence");
  require_size(std::span<const double>(out.data(), out.size()), 3 * size(), where_ + "::divergence", "output");
  std::fill(out.begin(), out.end(), 0.0);  // RPY is divergence-free (docs/theory/rpy.md)
}

std::vector<double> MobilityOperator::assemble_dense(std::size_t max_bytes) const {
  require_positions("assemble_dense");
  const std::size_t n = 3 * size();
  require(n * n * sizeof(double) <= max_bytes / 2, ErrorCode::out_of_memory, where_ + "::assemble_dense",
          "a dense matrix for N = " + std::to_string(size()) + " exceeds the memory limit");
  // Columns in blocks of unit vectors: one block product per 3N columns.
  std::vector<double> unit(n * n, 0.0);
  for (std::size_t j = 0; j < n; ++j) unit[j * n + j] = 1.0;
  std::vector<double> cols(n * n);
  do_apply(unit.data(), cols.data(), n);
  std::vector<double> dense(n * n);
  for (std::size_t j = 0; j < n; ++j)
    for (std::size_t i = 0; i < n; ++i) dense[i * n + j] = cols[j * n + i];
  return dense;
}

LinearOperatorView MobilityOperator::as_linear_operator() const {
  LinearOperatorView view;
  view.n = 3 * size();
  view.apply = [this](std::span<const double> x, std::span<double> y, std::size_t nrhs) {
    do_apply(x.data(), y.data(), nrhs);
  };
  return view;
}

LinearOperatorView MobilityOperator::scaled_grand_operator() const {
  LinearOperatorView view;
  const std::size_t n = 3 * size();
  view.n = 2 * n;
  view.apply = [this, n](std::span<const double> x, std::span<double> y, std::size_t nrhs) {
    const auto a = radii();
    std::vector<double> torques(n);
    for (std::size_t r = 0; r < nrhs; ++r) {
      const double* xr = x.data() + 2 * n * r;
      double* yr = y.data() + 2 * n * r;
      for (std::size_t k = 0; k < n; ++k) torques[k] = a[k / 3] * xr[n + k];  // S x
      do_apply_rotation(xr, torques.data(), yr, yr + n);                      // M S x
      for (std::size_t k = 0; k < n; ++k) yr[n + k] *= a[k / 3];              // S M S x
    }
  };
  return view;
}

}  // namespace rpyfmm::rpy
