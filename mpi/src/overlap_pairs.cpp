// rpyfmm — the overlap correction of DistributedFmmRpy: halo exchange, pair search and the
// corrections of each product (overlap_pairs.hpp).
#include "overlap_pairs.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>

#include "alltoallv.hpp"
#include "cell_tree.hpp"
#include "fmm_plan.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/rpy_kernel.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"
#include "stage_timer.hpp"

namespace rpyfmm::mpi::detail {
namespace {

constexpr const char* kWhere = "rpyfmm::mpi::DistributedFmmRpy::set_positions";
constexpr const char* kApply = "rpyfmm::mpi::DistributedFmmRpy::apply";
// Particles per leaf of the cell tree whose cover is the region published to the other ranks.
constexpr std::size_t kRegionCellCapacity = 32;
// The halo test uses a distance a hair larger than a_j + a_max: a particle sent in excess is only
// tested again by the pair search, one missed would lose a pair.
constexpr double kHaloSlack = 1.0 + 0x1p-40;
// A halo particle as sent: position, radius and global index (exact as a double below 2^53).
constexpr std::size_t kHaloRecord = 5;
constexpr std::uint64_t kDoubleBytes = sizeof(double);
// At most 2^20 grid cells per axis (keys of 3 x 21 bits).
constexpr int kGridBits = 21;
constexpr double kMaxCellsPerAxis = 0x1p20;

std::vector<std::uint64_t> keys_of(const SfcPartition& partition) {
  std::vector<std::uint64_t> keys;
  keys.reserve(partition.owned_size());
  for (const SfcKey& k : partition.owned()) keys.push_back(k.key);
  return keys;
}

// The box around all boxes of a region (a quick test before the boxes one by one).
Box hull(const std::vector<Box>& boxes) {
  Box h = boxes.front();
  for (const Box& b : boxes) {
    for (std::size_t d = 0; d < 3; ++d) {
      h.lo[d] = std::min(h.lo[d], b.lo[d]);
      h.hi[d] = std::max(h.hi[d], b.hi[d]);
    }
  }
  return h;
}

// Whether point p lies closer than `reach` to a box of the region.
bool near_region(const double* p, double reach, const std::vector<Box>& boxes, const Box& around) {
  const Cube point{{p[0], p[1], p[2]}, 0.0};
  if (distance(point, around) >= reach) return false;
  return std::any_of(boxes.begin(), boxes.end(), [&](const Box& b) { return distance(point, b) < reach; });
}

// A uniform grid over the points with cells of side >= 2 a_max: the overlapping partners of a
// particle lie in its own cell or the 26 around it. Points sorted by (cell key, index).
class PairGrid {
 public:
  PairGrid(std::span<const double> points, double a_max) {
    const std::size_t n = points.size() / 3;
    lo_ = {points[0], points[1], points[2]};
    std::array<double, 3> hi = lo_;
    for (std::size_t i = 0; i < 3 * n; ++i) {
      lo_[i % 3] = std::min(lo_[i % 3], points[i]);
      hi[i % 3] = std::max(hi[i % 3], points[i]);
    }
    double extent = 0.0;
    for (std::size_t d = 0; d < 3; ++d) extent = std::max(extent, hi[d] - lo_[d]);
    side_ = std::max(2.0 * a_max, extent / kMaxCellsPerAxis);
    sorted_.resize(n);
    for (std::size_t i = 0; i < n; ++i) sorted_[i] = {key(cell(&points[3 * i])), i};
    std::sort(sorted_.begin(), sorted_.end());
  }

