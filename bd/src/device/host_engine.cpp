#include "host_engine.hpp"

#include <algorithm>
#include <numeric>

#include "cell_binning.hpp"
#include "euler_maruyama.hpp"
#include "particle_force.hpp"
#include "step_status.hpp"
#include "verlet_rows.hpp"

namespace rpyfmm::bd::device {

namespace {
/// Loops of at least this many items run on the OpenMP threads (the stages' atomics and
/// store_min slots make any order give the same result).
constexpr std::int64_t kParallel = 4096;

/// f(i) for i in [0, n): what a kernel's threads do, one item each.
template <class F>
void for_each_item(std::uint64_t n, F&& f) {
  const auto count = static_cast<std::int64_t>(n);
#pragma omp parallel for schedule(static) if (count >= kParallel)
  for (std::int64_t k = 0; k < count; ++k) f(static_cast<std::uint32_t>(k));
}
}  // namespace

HostEngine::HostEngine(const ForceField& forces, std::vector<std::uint32_t> types, rpy::Geometry geometry,
                       const EngineOptions& options, std::span<const double> positions, std::uint64_t first_step)
    : t_(make_engine_tables(forces, types, geometry, options)),
      step_(first_step),
      schedule_(t_.cutoff, t_.fixed_interval) {
  check_positions(positions, t_.n);
  x_.assign(positions.begin(), positions.end());
  x_next_.resize(x_.size());
  f_.assign(x_.size(), 0.0);
  energy_.assign(t_.n, 0.0);
  if (options.pse != nullptr) {
    pse_ = options.pse;
    sqrt_ = options.sqrt;
    radii_ = particle_radii(t_);
    u_.assign(x_.size(), 0.0);
    times_["plan"] = 0.0;
    times_["drift"] = 0.0;
  }
}

void HostEngine::hydrodynamic_velocities() {
  // The CPU engine's steps 3 and 4 (Integrator::step): the plan at the step's positions, then
  // U = M F + sqrt(2 kT dt) / dt M^{1/2} z in one pass (or U = M F without noise).
  StopWatch watch;
  pse_->set_positions(x_, radii_);
  times_["plan"] += watch.seconds();
  watch.restart();
  products_ = t_.brownian ? fused_drift_and_noise(*pse_, f_, t_.noise / t_.dt, t_.seed, step_, u_, sqrt_)
                          : drift_and_noise(*pse_, f_, {}, u_, {}, sqrt_);
  times_["drift"] += watch.seconds();
}

CellGrid HostEngine::grid() const {
  return cell_grid_of(x_.data(), t_.n, t_.list_radius(), t_.image.periodic, t_.image.box);
}

void HostEngine::build_lists() {
  reference_ = x_;
  rows_.offsets.assign(t_.n + 1, 0);
  rows_.indices.clear();
  if (t_.cutoff == 0.0) return;
  const CellGrid g = grid();
  if (t_.rows_from_all_pairs(g)) {
    rows_from_all_pairs();
  } else {
    rows_from_cells(g);
  }
}

void HostEngine::rows_from_all_pairs() {
  const auto n = static_cast<std::uint32_t>(t_.n);
  const ListRadii radii{t_.list_rl2.data(), t_.ntypes};
  RowsBuild rows{rows_.offsets.data(), nullptr};
  for_each_item(n,
                [&](std::uint32_t i) { count_row_from_all(i, n, x_.data(), t_.type.data(), t_.image, radii, rows); });
  std::inclusive_scan(rows_.offsets.begin() + 1, rows_.offsets.end(), rows_.offsets.begin() + 1);
  rows_.indices.resize(rows_.offsets[n]);
  rows.indices = rows_.indices.data();
  for_each_item(n, [&](std::uint32_t i) { fill_row_from_all(i, n, x_.data(), t_.type.data(), t_.image, radii, rows); });
}

void HostEngine::rows_from_cells(const CellGrid& g) {
  const std::size_t n = t_.n;
  const std::uint64_t cells = g.cells();
  std::vector<std::uint32_t> cell_of(n), rank(n), count(cells + 1, 0), start(cells + 1), order(n), ts(n);
  std::vector<double> xs(3 * n);
  const CellBins bins{cell_of.data(), rank.data(), count.data(), start.data(), order.data()};
  for_each_item(n, [&](std::uint32_t i) { bin_particle(i, x_.data(), g, bins); });
  std::exclusive_scan(count.begin(), count.end(), start.begin(), std::uint32_t{0});
  for_each_item(n, [&](std::uint32_t i) { place_particle(i, bins); });
  for_each_item(cells, [&](std::uint32_t cell) { sort_cell(cell, bins); });
  for_each_item(n, [&](std::uint32_t s) { gather_slot(s, x_.data(), t_.type.data(), g, bins, xs.data(), ts.data()); });
  const SlotView slots{order.data(), start.data(), cell_of.data(), xs.data(), ts.data()};
  const ListRadii radii{t_.list_rl2.data(), t_.ntypes};
  RowsBuild rows{rows_.offsets.data(), nullptr};
  for_each_item(n, [&](std::uint32_t s) { count_row_from_cells(s, g, slots, radii, rows); });
  std::inclusive_scan(rows_.offsets.begin() + 1, rows_.offsets.end(), rows_.offsets.begin() + 1);
  rows_.indices.resize(rows_.offsets[n]);
  rows.indices = rows_.indices.data();
  for_each_item(n, [&](std::uint32_t s) { fill_row_from_cells(s, g, slots, radii, rows); });
}

void HostEngine::step() {
  StopWatch watch;
  rebuilt_ = schedule_.next_step();
  if (rebuilt_) build_lists();
  times_["neighbours"] += watch.seconds();
  watch.restart();
  StepStatus status;
  const ForceTables ft{t_.ntypes,
                       t_.type.data(),
                       t_.pairs.data(),
                       t_.has_pairs,
                       t_.external.data(),
                       t_.trap,
                       t_.bond_begin.data(),
                       t_.bonds.data(),
                       t_.bond_potentials.data(),
                       t_.image};
  const RowsView rows{rows_.offsets.data(), rows_.indices.data()};
  const ForceOutput fo{f_.data(), energy_.data(), &status.bad_pair, &status.bad_bond};
  for_each_item(t_.n, [&](std::uint32_t i) { particle_force(i, x_.data(), ft, rows, fo); });
  times_["forces"] += watch.seconds();
  if (pse_ != nullptr) hydrodynamic_velocities();
  watch.restart();
  const MotionTables mt{t_.type.data(), t_.mobility.data(), t_.sqrt_mobility.data(), t_.radius.data(), t_.dt,
                        t_.noise,       t_.brownian,        t_.max_displacement2,    t_.seed,          step_};
  const MotionOutput mo{x_next_.data(), schedule_.dynamic() ? reference_.data() : nullptr, t_.rebuild_limit2(),
                        &status.bad_move, &status.moved};
  if (pse_ != nullptr) {
    for_each_item(t_.n, [&](std::uint32_t i) { advance_particle_with(i, x_.data(), u_.data(), mt, mo); });
  } else {
    for_each_item(t_.n, [&](std::uint32_t i) { advance_particle(i, x_.data(), f_.data(), mt, mo); });
  }
  times_["update"] += watch.seconds();
  throw_if_failed(status, step_);
  x_.swap(x_next_);
  schedule_.set_moved(status.moved != kNone);
  ++step_;
}

void HostEngine::run(std::uint64_t count) {
  for (std::uint64_t k = 0; k < count; ++k) step();
}

double HostEngine::potential_energy() const {
  double energy = 0.0;
  for (const double e : energy_) energy += e;
  return energy;
}

}  // namespace rpyfmm::bd::device
