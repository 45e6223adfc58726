// rpyfmm — DistributedLaplaceFmm: options, the plan's stages (partition, cells, locally essential
// tree, serial plan) and the evaluation's (charges to the owners, equivalent and halo charges, the
// serial FMM, results back) (laplace_fmm.hpp, docs/mpi.md; the essential tree in
// essential_exchange.cpp).
#include "rpyfmm/mpi/laplace_fmm.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "essential_near.hpp"
#include "fmm_plan.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/partition.hpp"
#include "stage_timer.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "rpyfmm::mpi::DistributedLaplaceFmm";
constexpr const char* kSetPoints = "rpyfmm::mpi::DistributedLaplaceFmm::set_points";
constexpr const char* kEvaluate = "rpyfmm::mpi::DistributedLaplaceFmm::evaluate";

void check_options(const DistributedFmmOptions& o) {
  require(!o.fmm.export_direct_far || !o.fmm.near_field, ErrorCode::invalid_argument, kWhere,
          "export_direct_far needs near_field = false (the serial FMM's W/X pairs between particles are "
          "left to the caller with its near pairs)");
  require(o.separation == 0.0 || (o.separation >= 1.0 && o.separation <= 100.0), ErrorCode::invalid_argument, kWhere,
          "separation must be 0 (automatic) or in [1, 100], got " + format_number(o.separation));
  require(o.chebyshev_order >= 0 && o.chebyshev_order <= 32, ErrorCode::invalid_argument, kWhere,
          "chebyshev_order must be 0 (automatic) or in [1, 32], got " + std::to_string(o.chebyshev_order));
  require(o.curve == SfcCurve::morton || o.curve == SfcCurve::hilbert, ErrorCode::invalid_argument, kWhere,
          "curve must be SfcCurve::morton or SfcCurve::hilbert, got " + std::to_string(static_cast<int>(o.curve)));
  (void)fmm::LaplaceFmm(o.fmm);  // the serial FMM's own checks
}

// The options as numbers, compared between ranks.
std::vector<double> option_signature(const DistributedFmmOptions& o) {
  return {o.fmm.tolerance,
          static_cast<double>(o.fmm.leaf_capacity),
          o.fmm.min_leaf_side,
          o.fmm.root_scale,
          static_cast<double>(o.fmm.order),
          static_cast<double>(o.fmm.fitted_grid.occupancy),
          o.count_owned_once ? 1.0 : 0.0,
          o.separation,
          static_cast<double>(o.chebyshev_order),
          static_cast<double>(o.cell_capacity),
          o.overlap_exchange ? 1.0 : 0.0,
          o.fmm.near_field ? 1.0 : 0.0,
          o.gather_all_regions ? 1.0 : 0.0,
          static_cast<double>(o.curve),
          o.targets_follow_sources ? 1.0 : 0.0};
}

// Collective: translates the owned sources x and targets y next to the origin where the whole cloud lies far
// from it (its centre at least 4 extents out along an axis), by the centre of the global box on
// that axis, as the serial FMM does (exact_shifts in fmm/src/laplace_fmm.cpp): every coordinate is
// then within a factor 2 of the centre, so x - centre is exact (Sterbenz) and pair differences do
// not change, while the cells' cubes and Chebyshev nodes are rounded to the cloud's scale instead
// of the coordinates'. Potentials and fields are invariant under the translation. One allreduce.
void shift_to_centre(const Communicator& comm, std::vector<double>& x, std::vector<double>& y) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::array<double, 6> local{kInf, kInf, kInf, kInf, kInf, kInf}, box{};  // minima, minus maxima
  for (const std::vector<double>* points : {&x, &y}) {
    for (std::size_t i = 0; i < points->size(); ++i) {
      local[i % 3] = std::min(local[i % 3], (*points)[i]);
      local[3 + i % 3] = std::min(local[3 + i % 3], -(*points)[i]);
    }
  }
  check_mpi(MPI_Allreduce(local.data(), box.data(), 6, MPI_DOUBLE, MPI_MIN, comm.get()), "MPI_Allreduce");
  if (box[0] == kInf) return;  // no source anywhere
  double extent = 0.0;
  for (std::size_t d = 0; d < 3; ++d) extent = std::max(extent, 0.5 * -box[3 + d] - 0.5 * box[d]);
  extent *= 2.0;
  std::array<double, 3> shift{};
  for (std::size_t d = 0; d < 3; ++d) {
    const double mid = 0.5 * box[d] + 0.5 * -box[3 + d];
    if (std::abs(mid) >= 4.0 * extent) shift[d] = mid;
  }
  for (std::size_t i = 0; i < x.size(); ++i) x[i] -= shift[i % 3];
  for (std::size_t i = 0; i < y.size(); ++i) y[i] -= shift[i % 3];
}