  // Calls visit(j) for every point in the cells around p's (its own included), in a fixed order.
  template <class Visit>
  void for_each_near(const double* p, Visit&& visit) const {
    const std::array<std::int64_t, 3> c = cell(p);
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy)
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
          const std::array<std::int64_t, 3> q{c[0] + dx, c[1] + dy, c[2] + dz};
          if (std::any_of(q.begin(), q.end(), [](std::int64_t v) { return v < 0 || v >= (1 << kGridBits); })) continue;
          const std::uint64_t k = key(q);
          auto it = std::lower_bound(sorted_.begin(), sorted_.end(), std::pair<std::uint64_t, std::size_t>{k, 0});
          for (; it != sorted_.end() && it->first == k; ++it) visit(it->second);
        }
  }

 private:
  [[nodiscard]] std::array<std::int64_t, 3> cell(const double* p) const {
    std::array<std::int64_t, 3> c{};
    for (std::size_t d = 0; d < 3; ++d) {
      const double v = std::floor((p[d] - lo_[d]) / side_);
      c[d] = static_cast<std::int64_t>(std::min(v, static_cast<double>((1 << kGridBits) - 1)));
    }
    return c;
  }
  [[nodiscard]] static std::uint64_t key(const std::array<std::int64_t, 3>& c) {
    return (static_cast<std::uint64_t>(c[0]) << (2 * kGridBits)) | (static_cast<std::uint64_t>(c[1]) << kGridBits) |
           static_cast<std::uint64_t>(c[2]);
  }

  std::array<double, 3> lo_{};
  double side_ = 1.0;
  std::vector<std::pair<std::uint64_t, std::size_t>> sorted_;
};

// The correction of the pair (i, j) at d = x_i - x_j, or nothing when it does not overlap.
bool pair_correction(const double* d, double ai, double aj, OverlapPair& pair) {
  const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  const double r = std::sqrt(r2);
  if (!(r < ai + aj)) return false;
  const rpy::RpyScalars exact = rpy::rpy_scalars(r, ai, aj);
  if (r2 == 0.0) {  // coincident: no Laplace term to take back
    pair.df = exact.f;
    pair.dgr = 0.0;
    return true;
  }
  double f = 0.0, g = 0.0;
  far_form_scalars(r, ai, aj, f, g);
  pair.df = exact.f - f;
  pair.dgr = (exact.g - g) / r2;
  return true;
}

}  // namespace

RotationCorrection rotation_correction(double r, double ai, double aj) {
  const rpy::RpyRotationScalars exact = rpy::rpy_rotation_scalars(r, ai, aj);
  if (r == 0.0) return {0.0, 0.0, exact.h, 0.0};  // coincident: no Laplace term to take back
  const rpy::RpyRotationScalars far = rpy::rpy_rotation_far(r);
  return {(exact.ut - far.ut) / r, (exact.wf - far.wf) / r, exact.h - far.h, (exact.k - far.k) / (r * r)};
}

void far_form_scalars(double r, double ai, double aj, double& f, double& g) {
  const double c = rpy::rpy_detail::inv_8pi / r;
  const double s = (ai * ai + aj * aj) / (r * r);
  f = c * (1.0 + s / 3.0);
  g = c * (1.0 - s);
}

OverlapCorrection::OverlapCorrection(const Communicator& comm, std::span<const double> x, std::span<const double> a,
                                     double a_max, const RoundingLimits& limits)
    : comm_(comm) {
  const Column columns[] = {{x, 3}, {a, 1}};
  std::vector<std::vector<double>> owned;
  timed(traffic_.setup_seconds, [&] {
    partition_ = std::make_unique<SfcPartition>(comm_.get(), x);
    owned = partition_->to_owners(columns);
  });
  owned_n_ = partition_->owned_size();
  for (const SfcKey& k : partition_->owned()) index_.push_back(k.index);
  exchange_halo(owned[0], owned[1], a_max);
  find_pairs(owned[1], a_max);
  comm_.run([&] { require_resolvable(limits); });
  const std::uint64_t mine = pairs_.size();
  timed(traffic_.setup_seconds, [&] {
    check_mpi(MPI_Allreduce(&mine, &global_pairs_, 1, MPI_UINT64_T, MPI_SUM, comm_.get()), "MPI_Allreduce");
  });
}

