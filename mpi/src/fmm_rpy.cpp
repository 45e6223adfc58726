// rpyfmm — DistributedFmmRpy: the far field by DistributedLaplaceFmm on FmmRpy's densities and the
// exact near field on each owner (fmm_rpy.hpp, docs/mpi.md "Distributed FmmRpy").
#include "rpyfmm/mpi/fmm_rpy.hpp"

#include <algorithm>
#include <climits>
#include <cmath>
#include <string>
#include <utility>

// rpy/src (private to rpyfmm::rpy and this layer): FmmRpy's far-field densities and their
// combination, its leaves, the length units and the load scaling, shared with the serial operators.
#include "fmm_far_field.hpp"
#include "fmm_laplace_accuracy.hpp"
#include "fmm_leaf_rules.hpp"
#include "fmm_rpy_near.hpp"
#include "length_units.hpp"
#include "load_scaling.hpp"
#include "particle_set.hpp"
#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/core/validate.hpp"
#include "stage_timer.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "rpyfmm::mpi::DistributedFmmRpy";
constexpr const char* kSetPositions = "rpyfmm::mpi::DistributedFmmRpy::set_positions";
constexpr const char* kApply = "rpyfmm::mpi::DistributedFmmRpy::apply";
constexpr const char* kApplyBlock = "rpyfmm::mpi::DistributedFmmRpy::apply_block";

// The Laplace FMM's options, once every rank has checked its own and all ranks agree on them.
DistributedFmmOptions laplace_options(const Communicator& comm, const DistributedFmmRpyOptions& o) {
  comm.run([&] {
    ranges::require_in(ranges::kMobilityTolerance, o.tolerance, kWhere, "tolerance");
    require(o.leaf_capacity >= 0, ErrorCode::invalid_argument, kWhere,
            "leaf_capacity must be >= 0 (0 = automatic), got " + std::to_string(o.leaf_capacity));
  });
  const std::vector<double> signature{o.tolerance,
                                      static_cast<double>(o.leaf_capacity),
                                      o.separation,
                                      static_cast<double>(o.cell_capacity),
                                      o.overlap_exchange ? 1.0 : 0.0,
                                      static_cast<double>(o.curve)};
  require(same_on_every_rank(comm, signature), ErrorCode::invalid_argument, kWhere,
          "the ranks pass different options (tolerance, leaf_capacity, separation, cell_capacity, "
          "overlap_exchange or curve); every rank must pass the same ones");
  DistributedFmmOptions laplace;
  // The Laplace sums run at FmmRpy's accuracy for the requested tolerance (fmm_laplace_accuracy.hpp);
  // the combination's errors stay below it in the tests (tests/mpi/test_distributed_fmm_rpy.cpp). The
  // near field is summed as RPY blocks (fmm_rpy_near.hpp). min_leaf_side and the automatic leaves
  // are set per configuration (set_positions).
  const rpy::detail::LaplaceAccuracy accuracy = rpy::detail::laplace_accuracy_for(o.tolerance);
  laplace.fmm.tolerance = accuracy.tolerance;
  laplace.fmm.order = accuracy.order;
  laplace.fmm.planewave_nodes = accuracy.planewave_nodes;
  laplace.fmm.near_field = false;
  // FmmRpy's rule (rpy/src/fmm_operator.cpp, docs/design-notes.md item 7): the W/X pairs that the
  // Laplace FMM would sum directly go to the near field, where one RPY block per pair of particles
  // beats 4-7 Laplace densities; those with equivalent nodes stay Laplace pairs (essential_near.hpp).
  laplace.fmm.export_direct_far = true;
  laplace.fmm.leaf_capacity = o.leaf_capacity;
  laplace.separation = o.separation;
  laplace.cell_capacity = o.cell_capacity;
  laplace.overlap_exchange = o.overlap_exchange;
  laplace.curve = o.curve;
  // FmmRpy's leaves count particles: an owned particle, which an owner's serial FMM holds as a
  // source and as a target, counts once.
  laplace.count_owned_once = true;
  return laplace;
}

}  // namespace

DistributedFmmRpy::DistributedFmmRpy(MPI_Comm comm, double viscosity, const DistributedFmmRpyOptions& options)
    : comm_(comm),
      viscosity_(detail::agreed_viscosity(comm_, viscosity, kWhere)),
      options_(options),
      laplace_options_(laplace_options(comm_, options)),
      laplace_(comm, laplace_options_) {}

