// rpyfmm — DistributedLaplaceFmm: partition, locally essential tree, per-evaluation exchange of
// equivalent and halo charges, and the serial FMM on each owner (laplace_fmm.hpp, docs/mpi.md).
#include "rpyfmm/mpi/laplace_fmm.hpp"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <string>
#include <vector>

#include "cell_tree.hpp"
#include "chebyshev.hpp"
#include "essential_tree.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/partition.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "rpyfmm::mpi::DistributedLaplaceFmm";
constexpr const char* kSetPoints = "rpyfmm::mpi::DistributedLaplaceFmm::set_points";
constexpr const char* kEvaluate = "rpyfmm::mpi::DistributedLaplaceFmm::evaluate";
// Boxes per rank in the published cover of its region (region_cover): more boxes describe a
// region more tightly (fewer cells opened for it) at 48 bytes each in the all-gather.
constexpr std::size_t kRegionBoxes = 64;
constexpr std::size_t kBoxDoubles = 6;   // lo, hi
constexpr std::size_t kCubeDoubles = 5;  // center, half-side, order

// Runs `body` and adds its wall time to times[name].
template <class Body>
void timed(StageTimes& times, const char* name, Body&& body) {
  const StopWatch sw;
  body();
  times[name] += sw.seconds();
}

// Exclusive prefix sums as MPI's int displacements; throws (not collective) beyond INT_MAX.
std::vector<int> int_counts(std::span<const std::size_t> counts, std::vector<int>& displs, const char* what) {
  std::vector<int> c(counts.size());
  displs.assign(counts.size(), 0);
  std::size_t sum = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    displs[r] = static_cast<int>(sum);
    c[r] = static_cast<int>(counts[r]);
    sum += counts[r];
    require(sum <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, kWhere,
            std::string(what) + " exceed MPI's int counts");
  }
  return c;
}

// One MPI_Alltoallv of doubles: send[r] to rank r; returns what came from each rank, concatenated
// in rank order, with recv_counts (doubles per rank). Collective; sizes checked collectively.
std::vector<double> alltoallv(const Communicator& comm, const std::vector<std::vector<double>>& send,
                              std::span<const std::size_t> recv_counts, const char* what) {
  std::vector<std::size_t> send_counts(send.size());
  for (std::size_t r = 0; r < send.size(); ++r) send_counts[r] = send[r].size();
  std::vector<int> sc, sd, rc, rd;
  comm.run([&] {
    sc = int_counts(send_counts, sd, what);
    rc = int_counts(recv_counts, rd, what);
  });
  std::vector<double> packed(static_cast<std::size_t>(sd.empty() ? 0 : sd.back() + sc.back()));
  for (std::size_t r = 0; r < send.size(); ++r) std::copy(send[r].begin(), send[r].end(), packed.begin() + sd[r]);
  std::vector<double> received(static_cast<std::size_t>(rd.empty() ? 0 : rd.back() + rc.back()));
  check_mpi(MPI_Alltoallv(packed.data(), sc.data(), sd.data(), MPI_DOUBLE, received.data(), rc.data(), rd.data(),
                          MPI_DOUBLE, comm.get()),
            "MPI_Alltoallv");
  return received;
}

void check_options(const DistributedFmmOptions& o) {
  require(o.fmm.near_field && !o.fmm.export_direct_far, ErrorCode::invalid_argument, kWhere,
          "the serial FMM must evaluate the near field (near_field = true, export_direct_far = false)");
  require(o.separation == 0.0 || (o.separation >= 1.0 && o.separation <= 100.0), ErrorCode::invalid_argument, kWhere,
          "separation must be 0 (automatic) or in [1, 100], got " + format_number(o.separation));
  require(o.chebyshev_order >= 0 && o.chebyshev_order <= 32, ErrorCode::invalid_argument, kWhere,
          "chebyshev_order must be 0 (automatic) or in [1, 32], got " + std::to_string(o.chebyshev_order));
  (void)fmm::LaplaceFmm(o.fmm);  // the serial FMM's own checks
}