void OverlapCorrection::exchange_halo(std::span<const double> owned_x, std::span<const double> owned_a, double a_max) {
  std::uint64_t bytes = 0;
  const CellTree tree = build_cell_tree(keys_of(*partition_), owned_x, kRegionCellCapacity);
  std::vector<std::vector<Box>> regions;
  timed(traffic_.setup_seconds, [&] { regions = gather_regions(comm_, tree, bytes); });
  const auto ranks = static_cast<std::size_t>(comm_.size());
  sent_.assign(ranks, {});
  std::vector<std::vector<double>> send(ranks);
  std::vector<std::uint64_t> counts(ranks, 0), recv(ranks, 0);
  for (std::size_t r = 0; r < ranks; ++r) {
    if (static_cast<int>(r) == comm_.rank() || regions[r].empty()) continue;
    const Box around = hull(regions[r]);
    for (std::size_t j = 0; j < owned_n_; ++j) {
      if (!near_region(&owned_x[3 * j], (owned_a[j] + a_max) * kHaloSlack, regions[r], around)) continue;
      sent_[r].push_back(j);
      send[r].insert(send[r].end(), {owned_x[3 * j], owned_x[3 * j + 1], owned_x[3 * j + 2], owned_a[j],
                                     static_cast<double>(index_[j])});
    }
    counts[r] = sent_[r].size();
  }
  timed(traffic_.setup_seconds, [&] {
    check_mpi(MPI_Alltoall(counts.data(), 1, MPI_UINT64_T, recv.data(), 1, MPI_UINT64_T, comm_.get()), "MPI_Alltoall");
  });
  halo_counts_.assign(recv.begin(), recv.end());
  std::vector<std::size_t> recv_doubles(ranks);
  for (std::size_t r = 0; r < ranks; ++r) recv_doubles[r] = kHaloRecord * halo_counts_[r];
  std::vector<double> halo;
  timed(traffic_.setup_seconds, [&] { halo = alltoallv(comm_, send, recv_doubles, kWhere, "halo particles"); });
  halo_n_ = halo.size() / kHaloRecord;
  points_.assign(owned_x.begin(), owned_x.end());
  radii_.assign(owned_a.begin(), owned_a.end());
  for (std::size_t k = 0; k < halo_n_; ++k) {
    const double* record = &halo[kHaloRecord * k];
    points_.insert(points_.end(), record, record + 3);
    radii_.push_back(record[3]);
    index_.push_back(static_cast<std::uint64_t>(record[4]));
  }
}

void OverlapCorrection::find_pairs(std::span<const double> owned_a, double a_max) {
  first_.assign(owned_n_ + 1, 0);
  pairs_.clear();
  if (owned_n_ == 0) return;
  const PairGrid grid(points_, a_max);
  std::vector<std::vector<OverlapPair>> of(owned_n_);
  const auto m = static_cast<std::int64_t>(owned_n_);
#pragma omp parallel for schedule(dynamic, 64)
  for (std::int64_t ii = 0; ii < m; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    const double* xi = &points_[3 * i];
    grid.for_each_near(xi, [&](std::size_t j) {
      if (j == i) return;
      const double d[3] = {xi[0] - points_[3 * j], xi[1] - points_[3 * j + 1], xi[2] - points_[3 * j + 2]};
      OverlapPair pair;
      pair.j = j;
      if (pair_correction(d, owned_a[i], radii_[j], pair)) of[i].push_back(pair);
    });
  }
  for (std::size_t i = 0; i < owned_n_; ++i) {
    pairs_.insert(pairs_.end(), of[i].begin(), of[i].end());
    first_[i + 1] = pairs_.size();
  }
}

double cancellation_error(const double* d, double ai, double aj, double reach) {
  const double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  if (r2 == 0.0) return 0.0;  // coincident: no Laplace term
  const double r = std::sqrt(r2), a = std::max(ai, aj);
  return 0x1p-52 * a * ((ai * ai + aj * aj) / (r2 * r) + reach / r2);
}