DistributedFmmRpy::~DistributedFmmRpy() = default;
DistributedFmmRpy::DistributedFmmRpy(DistributedFmmRpy&&) noexcept = default;
DistributedFmmRpy& DistributedFmmRpy::operator=(DistributedFmmRpy&&) noexcept = default;

std::size_t DistributedFmmRpy::halo_size() const {
  return near_ ? near_->halo_size() : 0;
}

void DistributedFmmRpy::set_positions(std::span<const double> local_positions, double radius) {
  global_n_ = 0;  // no positions until this call succeeds on every rank
  sampler_blocks_.clear();
  set_positions(local_positions, detail::common_radii(comm_, local_positions, radius, kSetPositions));
}

void DistributedFmmRpy::set_positions(std::span<const double> local_positions, std::span<const double> local_radii) {
  global_n_ = 0;  // no positions until this call succeeds on every rank
  sampler_blocks_.clear();
  near_.reset();
  stats_ = FmmRpyCommunication{};
  comm_.run([&] { detail::check_local_particles(local_positions, local_radii, kSetPositions); });
  detail::timed(stats_.set_positions_seconds, [&] { counts_ = detail::gather_counts(comm_, local_radii.size()); });
  std::size_t total = 0;
  offset_ = 0;
  for (std::size_t r = 0; r < counts_.size(); ++r) {
    if (static_cast<int>(r) < comm_.rank()) offset_ += counts_[r];
    total += counts_[r];
  }
  // Same values on every rank, so every rank throws alike here without agreement.
  require(total > 0, ErrorCode::invalid_input, kSetPositions,
          "no particles on any of the " + std::to_string(counts_.size()) + " ranks (N = 0)");
  local_n_ = local_radii.size();
  detail::WholeSet set;
  detail::timed(stats_.set_positions_seconds,
                [&] { set = detail::gather_whole_set(comm_, local_positions, local_radii, offset_); });
  equal_radii_ = set.radii.a_min == set.radii.a_max;
  // FmmRpy::on_positions_set on this rank's share, with the whole set's box and units.
  comm_.run([&] {
    const rpy::detail::LengthUnits units =
        rpy::detail::choose_length_units(set.box, local_radii, set.radii, kSetPositions);
    scale_exponent_ = units.exponent;
    rpy::detail::to_fmm_frame(units, set.box, local_positions, local_radii, x_, a_);
    if (scale_exponent_ == 0) a_.assign(local_radii.begin(), local_radii.end());
  });
  positions_.assign(local_positions.begin(), local_positions.end());
  radii_.assign(local_radii.begin(), local_radii.end());
  largest_radius_ = set.radii.a_max;
  const double a_max = std::ldexp(set.radii.a_max, -scale_exponent_);
  // Leaves of each owner's serial FMM at least 2 a_max wide, as in FmmRpy, and no cell within 2 a_max
  // of a rank's region compressed for it (DistributedFmmOptions): every overlapping pair (r <
  // a_i + a_j <= 2 a_max, coincident points included) joins two particles, owned or halo, in
  // adjacent leaves, and so lies in the exact near field (docs/mpi.md). Automatic leaves are
  // FmmRpy's (rpy/src/fmm_leaf_rules.hpp), for a near field of RPY blocks; the fitted grid's rule by
  // the whole set's size, the same on every rank.
  DistributedFmmOptions laplace = laplace_options_;
  laplace.fmm.min_leaf_side = 2.0 * a_max;
  if (options_.leaf_capacity == 0) {
    laplace.fmm.leaf_capacity = rpy::detail::default_leaf_capacity(options_.tolerance);
    laplace.fmm.fitted_grid = rpy::detail::fitted_grid_rule(options_.tolerance, total);
  }
  laplace_ = DistributedLaplaceFmm(comm_.get(), laplace);
  laplace_.set_points(x_);
  stats_.set_positions_seconds += detail::total_seconds(laplace_.communication().plan_seconds);
  near_ = std::make_unique<detail::RpyNearField>(comm_, laplace_, a_, equal_radii_, a_max);
  stats_.near_set_positions_seconds = near_->setup().seconds;
  stats_.near_set_positions_bytes_received = near_->setup().bytes_received;
  stats_.set_positions_seconds += stats_.near_set_positions_seconds;
  global_n_ = total;
}