void check_points(std::span<const double> points, const char* name) {
  require(points.size() % 3 == 0, ErrorCode::invalid_input, kSetPoints,
          std::string(name) + " have " + std::to_string(points.size()) + " entries, not a multiple of 3");
  require_finite(points, kSetPoints, name, 3);
}

}  // namespace

int chebyshev_order_for(double tolerance, double separation) {
  return detail::order_at(tolerance, separation, 32);
}

DistributedLaplaceFmm::DistributedLaplaceFmm(MPI_Comm comm, const DistributedFmmOptions& options)
    : comm_(comm), options_(options) {
  comm_.run([&] { check_options(options_); });
  if (!same_on_every_rank(comm_, option_signature(options_))) {
    fail(ErrorCode::invalid_argument, kWhere, "the ranks pass different options");
  }
  separation_ = options_.separation > 0.0 ? options_.separation : kDefaultSeparation;
  cell_capacity_ = options_.cell_capacity > 0 ? options_.cell_capacity : kDefaultCellCapacity;
}

DistributedLaplaceFmm::~DistributedLaplaceFmm() = default;
DistributedLaplaceFmm::DistributedLaplaceFmm(DistributedLaplaceFmm&&) noexcept = default;
DistributedLaplaceFmm& DistributedLaplaceFmm::operator=(DistributedLaplaceFmm&&) noexcept = default;

std::size_t DistributedLaplaceFmm::local_size() const {
  return plan_ ? plan_->partition->input_size() : 0;
}
std::size_t DistributedLaplaceFmm::owned_size() const {
  return plan_ ? plan_->partition->owned_size() : 0;
}
std::uint64_t DistributedLaplaceFmm::global_size() const {
  return plan_ ? plan_->partition->global_size() : 0;
}
std::size_t DistributedLaplaceFmm::local_target_size() const {
  return plan_ ? plan_->targets().input_size() : 0;
}
std::size_t DistributedLaplaceFmm::owned_target_size() const {
  return plan_ ? plan_->targets().owned_size() : 0;
}
std::size_t DistributedLaplaceFmm::essential_size() const {
  return plan_ ? plan_->sources : 0;
}