void OverlapCorrection::require_resolvable(const RoundingLimits& limits) const {
  std::size_t worst_i = 0, worst_k = 0;
  double worst = 0.0;
  for (std::size_t i = 0; i < owned_n_; ++i) {
    const double* xi = &points_[3 * i];
    for (std::size_t k = first_[i]; k < first_[i + 1]; ++k) {
      const double* xj = &points_[3 * pairs_[k].j];
      const double d[3] = {xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]};
      const double e = cancellation_error(d, radii_[i], radii_[pairs_[k].j], limits.reach);
      if (e > worst) worst = e, worst_i = i, worst_k = k;
    }
  }
  if (worst <= limits.tolerance) return;
  const std::size_t j = pairs_[worst_k].j;
  double r2 = 0.0;
  for (std::size_t c = 0; c < 3; ++c) r2 += std::pow(points_[3 * worst_i + c] - points_[3 * j + c], 2);
  fail(ErrorCode::not_supported, kWhere,
       "particles " + std::to_string(index_[worst_i]) + " and " + std::to_string(index_[j]) + " (radii " +
           format_number(radii_[worst_i]) + " and " + format_number(radii_[j]) + ") overlap at distance " +
           format_number(std::sqrt(r2)) +
           ": the Laplace sums give such a pair its far form, up to (a / r)^3 times its exact block, and the "
           "rounding left after the overlap correction takes it back (estimated " +
           format_number(worst) + ") exceeds the tolerance " + format_number(limits.tolerance) +
           " (coincident points are exact; rpyfmm::mpi::DistributedDirectRpy sums any pair exactly)");
}

std::vector<std::vector<double>> OverlapCorrection::owned_and_halo(std::span<const Column> columns) const {
  const StopWatch watch;
  std::vector<std::vector<double>> values = partition_->to_owners(columns);
  std::size_t width = 0;
  for (const Column& c : columns) width += c.per;
  traffic_.add_bytes_received += width * owned_n_ * kDoubleBytes;
  const auto ranks = static_cast<std::size_t>(comm_.size());
  std::vector<std::vector<double>> send(ranks);
  std::vector<std::size_t> recv_doubles(ranks);
  for (std::size_t r = 0; r < ranks; ++r) {
    for (std::size_t j : sent_[r]) {
      for (std::size_t c = 0; c < columns.size(); ++c) {
        const double* v = &values[c][columns[c].per * j];
        send[r].insert(send[r].end(), v, v + columns[c].per);
      }
    }
    recv_doubles[r] = width * halo_counts_[r];
  }
  const std::vector<double> halo = alltoallv(comm_, send, recv_doubles, kApply, "halo loads");
  traffic_.add_seconds += watch.seconds();
  traffic_.halo_bytes_received = halo.size() * kDoubleBytes;
  traffic_.add_bytes_received += traffic_.halo_bytes_received;
  for (std::size_t q = 0; q < halo_n_; ++q) {
    const double* record = &halo[width * q];
    for (std::size_t c = 0; c < columns.size(); ++c) {
      values[c].insert(values[c].end(), record, record + columns[c].per);
      record += columns[c].per;
    }
  }
  return values;
}

std::vector<std::vector<double>> OverlapCorrection::to_origin(std::span<const Column> columns) const {
  std::vector<std::vector<double>> back;
  timed(traffic_.add_seconds, [&] { back = partition_->to_origin(columns); });
  for (const std::vector<double>& column : back) traffic_.add_bytes_received += column.size() * kDoubleBytes;
  return back;
}