void DistributedFmmRpy::apply(std::span<const double> local_forces, std::span<double> local_velocities) const {
  product(kApply, local_forces, local_velocities, 1);
}

void DistributedFmmRpy::apply_block(std::span<const double> local_forces, std::span<double> local_velocities,
                                    std::size_t nrhs) const {
  require(global_n_ > 0, ErrorCode::invalid_input, kApplyBlock, "positions not set (call set_positions first)");
  detail::agree_on_nrhs(comm_, nrhs, kApplyBlock);
  // nrhs is the same on every rank, so every rank throws alike here.
  require(
      nrhs <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, kApplyBlock,
      std::to_string(nrhs) + " right-hand sides: more than MPI's int counts address (" + std::to_string(INT_MAX) + ")");
  product(kApplyBlock, local_forces, local_velocities, nrhs);
}

void DistributedFmmRpy::product(const char* where, std::span<const double> local_forces,
                                std::span<double> local_velocities, std::size_t nrhs) const {
  // global_n_ is the same on every rank (set_positions succeeds or fails on all of them).
  require(global_n_ > 0, ErrorCode::invalid_input, where, "positions not set (call set_positions first)");
  const std::size_t n = local_n_;
  const std::size_t n3 = 3 * n;
  comm_.run([&] {
    require_size(local_forces, n3 * nrhs, where, "local forces");
    require_size(std::span<const double>(local_velocities.data(), local_velocities.size()), n3 * nrhs, where,
                 "local velocities");
    require_finite(local_forces, where, "local forces", 3);
  });
  // MobilityOperator::apply_block's load scale of each right-hand side, from its largest force of
  // all ranks: each right-hand side is scaled as in a product of it alone.
  std::vector<double> largest(nrhs, 0.0), global_largest(nrhs, 0.0);
  for (std::size_t r = 0; r < nrhs; ++r)
    for (double f : local_forces.subspan(n3 * r, n3)) largest[r] = std::max(largest[r], std::abs(f));
  double reduction_seconds = 0.0;
  detail::timed(reduction_seconds, [&] {
    check_mpi(
        MPI_Allreduce(largest.data(), global_largest.data(), static_cast<int>(nrhs), MPI_DOUBLE, MPI_MAX, comm_.get()),
        "MPI_Allreduce");
  });
  std::vector<int> k(nrhs);
  std::vector<double> f(n3 * nrhs);
  for (std::size_t r = 0; r < nrhs; ++r) {
    k[r] = rpy::detail::load_scale_exponent({std::span<const double>(&global_largest[r], 1)});
    for (std::size_t i = n3 * r; i < n3 * (r + 1); ++i) f[i] = std::ldexp(local_forces[i], -k[r]);
  }

  // The far pairs (FmmRpy::do_apply's far field): the densities of every right-hand side in one
  // Laplace evaluation, whose owners leave out their near pairs between particles.
  const std::size_t per_rhs = rpy::detail::translation_densities(equal_radii_);
  const std::size_t nd = per_rhs * nrhs;
  std::vector<double> charges(nd * n);
  std::vector<unsigned> outputs(nd);
  rpy::detail::far_field_charges(f.data(), n, nrhs, equal_radii_, x_, a_, charges, outputs);
  std::vector<double> results(nd * n * fmm::result_width), essential;
  laplace_.evaluate(charges, nd, outputs, results, essential);
  std::vector<double> u(n3 * nrhs);
  rpy::detail::combine_far_field(results, n, nrhs, equal_radii_, x_, a_, viscosity_, u.data());

  // The near pairs as exact RPY blocks and the self terms, on the owners, from the forces among
  // the essential charges (densities 0..2 of each right-hand side).
  near_->add_velocities(essential, per_rhs, nrhs, 1.0 / viscosity_, u);
  record_product(reduction_seconds);
  // Back from the length units (M(x, a) = 2^-e M(2^-e x, 2^-e a)) and the load scale, exactly.
  for (std::size_t i = 0; i < n3 * nrhs; ++i) {
    local_velocities[i] = std::ldexp(std::ldexp(u[i], -scale_exponent_), k[i / n3]);
  }
  comm_.run([&] { rpy::detail::require_finite_result(local_velocities, where, "velocities", "forces"); });
}