namespace {

std::vector<std::uint64_t> owned_keys(const SfcPartition& partition) {
  std::vector<std::uint64_t> keys;
  keys.reserve(partition.owned_size());
  for (const SfcKey& k : partition.owned()) keys.push_back(k.key);
  return keys;
}

// Collective: partitions the sources (and separate targets, when any rank passes one: by their own
// cuts, or by the sources' where they follow them) and moves their positions to the owners, next
// to the origin (shift_to_centre).
void partition_points(const Communicator& comm, DistributedLaplaceFmm::Plan& plan, std::span<const double> sources,
                      std::span<const double> targets, std::span<const double> weights,
                      const DistributedFmmOptions& options) {
  plan.partition = std::make_unique<SfcPartition>(comm.get(), sources, weights, options.curve);
  const Column source_column[] = {{sources, 3}};
  plan.owned_x = plan.partition->to_owners(source_column)[0];
  const int mine = targets.empty() ? 0 : 1;
  int separate = 0;
  check_mpi(MPI_Allreduce(&mine, &separate, 1, MPI_INT, MPI_MAX, comm.get()), "MPI_Allreduce");
  if (separate != 0) {
    plan.target_partition =
        options.targets_follow_sources
            ? std::make_unique<SfcPartition>(SfcPartition::aligned_with(*plan.partition, targets))
            : std::make_unique<SfcPartition>(comm.get(), targets, std::span<const double>{}, options.curve);
    const Column target_column[] = {{targets, 3}};
    plan.owned_targets = plan.target_partition->to_owners(target_column)[0];
  }
  shift_to_centre(comm, plan.owned_x, plan.owned_targets);
}

// The serial FMM's options where its tree holds every owned particle twice, as a source and as a
// target (DistributedFmmOptions::count_owned_once): the leaf capacity and the fitted grid's
// occupancy and point counts doubled, so that a leaf of owned particles splits as in the serial
// FMM at its own points. The fitted grid's capacity is twice its occupancy (fit_leaf_grid), so
// doubling the occupancy doubles that capacity too.
fmm::FmmOptions counting_owned_once(fmm::FmmOptions o) {
  constexpr std::size_t kMax = std::numeric_limits<std::size_t>::max();
  o.leaf_capacity *= 2;
  o.fitted_grid.occupancy *= 2;
  o.fitted_grid.min_points *= 2;
  o.fitted_grid.max_points = o.fitted_grid.max_points > kMax / 2 ? kMax : 2 * o.fitted_grid.max_points;
  return o;
}

// The serial FMM on this rank's essential sources and owned targets; none where either is empty
// (its targets' results are then 0). Targets at the sources when nothing came from the other ranks
// (one rank, or an isolated owner): the serial FMM's own mode, one tree of m points.
void plan_one_fmm(DistributedLaplaceFmm::Plan& plan, std::span<const double> sources, const fmm::FmmOptions& options,
                  bool count_owned_once) {
  const std::vector<double>& targets = plan.target_x();
  plan.sources = sources.empty() || targets.empty() ? 0 : sources.size() / 3;
  if (plan.sources == 0) return;
  if (!plan.target_partition && sources.size() == plan.owned_x.size()) {
    plan.fmm.set_points(sources);
  } else {
    if (count_owned_once && !plan.target_partition) plan.fmm = fmm::LaplaceFmm(counting_owned_once(options));
    plan.fmm.set_points(sources, targets);
  }
}

// DistributedFmmOptions::overlap_exchange: the owned sources' FMM (own mode at the sources) and
// the received sources' FMM, both at the owned targets.
void plan_split_fmm(DistributedLaplaceFmm::Plan& plan, std::span<const double> sources) {
  const std::vector<double>& targets = plan.target_x();
  const std::size_t owned = plan.owned_x.size();
  plan.split = true;
  plan.sources = sources.empty() || targets.empty() ? 0 : sources.size() / 3;
  plan.own_runs = owned > 0 && !targets.empty();
  plan.received_runs = sources.size() > owned && !targets.empty();
  if (plan.own_runs) {
    if (plan.target_partition) {
      plan.own_fmm.set_points(plan.owned_x, targets);
    } else {
      plan.own_fmm.set_points(plan.owned_x);
    }
  }
  if (plan.received_runs) plan.received_fmm.set_points(sources.subspan(owned), targets);
}

// Collective: the serial FMM (one, or split in two) on this rank's essential sources.
void plan_serial_fmm(const Communicator& comm, DistributedLaplaceFmm::Plan& plan, const DistributedFmmOptions& options,
                     const std::vector<double>& sources, StageTimes& times) {
  plan.fmm = fmm::LaplaceFmm(options.fmm);
  plan.own_fmm = fmm::LaplaceFmm(options.fmm);
  plan.received_fmm = fmm::LaplaceFmm(options.fmm);
  comm.run([&] {
    detail::timed(times, "plan_fmm", [&] {
      if (options.overlap_exchange) {
        plan_split_fmm(plan, sources);
      } else {
        plan_one_fmm(plan, sources, options.fmm, options.count_owned_once);
      }
    });
  });
}

}  // namespace