void OverlapCorrection::add_translation(std::size_t i, const double* f, double* ui) const {
  const double* xi = &points_[3 * i];
  for (std::size_t k = first_[i]; k < first_[i + 1]; ++k) {
    const OverlapPair& p = pairs_[k];
    const double* xj = &points_[3 * p.j];
    const double* fj = &f[3 * p.j];
    const double d[3] = {xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]};
    const double df = p.dgr * (d[0] * fj[0] + d[1] * fj[1] + d[2] * fj[2]);
    for (std::size_t c = 0; c < 3; ++c) ui[c] += p.df * fj[c] + df * d[c];
  }
}

void OverlapCorrection::add_rotation(std::size_t i, const double* f, const double* t, double* ui, double* wi) const {
  const double* xi = &points_[3 * i];
  for (std::size_t k = first_[i]; k < first_[i + 1]; ++k) {
    const std::size_t j = pairs_[k].j;
    const double* xj = &points_[3 * j];
    const double* fj = &f[3 * j];
    const double* tj = &t[3 * j];
    const double d[3] = {xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]};
    const double r = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const RotationCorrection q = rotation_correction(r, radii_[i], radii_[j]);
    const double dt = q.k * (d[0] * tj[0] + d[1] * tj[1] + d[2] * tj[2]);
    for (std::size_t c = 0; c < 3; ++c) {
      const std::size_t c1 = (c + 1) % 3, c2 = (c + 2) % 3;
      ui[c] += q.ut * (tj[c1] * d[c2] - tj[c2] * d[c1]);
      wi[c] += q.wf * (fj[c1] * d[c2] - fj[c2] * d[c1]) + q.h * tj[c] + dt * d[c];
    }
  }
}

void OverlapCorrection::add(std::span<const double> f, std::span<double> u, std::size_t nrhs) const {
  traffic_ = OverlapTraffic{traffic_.setup_seconds};
  if (global_pairs_ == 0) return;
  const std::size_t n3 = f.size() / nrhs;
  std::vector<Column> in;
  for (std::size_t r = 0; r < nrhs; ++r) in.push_back({f.subspan(r * n3, n3), 3});
  const std::vector<std::vector<double>> loads = owned_and_halo(in);
  std::vector<std::vector<double>> correction(nrhs, std::vector<double>(3 * owned_n_, 0.0));
  const auto m = static_cast<std::int64_t>(owned_n_);
#pragma omp parallel for schedule(static)
  for (std::int64_t ii = 0; ii < m; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    for (std::size_t r = 0; r < nrhs; ++r) add_translation(i, loads[r].data(), &correction[r][3 * i]);
  }
  std::vector<Column> out;
  for (const auto& c : correction) out.push_back({c, 3});
  const std::vector<std::vector<double>> back = to_origin(out);
  for (std::size_t r = 0; r < nrhs; ++r)
    for (std::size_t k = 0; k < back[r].size(); ++k) u[r * n3 + k] += back[r][k];
}

void OverlapCorrection::add(std::span<const double> f, std::span<const double> t, std::span<double> u,
                            std::span<double> w) const {
  traffic_ = OverlapTraffic{traffic_.setup_seconds};
  if (global_pairs_ == 0) return;
  const Column in[] = {{f, 3}, {t, 3}};
  const std::vector<std::vector<double>> loads = owned_and_halo(in);
  std::vector<double> cu(3 * owned_n_, 0.0), cw(3 * owned_n_, 0.0);
  const auto m = static_cast<std::int64_t>(owned_n_);
#pragma omp parallel for schedule(static)
  for (std::int64_t ii = 0; ii < m; ++ii) {
    const auto i = static_cast<std::size_t>(ii);
    add_translation(i, loads[0].data(), &cu[3 * i]);
    add_rotation(i, loads[0].data(), loads[1].data(), &cu[3 * i], &cw[3 * i]);
  }
  const Column out[] = {{cu, 3}, {cw, 3}};
  const std::vector<std::vector<double>> back = to_origin(out);
  for (std::size_t k = 0; k < back[0].size(); ++k) {
    u[k] += back[0][k];
    w[k] += back[1][k];
  }
}

}  // namespace rpyfmm::mpi::detail