// The options as numbers, compared between ranks.
std::vector<double> option_signature(const DistributedFmmOptions& o) {
  return {o.fmm.tolerance,  static_cast<double>(o.fmm.leaf_capacity), o.fmm.min_leaf_side,
          o.fmm.root_scale, static_cast<double>(o.fmm.order),         static_cast<double>(o.fmm.fitted_grid.occupancy),
          o.separation,     static_cast<double>(o.chebyshev_order),   static_cast<double>(o.cell_capacity)};
}

// Collective: whether every rank passed the same values (min and max of each entry agree).
bool same_on_every_rank(const Communicator& comm, std::vector<double> values) {
  const std::size_t n = values.size();
  for (std::size_t i = 0; i < n; ++i) values.push_back(-values[i]);
  std::vector<double> seen(values.size());
  check_mpi(MPI_Allreduce(values.data(), seen.data(), static_cast<int>(values.size()), MPI_DOUBLE, MPI_MIN, comm.get()),
            "MPI_Allreduce");
  for (std::size_t i = 0; i < n; ++i) {
    if (seen[i] != -seen[n + i]) return false;
  }
  return true;
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

namespace {

std::size_t cube_nodes(int order) {
  const auto p = static_cast<std::size_t>(order);
  return p * p * p;
}

}  // namespace

struct DistributedLaplaceFmm::Plan {
  std::unique_ptr<SfcPartition> partition;
  std::vector<double> owned_x;  // 3 per owned source, in the owned (key) order
  // Separate targets: their own partition and the owned targets; null and empty at the sources.
  std::unique_ptr<SfcPartition> target_partition;
  std::vector<double> owned_targets;
  detail::CellTree tree;
  // Per rank: the cells this rank sends to it, with the slot of each compressed one in `jobs`; the
  // particles, cells and nodes it receives from it.
  std::vector<detail::EssentialCells> sent;
  std::vector<std::vector<std::size_t>> slots;
  std::vector<std::size_t> recv_halo, recv_cells, recv_nodes;
  // The distinct (cell, order) compressed for any rank, increasing, and the offset of each one's
  // equivalent charges in units of nd values (the sum of the earlier ones' p^3).
  std::vector<detail::Compressed> jobs;
  std::vector<std::size_t> job_offset;
  std::size_t sources = 0;  // of the serial FMM: owned + halo + equivalent nodes; 0 when it does not run
  fmm::LaplaceFmm fmm;

  // The partition and owned positions of the targets (the sources' when evaluating at them).
  [[nodiscard]] const SfcPartition& targets() const { return target_partition ? *target_partition : *partition; }
  [[nodiscard]] const std::vector<double>& target_x() const { return target_partition ? owned_targets : owned_x; }
};

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

// Collective: every rank's cover of its region (region_cover), by rank: one all-gather of counts and
// one of the boxes.
std::vector<std::vector<detail::Box>> gather_regions(const Communicator& comm, const detail::CellTree& tree,
                                                     std::uint64_t& bytes) {
  const std::vector<detail::Box> mine = detail::region_cover(tree, kRegionBoxes);
  const auto ranks = static_cast<std::size_t>(comm.size());
  const int count = static_cast<int>(kBoxDoubles * mine.size());
  std::vector<int> counts(ranks), displs(ranks);
  check_mpi(MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, comm.get()), "MPI_Allgather");
  std::partial_sum(counts.begin(), counts.end() - 1, displs.begin() + 1);
  std::vector<double> packed, all(static_cast<std::size_t>(displs.back() + counts.back()));
  for (const detail::Box& b : mine) {
    packed.insert(packed.end(), b.lo.begin(), b.lo.end());
    packed.insert(packed.end(), b.hi.begin(), b.hi.end());
  }
  check_mpi(MPI_Allgatherv(packed.data(), count, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE,
                           comm.get()),
            "MPI_Allgatherv");
  bytes += all.size() * sizeof(double);
  std::vector<std::vector<detail::Box>> regions(ranks);
  for (std::size_t r = 0; r < ranks; ++r) {
    for (int i = displs[r]; i < displs[r] + counts[r]; i += static_cast<int>(kBoxDoubles)) {
      const double* v = all.data() + i;
      regions[r].push_back(detail::Box{{v[0], v[1], v[2]}, {v[3], v[4], v[5]}});
    }
  }
  return regions;
}