void DistributedLaplaceFmm::set_points(std::span<const double> local_sources, std::span<const double> local_targets,
                                       std::span<const double> local_weights) {
  plan_.reset();
  stats_ = {};
  comm_.run([&] {
    check_points(local_sources, "local sources");
    check_points(local_targets, "local targets");
  });
  auto plan = std::make_unique<Plan>();
  detail::timed(stats_.plan_seconds, "partition",
                [&] { partition_points(comm_, *plan, local_sources, local_targets, local_weights, options_); });
  if (plan->partition->global_size() == 0) fail(ErrorCode::invalid_input, kSetPoints, "no rank has a source");
  stats_.plan_bytes_received += (plan->owned_x.size() + plan->owned_targets.size()) * sizeof(double);

  plan->tree = detail::build_cell_tree(owned_keys(*plan->partition), plan->owned_x, cell_capacity_);
  // The region this rank publishes is that of its targets.
  const detail::CellTree target_tree =
      plan->target_partition
          ? detail::build_cell_tree(owned_keys(*plan->target_partition), plan->owned_targets, cell_capacity_)
          : detail::CellTree{};
  const detail::Acceptance acceptance{options_.fmm.tolerance, separation_, 32, options_.chebyshev_order,
                                      options_.fmm.min_leaf_side};
  std::vector<detail::Region> regions;
  detail::timed(stats_.plan_seconds, "summaries", [&] {
    regions = detail::exchange_regions(comm_, plan->target_partition ? target_tree : plan->tree, plan->tree, acceptance,
                                       options_.gather_all_regions, stats_);
  });
  detail::select_cells(*plan, regions, comm_.rank(), acceptance);
  std::vector<double> sources;
  detail::timed(stats_.plan_seconds, "geometry",
                [&] { sources = detail::exchange_geometry(comm_, *plan, stats_.plan_bytes_received); });
  detail::count_essential(*plan, stats_);
  if (!options_.fmm.near_field) {
    // The near pairs left out of the serial FMM: those with equivalent nodes are summed by the
    // evaluation (essential_near.hpp), the others by the caller (plan()).
    plan->essential_x = sources;
    if (stats_.nodes_received > 0) plan->node = detail::node_sources(*plan);
  }
  plan_serial_fmm(comm_, *plan, options_, sources, stats_.compute_seconds);
  plan_ = std::move(plan);
}

namespace {

void check_evaluation(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                      std::span<double> results, std::size_t n, std::size_t n_targets) {
  require(nd >= 1, ErrorCode::invalid_argument, kEvaluate, "nd must be >= 1");
  require_size(charges, nd * n, kEvaluate, "local charges (nd x n)");
  require_finite(charges, kEvaluate, "local charges", std::max<std::size_t>(n, 1));
  require(outputs.size() == nd, ErrorCode::invalid_input, kEvaluate,
          "outputs has " + std::to_string(outputs.size()) + " entries, expected nd = " + std::to_string(nd));
  fmm::require_valid_outputs(outputs, kEvaluate);  // the serial FMM's flags, groups included
  require(results.size() == nd * n_targets * fmm::result_width, ErrorCode::invalid_input, kEvaluate,
          "local results have " + std::to_string(results.size()) +
              " entries, expected nd x targets x 10 = " + std::to_string(nd * n_targets * fmm::result_width));
}

}  // namespace

void DistributedLaplaceFmm::evaluate(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                                     std::span<double> results) const {
  evaluate_impl(charges, nd, outputs, results, nullptr);
}

void DistributedLaplaceFmm::evaluate(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                                     std::span<double> results, std::vector<double>& essential_charges) const {
  essential_charges.clear();
  evaluate_impl(charges, nd, outputs, results, &essential_charges);
}

