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
#include "fmm_laplace_accuracy.hpp"
#include "fmm_leaf_rules.hpp"
#include "fmm_near_field.hpp"
#include "length_units.hpp"
#include "near_schedule.hpp"
#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"

namespace rpyfmm::rpy {

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
  plan_ = options_.leaf_capacity > 0
              ? make_plan(options_.leaf_capacity, {})
              : make_plan(detail::default_leaf_capacity(eps), detail::fitted_grid_rule(eps, size()));
}

FmmRpy::Plan FmmRpy::make_plan(int leaf_capacity, const fmm::FittedGridRule& fitted_grid) const {
  const std::span<const double> a = unit_radii();
  // The Laplace FMM runs at the requested tolerance, with more plane-wave nodes and a higher order
  // just above each table's step (fmm_laplace_accuracy.hpp): the far field combines up to 7
  // outputs with partial cancellation (x_m E_k(F^m) - E_k(x.F)), which amplifies the table's own
  // error there (tests/rpy/test_fmm_force_dipoles.cpp and test_fmm_operator.cpp hold the contract).
  fmm::FmmOptions fo;
  const detail::LaplaceAccuracy accuracy = detail::laplace_accuracy_for(options_.tolerance);
  fo.tolerance = accuracy.tolerance;
  fo.order = accuracy.order;
  fo.planewave_nodes = accuracy.planewave_nodes;
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
  // enough leaves to keep every colour busy (fmm_near_field.hpp).
  plan.near_schedule = std::make_unique<detail::NearSchedule>(detail::near_schedule_for(plan.fmm->near_field(), true));
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

void FmmRpy::apply_near_field(const double* forces, double* velocities, std::size_t nrhs) const {
  // Unscaled, the exact input positions (the centred ones may be rounded); scaled, the exactly
  // translated and scaled ones of length_units.hpp.
  const std::span<const double> x = scale_exponent_ == 0 ? positions() : std::span<const double>(centered_);
  const detail::NearPoints points{
      plan_.fmm->near_field(), *plan_.near_schedule, x, unit_radii(), size(), equal_radii(), true};
  detail::add_near_velocities(points, forces, velocities, nrhs, 1.0 / viscosity());
}

}  // namespace rpyfmm::rpy