// The cells this rank sends to every other rank, the distinct (cell, order) compressed, and the
// slot of each sent one among them.
void select_cells(DistributedLaplaceFmm::Plan& plan, const std::vector<std::vector<detail::Box>>& regions, int rank,
                  const detail::Acceptance& acceptance) {
  plan.sent.assign(regions.size(), {});
  for (std::size_t r = 0; r < regions.size(); ++r) {
    if (static_cast<int>(r) == rank) continue;
    plan.sent[r] = detail::essential_cells(plan.tree, regions[r], acceptance);
    plan.jobs.insert(plan.jobs.end(), plan.sent[r].compressed.begin(), plan.sent[r].compressed.end());
  }
  std::sort(plan.jobs.begin(), plan.jobs.end());
  plan.jobs.erase(std::unique(plan.jobs.begin(), plan.jobs.end()), plan.jobs.end());
  plan.job_offset.assign(plan.jobs.size() + 1, 0);
  for (std::size_t j = 0; j < plan.jobs.size(); ++j)
    plan.job_offset[j + 1] = plan.job_offset[j] + cube_nodes(plan.jobs[j].order);
  plan.slots.assign(regions.size(), {});
  for (std::size_t r = 0; r < regions.size(); ++r) {
    for (const detail::Compressed& c : plan.sent[r].compressed) {
      plan.slots[r].push_back(
          static_cast<std::size_t>(std::lower_bound(plan.jobs.begin(), plan.jobs.end(), c) - plan.jobs.begin()));
    }
  }
}

// The geometry sent to rank r: the halo particles' positions, then each compressed cell's cube.
std::vector<double> geometry_for(const DistributedLaplaceFmm::Plan& plan, std::size_t r, std::size_t& halo) {
  std::vector<double> out;
  halo = 0;
  for (std::uint32_t c : plan.sent[r].halo) {
    const detail::Cell& cell = plan.tree.cells[c];
    out.insert(out.end(), plan.owned_x.begin() + static_cast<std::ptrdiff_t>(3 * cell.begin),
               plan.owned_x.begin() + static_cast<std::ptrdiff_t>(3 * cell.end));
    halo += cell.size();
  }
  for (const detail::Compressed& c : plan.sent[r].compressed) {
    const detail::Cube cube = detail::cell_cube(plan.tree.cells[c.cell]);
    out.insert(out.end(), {cube.center[0], cube.center[1], cube.center[2], cube.half, static_cast<double>(c.order)});
  }
  return out;
}

// Collective: the locally essential geometry (halo positions and cubes) from every rank; returns
// the serial FMM's sources: owned, then per rank in rank order its halo particles and the nodes of
// its cells.
std::vector<double> exchange_geometry(const Communicator& comm, DistributedLaplaceFmm::Plan& plan,
                                      std::uint64_t& bytes) {
  const auto ranks = static_cast<std::size_t>(comm.size());
  std::vector<std::vector<double>> send(ranks);
  std::vector<std::uint64_t> counts(2 * ranks), recv(2 * ranks);  // (halo particles, cells) per rank
  for (std::size_t r = 0; r < ranks; ++r) {
    send[r] = geometry_for(plan, r, counts[2 * r]);
    counts[2 * r + 1] = plan.sent[r].compressed.size();
  }
  check_mpi(MPI_Alltoall(counts.data(), 2, MPI_UINT64_T, recv.data(), 2, MPI_UINT64_T, comm.get()), "MPI_Alltoall");
  plan.recv_halo.resize(ranks);
  plan.recv_cells.resize(ranks);
  std::vector<std::size_t> recv_doubles(ranks);
  for (std::size_t r = 0; r < ranks; ++r) {
    plan.recv_halo[r] = recv[2 * r];
    plan.recv_cells[r] = recv[2 * r + 1];
    recv_doubles[r] = 3 * plan.recv_halo[r] + kCubeDoubles * plan.recv_cells[r];
  }
  const std::vector<double> got = alltoallv(comm, send, recv_doubles, "the essential tree's geometry");
  bytes += got.size() * sizeof(double);

  std::vector<double> sources = plan.owned_x, cell_nodes;
  plan.recv_nodes.assign(ranks, 0);
  std::size_t at = 0;
  for (std::size_t r = 0; r < ranks; ++r) {
    sources.insert(sources.end(), got.begin() + static_cast<std::ptrdiff_t>(at),
                   got.begin() + static_cast<std::ptrdiff_t>(at + 3 * plan.recv_halo[r]));
    at += 3 * plan.recv_halo[r];
    for (std::size_t c = 0; c < plan.recv_cells[r]; ++c, at += kCubeDoubles) {
      const detail::Cube cube{{got[at], got[at + 1], got[at + 2]}, got[at + 3]};
      const int order = static_cast<int>(got[at + 4]);
      cell_nodes.resize(3 * cube_nodes(order));
      detail::chebyshev_nodes(cube, order, cell_nodes);
      sources.insert(sources.end(), cell_nodes.begin(), cell_nodes.end());
      plan.recv_nodes[r] += cube_nodes(order);
    }
  }
  return sources;
}

}  // namespace