void DistributedLaplaceFmm::evaluate_impl(std::span<const double> charges, std::size_t nd,
                                          std::span<const unsigned> outputs, std::span<double> results,
                                          std::vector<double>* essential) const {
  comm_.run([&] {
    require(plan_ != nullptr, ErrorCode::invalid_input, kEvaluate, "set_points has not succeeded");
    check_evaluation(charges, nd, outputs, results, plan_->partition->input_size(), plan_->targets().input_size());
  });
  std::vector<double> signature{static_cast<double>(nd)};
  if (!same_on_every_rank(comm_, signature))
    fail(ErrorCode::invalid_argument, kEvaluate, "the ranks pass different nd");
  signature.assign(outputs.begin(), outputs.end());
  if (!same_on_every_rank(comm_, signature)) {
    fail(ErrorCode::invalid_argument, kEvaluate, "the ranks pass different outputs");
  }
  const Plan& plan = *plan_;
  stats_.evaluate_seconds.clear();
  stats_.compute_seconds.erase("anterpolation");
  stats_.compute_seconds.erase("fmm");
  stats_.evaluate_bytes_received = 0;
  const std::size_t n = plan.partition->input_size(), n_targets = plan.targets().input_size();
  const std::size_t m_targets = plan.targets().owned_size();

  std::vector<double> owned_q;
  detail::timed(stats_.evaluate_seconds, "charges", [&] {
    std::vector<Column> columns;
    for (std::size_t d = 0; d < nd; ++d) columns.push_back({charges.subspan(d * n, n), 1});
    for (const std::vector<double>& c : plan.partition->to_owners(columns))
      owned_q.insert(owned_q.end(), c.begin(), c.end());
  });
  stats_.evaluate_bytes_received += owned_q.size() * sizeof(double);

  std::vector<double> owned_results(nd * m_targets * fmm::result_width, 0.0);
  if (plan.split) {
    evaluate_split(plan, owned_q, nd, outputs, owned_results, essential);
  } else {
    evaluate_one(plan, owned_q, nd, outputs, owned_results, essential);
  }

  // Back to the input ranks: only the columns the flags fill (fmm::filled_result_columns), the others 0.
  const std::vector<std::vector<std::size_t>> filled = fmm::filled_result_columns(outputs);
  std::size_t filled_width = 0;
  detail::timed(stats_.evaluate_seconds, "results", [&] {
    std::vector<std::vector<double>> packed;
    std::vector<Column> columns;
    for (std::size_t d = 0; d < nd; ++d) {
      if (filled[d].empty()) continue;
      const double* from = owned_results.data() + d * m_targets * fmm::result_width;
      std::vector<double>& p = packed.emplace_back(m_targets * filled[d].size());
      for (std::size_t i = 0, at = 0; i < m_targets; ++i)
        for (std::size_t c : filled[d]) p[at++] = from[i * fmm::result_width + c];
      filled_width += filled[d].size();
    }
    for (std::size_t d = 0, k = 0; d < nd; ++d)
      if (!filled[d].empty()) columns.push_back({packed[k++], filled[d].size()});
    const std::vector<std::vector<double>> back = plan.targets().to_origin(columns);
    std::fill(results.begin(), results.end(), 0.0);
    for (std::size_t d = 0, k = 0; d < nd; ++d) {
      if (filled[d].empty()) continue;
      const std::vector<double>& b = back[k++];
      double* to = results.data() + d * n_targets * fmm::result_width;
      for (std::size_t i = 0, at = 0; i < n_targets; ++i)
        for (std::size_t c : filled[d]) to[i * fmm::result_width + c] = b[at++];
    }
  });
  stats_.evaluate_bytes_received += filled_width * n_targets * sizeof(double);
}

void DistributedLaplaceFmm::evaluate_one(const Plan& plan, std::span<const double> owned_q, std::size_t nd,
                                         std::span<const unsigned> outputs, std::span<double> owned_results,
                                         std::vector<double>* essential) const {
  // The halo charges travel while the cells are anterpolated (MPI progressed between pieces of
  // it), then the equivalent charges; the serial FMM waits for both.
  std::unique_ptr<detail::PendingAlltoallv> halo;
  detail::timed(stats_.evaluate_seconds, "essential",
                [&] { halo = detail::post_halo_charges(comm_, plan, owned_q, nd); });
  std::vector<double> equivalent;
  detail::timed(stats_.compute_seconds, "anterpolation",
                [&] { equivalent = detail::anterpolate_cells(plan, owned_q, nd, [&] { halo->test(); }); });
  detail::ReceivedCharges got;
  detail::timed(stats_.evaluate_seconds, "essential", [&] {
    got.nodes = detail::exchange_node_charges(comm_, plan, equivalent, nd);
    got.halo = halo->wait();
  });
  stats_.evaluate_bytes_received += (got.halo.size() + got.nodes.size()) * sizeof(double);
  // Timed inside run(): the local work only, not the wait for the slower ranks in its agreement.
  comm_.run([&] {
    detail::timed(stats_.compute_seconds, "fmm", [&] {
      if (plan.sources == 0) return;
      std::vector<double> q = detail::assemble_charges(plan, owned_q, got, nd);
      plan.fmm.evaluate(q, nd, outputs, owned_results);
      if (!plan.node.empty()) {
        for (const detail::NearPiece& piece : detail::near_pieces(plan))
          detail::add_node_near_field(plan, piece, q, plan.sources, nd, outputs, owned_results);
      }
      if (essential != nullptr) *essential = std::move(q);
    });
  });
}