void DistributedFmmRpy::record_product(double reduction_seconds) const {
  const FmmCommunication& far = laplace_.communication();
  const detail::RpyNearExchange& near = near_->back();
  stats_.near_apply_seconds = near.seconds;
  stats_.near_apply_bytes_received = near.bytes_received;
  stats_.near_sums_seconds = near_->sums_seconds();
  stats_.apply_seconds = reduction_seconds + detail::total_seconds(far.evaluate_seconds) + near.seconds;
  stats_.apply_bytes_received = far.evaluate_bytes_received + near.bytes_received;
  stats_.applies_seconds += stats_.apply_seconds;
}

void DistributedFmmRpy::apply(std::span<const double> local_forces, std::span<const double> local_torques,
                              std::span<double> local_velocities, std::span<double> local_angular_velocities) const {
  require(global_n_ > 0, ErrorCode::invalid_input, kApply, "positions not set (call set_positions first)");
  const std::size_t n = local_n_;
  comm_.run([&] {
    require_size(local_forces, 3 * n, kApply, "local forces");
    require_size(local_torques, 3 * n, kApply, "local torques");
    require_size(std::span<const double>(local_velocities.data(), local_velocities.size()), 3 * n, kApply,
                 "local velocities");
    require_size(std::span<const double>(local_angular_velocities.data(), local_angular_velocities.size()), 3 * n,
                 kApply, "local angular velocities");
    require_finite(local_forces, kApply, "local forces", 3);
    require_finite(local_torques, kApply, "local torques", 3);
  });
  // MobilityOperator::apply's load scale for [F; T], from the largest load of all ranks
  // (largest_rotation_load, with the largest radius of all ranks).
  const double largest = rpy::detail::largest_rotation_load(local_forces, local_torques, largest_radius_);
  double global_largest = 0.0, reduction_seconds = 0.0;
  detail::timed(reduction_seconds, [&] {
    check_mpi(MPI_Allreduce(&largest, &global_largest, 1, MPI_DOUBLE, MPI_MAX, comm_.get()), "MPI_Allreduce");
  });
  const int k = rpy::detail::load_scale_exponent({std::span<const double>(&global_largest, 1)});
  // In the length units 2^e the blocks carry 1/L (tt), 1/L^2 (ut, wf) and 1/L^3 (rr): with the
  // torques as 2^-e T every sum below is 2^e U or 2^(2e) W (FmmRpy::do_apply_rotation).
  const int e = scale_exponent_;
  std::vector<double> f(3 * n), t(3 * n);
  for (std::size_t i = 0; i < 3 * n; ++i) {
    f[i] = std::ldexp(local_forces[i], -k);
    t[i] = std::ldexp(local_torques[i], -k - e);
  }

  // The far pairs: FmmRpy's densities with rotation in one evaluation.
  const std::size_t nd = rpy::detail::rotation_densities(equal_radii_);
  std::vector<double> charges(nd * n);
  std::vector<unsigned> outputs(nd);
  rpy::detail::rotation_far_field_charges(f.data(), t.data(), n, equal_radii_, x_, a_, charges, outputs);
  std::vector<double> results(nd * n * fmm::result_width), essential;
  laplace_.evaluate(charges, nd, outputs, results, essential);
  std::vector<double> u(3 * n), ut(3 * n), wf(3 * n), rr(3 * n);
  rpy::detail::combine_far_field(results, n, 1, equal_radii_, x_, a_, viscosity_, u.data());
  rpy::detail::combine_rotation_far_field(results, n, equal_radii_, ut.data(), wf.data(), rr.data());

  // The near pairs' exact blocks and the self terms, on the owners, from the forces and torques
  // among the essential charges: the translational ones into u as in the product without torques,
  // the rotational ones into ut (U) and wf (W).
  const double inv_eta = 1.0 / viscosity_;
  near_->add_grand(essential, rpy::detail::translation_densities(equal_radii_), inv_eta, u, ut, wf);
  record_product(reduction_seconds);
  // Back from the length units and the load scale, exactly.
  for (std::size_t i = 0; i < 3 * n; ++i) {
    local_velocities[i] = std::ldexp(std::ldexp(u[i] + inv_eta * ut[i], -e), k);
    local_angular_velocities[i] = std::ldexp(std::ldexp(inv_eta * (wf[i] + rr[i]), -2 * e), k);
  }
  comm_.run([&] {
    rpy::detail::require_finite_result(local_velocities, kApply, "velocities", "forces and torques");
    rpy::detail::require_finite_result(local_angular_velocities, kApply, "angular velocities", "forces and torques");
  });
}

}  // namespace rpyfmm::mpi