namespace {

std::vector<std::uint64_t> owned_keys(const SfcPartition& partition) {
  std::vector<std::uint64_t> keys;
  keys.reserve(partition.owned_size());
  for (const SfcKey& k : partition.owned()) keys.push_back(k.key);
  return keys;
}

// The locally essential tree's counts in the statistics.
void count_essential(const DistributedLaplaceFmm::Plan& plan, FmmCommunication& stats) {
  for (std::size_t r = 0; r < plan.sent.size(); ++r) {
    for (std::uint32_t c : plan.sent[r].halo) stats.halo_sent += plan.tree.cells[c].size();
    for (const detail::Compressed& c : plan.sent[r].compressed) stats.nodes_sent += cube_nodes(c.order);
    stats.cells_sent += plan.sent[r].compressed.size();
    stats.halo_received += plan.recv_halo[r];
    stats.cells_received += plan.recv_cells[r];
    stats.nodes_received += plan.recv_nodes[r];
  }
}

// Collective: partitions the sources (and separate targets, when any rank passes one) and moves
// their positions to the owners, next to the origin (shift_to_centre).
void partition_points(const Communicator& comm, DistributedLaplaceFmm::Plan& plan, std::span<const double> sources,
                      std::span<const double> targets, std::span<const double> weights) {
  plan.partition = std::make_unique<SfcPartition>(comm.get(), sources, weights);
  const Column source_column[] = {{sources, 3}};
  plan.owned_x = plan.partition->to_owners(source_column)[0];
  const int mine = targets.empty() ? 0 : 1;
  int separate = 0;
  check_mpi(MPI_Allreduce(&mine, &separate, 1, MPI_INT, MPI_MAX, comm.get()), "MPI_Allreduce");
  if (separate != 0) {
    plan.target_partition = std::make_unique<SfcPartition>(comm.get(), targets);
    const Column target_column[] = {{targets, 3}};
    plan.owned_targets = plan.target_partition->to_owners(target_column)[0];
  }
  shift_to_centre(comm, plan.owned_x, plan.owned_targets);
}

// Collective: the serial FMM on this rank's essential sources and owned targets; none where either
// is empty (its targets' results are then 0). Targets at the sources when nothing came from the
// other ranks (one rank, or an isolated owner): the serial FMM's own mode, one tree of m points.
void plan_serial_fmm(const Communicator& comm, DistributedLaplaceFmm::Plan& plan, const fmm::FmmOptions& options,
                     const std::vector<double>& sources) {
  plan.fmm = fmm::LaplaceFmm(options);
  const std::vector<double>& targets = plan.target_x();
  plan.sources = sources.empty() || targets.empty() ? 0 : sources.size() / 3;
  comm.run([&] {
    if (plan.sources == 0) return;
    if (!plan.target_partition && sources.size() == plan.owned_x.size()) {
      plan.fmm.set_points(sources);
    } else {
      plan.fmm.set_points(sources, targets);
    }
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
  timed(stats_.plan_seconds, "partition",
        [&] { partition_points(comm_, *plan, local_sources, local_targets, local_weights); });
  if (plan->partition->global_size() == 0) fail(ErrorCode::invalid_input, kSetPoints, "no rank has a source");
  stats_.plan_bytes_received += (plan->owned_x.size() + plan->owned_targets.size()) * sizeof(double);

  plan->tree = detail::build_cell_tree(owned_keys(*plan->partition), plan->owned_x, cell_capacity_);
  // The region this rank publishes is that of its targets.
  const detail::CellTree target_tree =
      plan->target_partition
          ? detail::build_cell_tree(owned_keys(*plan->target_partition), plan->owned_targets, cell_capacity_)
          : detail::CellTree{};
  std::vector<std::vector<detail::Box>> regions;
  timed(stats_.plan_seconds, "summaries", [&] {
    regions = gather_regions(comm_, plan->target_partition ? target_tree : plan->tree, stats_.plan_bytes_received);
  });
  const detail::Acceptance acceptance{options_.fmm.tolerance, separation_, 32, options_.chebyshev_order};
  select_cells(*plan, regions, comm_.rank(), acceptance);
  std::vector<double> sources;
  timed(stats_.plan_seconds, "geometry",
        [&] { sources = exchange_geometry(comm_, *plan, stats_.plan_bytes_received); });
  count_essential(*plan, stats_);
  timed(stats_.compute_seconds, "plan_fmm", [&] { plan_serial_fmm(comm_, *plan, options_.fmm, sources); });
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
  for (std::size_t d = 0; d < nd; ++d) {
    require(outputs[d] >= 1 && outputs[d] <= fmm::all_outputs, ErrorCode::invalid_argument, kEvaluate,
            "outputs[" + std::to_string(d) + "] must be a non-empty subset of potential|gradient|hessian, got " +
                std::to_string(outputs[d]));
  }
  require(results.size() == nd * n_targets * fmm::result_width, ErrorCode::invalid_input, kEvaluate,
          "local results have " + std::to_string(results.size()) +
              " entries, expected nd x targets x 10 = " + std::to_string(nd * n_targets * fmm::result_width));
}

// The equivalent charges of every (cell, order) in plan.jobs: job j's nd x p^3 values at
// nd × job_offset[j].
std::vector<double> anterpolate_cells(const DistributedLaplaceFmm::Plan& plan, std::span<const double> owned_q,
                                      std::size_t nd) {
  const std::size_t m = plan.owned_x.size() / 3;
  std::vector<double> eq(nd * plan.job_offset.back());
  const auto jobs = static_cast<std::ptrdiff_t>(plan.jobs.size());
#pragma omp parallel for schedule(dynamic, 1)
  for (std::ptrdiff_t i = 0; i < jobs; ++i) {
    const auto j = static_cast<std::size_t>(i);
    const detail::Cell& cell = plan.tree.cells[plan.jobs[j].cell];
    const std::span<const double> x(plan.owned_x.data() + 3 * cell.begin, 3 * cell.size());
    const std::size_t nodes = cube_nodes(plan.jobs[j].order);
    detail::anterpolate(detail::cell_cube(cell), plan.jobs[j].order, x, owned_q.data() + cell.begin, m, nd,
                        std::span<double>(eq.data() + nd * plan.job_offset[j], nd * nodes));
  }
  return eq;
}

// The charges sent to rank r: per density, the halo particles' charges, then the cells' equivalent
// charges (the layout of exchange_geometry's sources).
std::vector<double> charges_for(const DistributedLaplaceFmm::Plan& plan, std::size_t r, std::span<const double> owned_q,
                                std::span<const double> eq, std::size_t nd) {
  const std::size_t m = plan.owned_x.size() / 3;
  std::vector<double> out;
  for (std::size_t d = 0; d < nd; ++d) {
    for (std::uint32_t c : plan.sent[r].halo) {
      const detail::Cell& cell = plan.tree.cells[c];
      out.insert(out.end(), owned_q.begin() + static_cast<std::ptrdiff_t>(d * m + cell.begin),
                 owned_q.begin() + static_cast<std::ptrdiff_t>(d * m + cell.end));
    }
    for (std::size_t slot : plan.slots[r]) {
      const std::size_t nodes = cube_nodes(plan.jobs[slot].order);
      const auto first = eq.begin() + static_cast<std::ptrdiff_t>(nd * plan.job_offset[slot] + d * nodes);
      out.insert(out.end(), first, first + static_cast<std::ptrdiff_t>(nodes));
    }
  }
  return out;
}

// The serial FMM's charges (nd x sources): owned, then per rank its received block, per density.
std::vector<double> assemble_charges(const DistributedLaplaceFmm::Plan& plan, std::span<const double> owned_q,
                                     std::span<const double> got, std::span<const std::size_t> per_density,
                                     std::size_t nd) {
  const std::size_t m = plan.owned_x.size() / 3;
  std::vector<double> q(nd * plan.sources);
  for (std::size_t d = 0; d < nd; ++d) {
    std::copy_n(owned_q.begin() + static_cast<std::ptrdiff_t>(d * m), m,
                q.begin() + static_cast<std::ptrdiff_t>(d * plan.sources));
  }
  std::size_t at = 0, offset = m;
  for (std::size_t r = 0; r < per_density.size(); ++r) {
    for (std::size_t d = 0; d < nd; ++d, at += per_density[r]) {
      std::copy_n(got.begin() + static_cast<std::ptrdiff_t>(at), per_density[r],
                  q.begin() + static_cast<std::ptrdiff_t>(d * plan.sources + offset));
    }
    offset += per_density[r];
  }
  return q;
}

}  // namespace

void DistributedLaplaceFmm::evaluate(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                                     std::span<double> results) const {
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
  timed(stats_.evaluate_seconds, "charges", [&] {
    std::vector<Column> columns;
    for (std::size_t d = 0; d < nd; ++d) columns.push_back({charges.subspan(d * n, n), 1});
    for (const std::vector<double>& c : plan.partition->to_owners(columns))
      owned_q.insert(owned_q.end(), c.begin(), c.end());
  });
  stats_.evaluate_bytes_received += owned_q.size() * sizeof(double);

  std::vector<double> eq;
  timed(stats_.compute_seconds, "anterpolation", [&] { eq = anterpolate_cells(plan, owned_q, nd); });
  const auto ranks = static_cast<std::size_t>(comm_.size());
  std::vector<std::vector<double>> send(ranks);
  std::vector<std::size_t> per_density(ranks), recv_counts(ranks);
  for (std::size_t r = 0; r < ranks; ++r) {
    send[r] = charges_for(plan, r, owned_q, eq, nd);
    per_density[r] = plan.recv_halo[r] + plan.recv_nodes[r];
    recv_counts[r] = nd * per_density[r];
  }
  std::vector<double> got;
  timed(stats_.evaluate_seconds, "essential",
        [&] { got = alltoallv(comm_, send, recv_counts, "the essential charges"); });
  stats_.evaluate_bytes_received += got.size() * sizeof(double);

  std::vector<double> owned_results(nd * m_targets * fmm::result_width, 0.0);
  timed(stats_.compute_seconds, "fmm", [&] {
    comm_.run([&] {
      if (plan.sources > 0) {
        plan.fmm.evaluate(assemble_charges(plan, owned_q, got, per_density, nd), nd, outputs, owned_results);
      }
    });
  });

  timed(stats_.evaluate_seconds, "results", [&] {
    std::vector<Column> columns;
    const std::size_t width = m_targets * fmm::result_width;
    for (std::size_t d = 0; d < nd; ++d)
      columns.push_back({std::span<const double>(owned_results).subspan(d * width, width), fmm::result_width});
    const std::vector<std::vector<double>> back = plan.targets().to_origin(columns);
    for (std::size_t d = 0; d < nd; ++d) {
      std::copy(back[d].begin(), back[d].end(),
                results.begin() + static_cast<std::ptrdiff_t>(d * n_targets * fmm::result_width));
    }
  });
  stats_.evaluate_bytes_received += nd * n_targets * fmm::result_width * sizeof(double);
}

void DistributedLaplaceFmm::evaluate(std::span<const double> charges, std::size_t nd, unsigned outputs,
                                     std::span<double> results) const {
  const std::vector<unsigned> flags(nd, outputs);
  evaluate(charges, nd, flags, results);
}

}  // namespace rpyfmm::mpi