void DistributedLaplaceFmm::evaluate_split(const Plan& plan, std::span<const double> owned_q, std::size_t nd,
                                           std::span<const unsigned> outputs, std::span<double> owned_results,
                                           std::vector<double>* essential) const {
  // Both exchanges are posted before the owned sources' FMM, which needs only the owned charges;
  // the received sources' FMM waits for them and adds its results.
  std::unique_ptr<detail::PendingAlltoallv> halo, nodes;
  detail::timed(stats_.evaluate_seconds, "essential",
                [&] { halo = detail::post_halo_charges(comm_, plan, owned_q, nd); });
  std::vector<double> equivalent;
  detail::timed(stats_.compute_seconds, "anterpolation",
                [&] { equivalent = detail::anterpolate_cells(plan, owned_q, nd, [&] { halo->test(); }); });
  detail::timed(stats_.evaluate_seconds, "essential", [&] {
    nodes = detail::post_node_charges(comm_, plan, equivalent, nd);
    halo->test();
    nodes->test();
  });
  comm_.run([&] {
    detail::timed(stats_.compute_seconds, "fmm", [&] {
      if (plan.own_runs) plan.own_fmm.evaluate(owned_q, nd, outputs, owned_results);
    });
  });
  detail::ReceivedCharges got;
  detail::timed(stats_.evaluate_seconds, "essential", [&] {
    got.halo = halo->wait();
    got.nodes = nodes->wait();
  });
  stats_.evaluate_bytes_received += (got.halo.size() + got.nodes.size()) * sizeof(double);
  comm_.run([&] {
    detail::timed(stats_.compute_seconds, "fmm", [&] {
      if (essential != nullptr && plan.sources > 0) *essential = detail::assemble_charges(plan, owned_q, got, nd);
      if (!plan.received_runs) return;
      std::vector<double> received(owned_results.size());
      const std::vector<double> q = detail::assemble_received(plan, got, nd);
      plan.received_fmm.evaluate(q, nd, outputs, received);
      for (std::size_t i = 0; i < received.size(); ++i) owned_results[i] += received[i];
      if (plan.node.empty()) return;
      // The owned sources' FMM holds no node; the received sources' is numbered from the owned count.
      const std::size_t m = plan.owned_x.size() / 3;
      for (const detail::NearPiece& piece : detail::near_pieces(plan))
        if (piece.offset == m)
          detail::add_node_near_field(plan, piece, q, plan.sources - m, nd, outputs, owned_results);
    });
  });
}

std::vector<double> DistributedLaplaceFmm::measured_weights() const {
  constexpr const char* where = "rpyfmm::mpi::DistributedLaplaceFmm::measured_weights";
  comm_.run([&] {
    require(plan_ != nullptr, ErrorCode::invalid_input, where, "set_points has not succeeded");
    require(!plan_->target_partition, ErrorCode::not_supported, where,
            "measured weights need results at the sources (set_points without targets)");
  });
  const Plan& plan = *plan_;
  // The serial FMM's targets are the owned sources, in owned order (plan_serial_fmm).
  std::vector<double> owned(plan.partition->owned_size(), 0.0);
  const auto add_costs = [&](const fmm::LaplaceFmm& fmm) {
    const std::vector<double> costs = fmm.last_target_costs();
    for (std::size_t i = 0; i < std::min(costs.size(), owned.size()); ++i) owned[i] += costs[i];
  };
  if (!plan.split && plan.sources > 0) add_costs(plan.fmm);
  if (plan.own_runs) add_costs(plan.own_fmm);
  if (plan.received_runs) add_costs(plan.received_fmm);
  const Column column{owned, 1};
  return plan.partition->to_origin(std::span<const Column>(&column, 1))[0];
}

void DistributedLaplaceFmm::evaluate(std::span<const double> charges, std::size_t nd, unsigned outputs,
                                     std::span<double> results) const {
  const std::vector<unsigned> flags(nd, outputs);
  evaluate(charges, nd, flags, results);
}

}  // namespace rpyfmm::mpi
