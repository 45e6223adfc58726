// rpyfmm — DistributedPseRpy: PseRpy's parameters for the whole set, the wave space on FFTW-MPI
// slabs and the real space on each rank's particles and halo (pse_operator.hpp, docs/mpi.md).
// [PSE]: Fiore, Balboa Usabiaga, Donev & Swan, J. Chem. Phys. 146, 124116 (2017).
#include "rpyfmm/mpi/pse_operator.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <string>

// rpy/src (private to rpyfmm::rpy and this layer): the load scaling and the wrap of the serial
// operators, so that every particle sits on the serial operator's grid points.
#include "alltoallv.hpp"
#include "krylov_space.hpp"
#include "load_scaling.hpp"
#include "particle_set.hpp"
#include "pse/kernels_common.hpp"
#include "pse/noise_hash.hpp"
#include "pse/real_space_sqrt.hpp"
#include "pse_memory.hpp"
#include "pse_real_halo.hpp"
#include "pse_slab_wave.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/mpi/sqrt.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "sqrt/krylov_space.hpp"
#include "wrap_into_box.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kWhere = "DistributedPseRpy";
constexpr const char* kSetPositions = "DistributedPseRpy::set_positions";
constexpr const char* kApply = "DistributedPseRpy::apply";

// Everything that decides the parameters and the products: it must be the same on every rank.
std::vector<double> agreed_values(const rpy::Geometry& g, double viscosity, const rpy::pse::PseOptions& o) {
  return {g.is_periodic() ? 1.0 : 0.0,
          g.box()[0],
          g.box()[1],
          g.box()[2],
          viscosity,
          o.tolerance,
          o.xi,
          o.r_cut,
          static_cast<double>(o.grid[0]),
          static_cast<double>(o.grid[1]),
          static_cast<double>(o.grid[2]),
          static_cast<double>(o.support),
          o.window_eta,
          o.lanczos_tolerance,
          o.real_space_table ? 1.0 : 0.0,
          o.real_space_cache ? 1.0 : 0.0,
          static_cast<double>(o.max_memory_bytes),
          o.cost_real_pair,
          o.cost_fft_point,
          o.cost_grid_point,
          o.cost_support_point,
          o.cost_real_products,
          o.pair_density};
}

// The split sampler's options, checked on this rank (apply_sqrt, apply_sqrt_rotation): method
// automatic or split (the generic solvers are not offered across ranks), no block preconditioner.
void check_split_options(const rpy::SqrtOptions& options, const char* where) {
  require(options.method == rpy::SqrtMethod::automatic || options.method == rpy::SqrtMethod::split,
          ErrorCode::not_supported, where,
          std::string("method '") + rpy::to_string(options.method) +
              "' is not offered across ranks (automatic or split: the PSE split sampler)");
  require(options.preconditioner != rpy::SqrtPreconditioner::block, ErrorCode::not_supported, where,
          "the block preconditioner serves the Lanczos and Chebyshev samplers only, not the split sampler");
}

}  // namespace

struct DistributedPseRpy::Impl {
  Communicator comm;
  rpy::Geometry geometry;
  double viscosity;
  rpy::pse::PseOptions options;
  rpy::pse::PseParameters params;
  std::unique_ptr<detail::SlabWaveSpace> wave;
  std::unique_ptr<detail::RealSpaceHalo> real;
  std::size_t planned_n = 0;  // the N of the plan (0: none)
  std::size_t local_n = 0, global_n = 0, offset = 0;
  std::vector<std::size_t> rank_counts;  // every rank's local N, in rank order
  std::size_t memory = 0;                // this rank's checked memory (pse_memory.hpp)
  PseExchangeCounts counts;
  // The exchanges' statistics (communication()) and the exchanges' traffic when the last product began.
  mutable CommunicationStats stats;
  mutable detail::IndexExchange::Traffic traffic_before;

  Impl(MPI_Comm c, rpy::Geometry g, double eta, const rpy::pse::PseOptions& o)
      : comm(c), geometry(g), viscosity(eta), options(o) {}

  // The slabs' and the halo's exchanges together since set_positions.
  [[nodiscard]] detail::IndexExchange::Traffic traffic() const;
  // set_positions' exchanges as communication() reports them, the products' counted from here.
  void record_set_positions() const;
  // Records the exchanges of one product (the public call that holds it) when it ends, also by an
  // exception.
  struct ProductRecord {
    const Impl& im;
    explicit ProductRecord(const Impl& owner) : im(owner) { im.traffic_before = im.traffic(); }
    ~ProductRecord();
    ProductRecord(const ProductRecord&) = delete;
    ProductRecord& operator=(const ProductRecord&) = delete;
  };

  // The rank's share in the global order (local_n, offset; one MPI_Allgather), returning N; throws
  // alike on every rank when no rank has a particle.
  [[nodiscard]] std::size_t share(std::size_t n);
  // The common radius (one MPI_Allreduce); throws alike on every rank when the radii differ.
  [[nodiscard]] double common_radius(std::span<const double> radii) const;
  // PseRpy's parameter choice for the whole set, the budget of the whole grid that of all ranks
  // together (collective only in failing alike: the same data on every rank).
  [[nodiscard]] rpy::pse::PseParameters choose(double radius) const;
  // PseRpy::on_positions_set's plan for the whole set: again when the radius changes, or N with
  // automatic xi; each rank's memory checked against the limit at every call (collective).
  void plan(double radius);
  // w = M_r^{1/2} z1 + M_w^{1/2} z2(key): the split sampler's two parts ([PSE] eqs. 17-21).
  [[nodiscard]] rpy::SqrtReport split_sample(const std::vector<double>& z1, const rpy::pse::detail::NoiseKey& key,
                                             std::span<double> w) const;
  // pse::noise_hash of the global vector whose segments are each the concatenation of the ranks'
  // shares in rank order: [z] for apply_sqrt, [z_t; z_r] with rotation (collective).
  [[nodiscard]] std::uint64_t noise_hash(std::initializer_list<std::span<const double>> local_segments) const;
  // The same for segments whose global order is given by `indices` (this rank's entries' global
  // indices, over all ranks a permutation of 0 ... N - 1): the entries are first sent to the ranks
  // holding contiguous blocks of that order (collective).
  [[nodiscard]] std::uint64_t noise_hash(std::initializer_list<std::span<const double>> local_segments,
                                         std::span<const std::uint64_t> indices, const char* where) const;
  // The hash chain h continued over one segment's pieces in rank order, rank r holding chain_counts[r]
  // particles' entries (local_z this rank's) (collective).
  [[nodiscard]] std::uint64_t chain_hash(std::uint64_t h, std::span<const double> local_z,
                                         std::span<const std::size_t> chain_counts) const;
  // The grand split sampler: Lanczos on S M_r S plus the wave noise keyed by `hash`.
  [[nodiscard]] rpy::SqrtReport grand_split_sample(std::span<const double> z_t, std::span<const double> z_r,
                                                   std::uint64_t hash, std::span<double> w_t,
                                                   std::span<double> w_r) const;
  // apply_sqrt_rotation: the wave noise keyed by the hash of [z_t; z_r] in rank order (indices
  // null) or in the order of the given global indices.
  [[nodiscard]] rpy::SqrtReport grand_sample(std::span<const double> z_t, std::span<const double> z_r,
                                             const std::span<const std::uint64_t>* indices, std::span<double> w_t,
                                             std::span<double> w_r, const rpy::SqrtOptions& sampler) const;
  // apply_sqrt_rotation's checks of this rank's arrays and options (collective).
  void check_grand_noise(std::span<const double> z_t, std::span<const double> z_r, std::span<double> w_t,
                         std::span<double> w_r, const rpy::SqrtOptions& sampler, const char* where) const;
  // Global indices of this rank's particles: one per particle, each below N (not collective).
  void check_indices(std::span<const std::uint64_t> indices, const char* where) const;
  // apply()'s and apply_with_noise's checks of this rank's arrays (collective).
  void check_arrays(std::span<const double> forces, std::span<double> velocities, const char* where) const;
  // M_r^{1/2} z1 by the serial Lanczos iteration on a distributed basis (w: 3 local_n).
  [[nodiscard]] rpy::SqrtReport real_sqrt(const std::vector<double>& z1, double* w) const;
  // (S M_r S)^{1/2} z with rotation, S = diag(I, a I), z and w this rank's [x_t; x_r] (6 local_n).
  [[nodiscard]] rpy::SqrtReport real_sqrt_rotation(const std::vector<double>& z, double* w) const;
  // apply_with_noise, z1 keyed by the rank order (indices null) or by the given global indices.
  [[nodiscard]] rpy::SqrtReport fused(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                                      std::uint64_t step, const std::span<const std::uint64_t>* indices,
                                      std::span<double> velocities) const;
};

detail::IndexExchange::Traffic DistributedPseRpy::Impl::traffic() const {
  detail::IndexExchange::Traffic sum;
  for (const detail::IndexExchange::Traffic t : {wave ? wave->traffic() : sum, real ? real->traffic() : sum}) {
    sum.seconds += t.seconds;
    sum.bytes_received += t.bytes_received;
  }
  return sum;
}

void DistributedPseRpy::Impl::record_set_positions() const {
  traffic_before = traffic();
  stats = CommunicationStats{.set_positions_seconds = traffic_before.seconds};
}

DistributedPseRpy::Impl::ProductRecord::~ProductRecord() {
  const detail::IndexExchange::Traffic now = im.traffic();
  im.stats.apply_seconds = now.seconds - im.traffic_before.seconds;
  im.stats.apply_bytes_received = now.bytes_received - im.traffic_before.bytes_received;
  im.stats.applies_seconds += im.stats.apply_seconds;
}

void DistributedPseRpy::Impl::check_indices(std::span<const std::uint64_t> indices, const char* where) const {
  require(indices.size() == local_n, ErrorCode::invalid_input, where,
          "local indices must hold one per local particle: " + std::to_string(indices.size()) + " for " +
              std::to_string(local_n));
  for (const std::uint64_t i : indices)
    require(i < global_n, ErrorCode::invalid_input, where,
            "global index " + std::to_string(i) + " is not below the number of particles " + std::to_string(global_n));
}

void DistributedPseRpy::Impl::check_arrays(std::span<const double> forces, std::span<double> velocities,
                                           const char* where) const {
  // global_n is the same on every rank (set_positions succeeds or fails on all of them).
  require(global_n > 0, ErrorCode::invalid_input, where, "positions not set (call set_positions first)");
  comm.run([&] {
    require_size(forces, 3 * local_n, where, "local forces");
    require_size(std::span<const double>(velocities.data(), velocities.size()), 3 * local_n, where, "local velocities");
    require_finite(forces, where, "local forces", 3);
  });
}

rpy::SqrtReport DistributedPseRpy::Impl::real_sqrt(const std::vector<double>& z1, double* w) const {
  const std::size_t n3 = 3 * local_n;
  // The basis distributed as the particles, its inner products reduced over the ranks
  // (krylov_space.hpp), with PseRpy's real-space options.
  DistributedKrylovSpace space(comm, rank_counts);
  const auto product = [&](const double* x, double* y) {
    std::fill(y, y + n3, 0.0);
    real->apply(comm, x, y);
  };
  return rpy::sqrt_detail::lanczos_sqrt_in_space(space, product, z1.data(), w,
                                                 rpy::pse::detail::real_space_sqrt_options(params.lanczos_tolerance));
}

rpy::SqrtReport DistributedPseRpy::Impl::split_sample(const std::vector<double>& z1,
                                                      const rpy::pse::detail::NoiseKey& key,
                                                      std::span<double> w) const {
  rpy::SqrtReport report = real_sqrt(z1, w.data());
  // + M_w^{1/2} z2 (the slabs' field of `key`).
  wave->add_noise(key, w.data(), local_n);
  report.method = rpy::SqrtMethod::split;
  report.operator_applications += 1;
  return report;
}

rpy::SqrtReport DistributedPseRpy::Impl::real_sqrt_rotation(const std::vector<double>& z, double* w) const {
  const std::size_t n3 = 3 * local_n;
  const double a = params.radius;
  // PseRpy::do_apply_sqrt_rotation's S M_r S: the translational sum and the rotational blocks over
  // its neighbour lists, on x_t and the torques a x_r, the rotational rows scaled by a. The basis
  // holds two segments, translations then rotations (krylov_space.hpp).
  DistributedKrylovSpace space(comm, rank_counts, 2);
  std::vector<double> torques(n3);
  const auto product = [&](const double* x, double* y) {
    for (std::size_t k = 0; k < n3; ++k) torques[k] = a * x[n3 + k];
    std::fill(y, y + 2 * n3, 0.0);
    real->apply_rotation(comm, x, torques.data(), y, y + n3);
    for (std::size_t k = 0; k < n3; ++k) y[n3 + k] *= a;
  };
  return rpy::sqrt_detail::lanczos_sqrt_in_space(space, product, z.data(), w,
                                                 rpy::pse::detail::real_space_sqrt_options(params.lanczos_tolerance));
}

std::uint64_t DistributedPseRpy::Impl::noise_hash(std::initializer_list<std::span<const double>> local_segments) const {
  std::uint64_t h = rpy::pse::detail::noise_hash_start(3 * global_n * local_segments.size());
  for (const std::span<const double> segment : local_segments) h = chain_hash(h, segment, rank_counts);
  return h;
}

std::uint64_t DistributedPseRpy::Impl::noise_hash(std::initializer_list<std::span<const double>> local_segments,
                                                  std::span<const std::uint64_t> indices, const char* where) const {
  // Rank r receives the entries of global indices [r b, (r + 1) b), b = ceil(N / P): the index and
  // the particle's triple of every segment, and lays them out in that order.
  const auto ranks = static_cast<std::size_t>(comm.size());
  const std::uint64_t block = (global_n + ranks - 1) / ranks;
  const std::size_t width = 1 + 3 * local_segments.size();
  std::vector<std::vector<double>> send(ranks);
  for (std::size_t i = 0; i < local_n; ++i) {
    std::vector<double>& to = send[static_cast<std::size_t>(indices[i] / block)];
    to.push_back(static_cast<double>(indices[i]));  // exact: N < 2^53
    for (const std::span<const double> segment : local_segments)
      to.insert(to.end(), segment.begin() + static_cast<std::ptrdiff_t>(3 * i),
                segment.begin() + static_cast<std::ptrdiff_t>(3 * i + 3));
  }
  const std::vector<double> received = detail::alltoallv(comm, send, where, "the noise in global order");
  const std::uint64_t first = std::min<std::uint64_t>(block * static_cast<std::uint64_t>(comm.rank()), global_n);
  const std::uint64_t mine = std::min<std::uint64_t>(block, global_n - first);
  std::vector<std::vector<double>> ordered(local_segments.size(), std::vector<double>(3 * mine));
  std::vector<char> seen(mine, 0);
  std::uint64_t repeated = global_n;
  for (std::size_t k = 0; k < received.size(); k += width) {
    const auto slot = static_cast<std::uint64_t>(received[k]) - first;
    if (seen[slot] != 0) repeated = std::min(repeated, first + slot);
    seen[slot] = 1;
    for (std::size_t s = 0; s < ordered.size(); ++s)
      std::copy_n(received.begin() + static_cast<std::ptrdiff_t>(k + 1 + 3 * s), 3, ordered[s].begin() + 3 * slot);
  }
  comm.run([&] {
    require(repeated == global_n, ErrorCode::invalid_input, where,
            "the local indices of all ranks are not a permutation of 0 ... N - 1: global index " +
                std::to_string(repeated) + " is given more than once");
  });
  std::vector<std::size_t> block_counts(ranks);
  for (std::size_t r = 0; r < ranks; ++r) {
    const std::uint64_t begin = std::min<std::uint64_t>(block * r, global_n);
    block_counts[r] = static_cast<std::size_t>(std::min<std::uint64_t>(block, global_n - begin));
  }
  std::uint64_t h = rpy::pse::detail::noise_hash_start(3 * global_n * local_segments.size());
  for (const std::vector<double>& segment : ordered) h = chain_hash(h, segment, block_counts);
  return h;
}

std::uint64_t DistributedPseRpy::Impl::chain_hash(std::uint64_t h, std::span<const double> local_z,
                                                  std::span<const std::size_t> chain_counts) const {
  // The chain passes the ranks with particles in rank order; the last of them broadcasts the end.
  constexpr int kTag = 19283;
  int previous = -1, next = -1, last = -1;
  for (int r = 0; r < comm.size(); ++r) {
    if (chain_counts[static_cast<std::size_t>(r)] == 0) continue;
    if (r < comm.rank()) previous = r;
    if (r > comm.rank() && next < 0) next = r;
    last = r;
  }
  if (chain_counts[static_cast<std::size_t>(comm.rank())] > 0) {
    if (previous >= 0) {
      check_mpi(MPI_Recv(&h, 1, MPI_UINT64_T, previous, kTag, comm.get(), MPI_STATUS_IGNORE), "MPI_Recv");
    }
    h = rpy::pse::detail::noise_hash_extend(h, local_z);
    if (next >= 0) check_mpi(MPI_Send(&h, 1, MPI_UINT64_T, next, kTag, comm.get()), "MPI_Send");
  }
  check_mpi(MPI_Bcast(&h, 1, MPI_UINT64_T, last, comm.get()), "MPI_Bcast");
  return h;
}

std::size_t DistributedPseRpy::Impl::share(std::size_t n) {
  const auto mine = static_cast<std::uint64_t>(n);
  std::vector<std::uint64_t> all(static_cast<std::size_t>(comm.size()));
  check_mpi(MPI_Allgather(&mine, 1, MPI_UINT64_T, all.data(), 1, MPI_UINT64_T, comm.get()), "MPI_Allgather");
  std::uint64_t total = 0;
  offset = 0;
  for (std::size_t r = 0; r < all.size(); ++r) {
    if (static_cast<int>(r) < comm.rank()) offset += all[r];
    total += all[r];
  }
  require(total > 0, ErrorCode::invalid_input, kSetPositions,
          "no particles on any of the " + std::to_string(comm.size()) + " ranks (N = 0)");
  local_n = n;
  rank_counts.assign(all.begin(), all.end());
  return total;
}

double DistributedPseRpy::Impl::common_radius(std::span<const double> radii) const {
  constexpr double inf = std::numeric_limits<double>::infinity();
  std::array<double, 2> local{inf, inf}, global{};  // min a, min -a
  for (const double a : radii) local = {std::min(local[0], a), std::min(local[1], -a)};
  check_mpi(MPI_Allreduce(local.data(), global.data(), 2, MPI_DOUBLE, MPI_MIN, comm.get()), "MPI_Allreduce");
  require(global[0] == -global[1], ErrorCode::not_supported, kSetPositions,
          "PSE supports equal radii only (the paper's assumption); the radii given differ (from " +
              format_number(global[0]) + " to " + format_number(-global[1]) + ")");
  return global[0];
}

rpy::pse::PseParameters DistributedPseRpy::Impl::choose(double radius) const {
  // PseRpy's choice for the whole set (the same data on every rank: it succeeds or fails alike),
  // with the memory of all ranks together as the whole grid's budget (pse_memory.hpp).
  rpy::pse::PseOptions o = options;
  o.max_memory_bytes = detail::whole_grid_budget(options.max_memory_bytes, comm.size());
  try {
    return rpy::pse::choose_parameters(o, radius, geometry.box(), global_n);
  } catch (const Error& e) {
    if (e.code() != ErrorCode::out_of_memory || comm.size() == 1) throw;
    throw Error(e.code(), std::string(e.what()) + " (the budget of the whole grid on " + std::to_string(comm.size()) +
                              " ranks: " + std::to_string(comm.size()) + " x max_memory_bytes)");
  }
}

void DistributedPseRpy::Impl::plan(double radius) {
  const bool planned = planned_n != 0 && params.radius == radius && (options.xi != 0.0 || planned_n == global_n);
  if (!planned) {
    planned_n = 0;
    wave.reset();
    real.reset();
  }
  rpy::pse::PseParameters p = planned ? params : choose(radius);
  // Double-precision grids and pair cache throughout (FFTW-MPI's double transforms).
  p.wave_single = false;
  // Each rank's slab and windows within the limit, before any allocation; at every set_positions,
  // since the windows follow this rank's share.
  memory = detail::check_rank_memory(comm, p, local_n, options.max_memory_bytes, kSetPositions);
  if (planned) return;
  // The pair cache within what the limit leaves beside this rank's slab and windows, as PseRpy
  // keeps its cache within what the limit leaves beside its grids.
  const auto cache =
      options.real_space_cache ? rpy::pse::detail::PairCache::double_precision : rpy::pse::detail::PairCache::off;
  comm.run([&] {
    real = std::make_unique<detail::RealSpaceHalo>(p, geometry.box(), viscosity, options.real_space_table, cache,
                                                   options.max_memory_bytes - memory);
  });
  wave = std::make_unique<detail::SlabWaveSpace>(comm, p, geometry.box(), viscosity);
  params = p;
  planned_n = global_n;
}

DistributedPseRpy::DistributedPseRpy(MPI_Comm comm, rpy::Geometry geometry, double viscosity,
                                     const rpy::pse::PseOptions& options)
    : impl_(std::make_unique<Impl>(comm, geometry, viscosity, options)) {
  // PseRpy's own checks of the geometry, viscosity and options, on every rank.
  impl_->comm.run([&] { const rpy::pse::PseRpy check(geometry, viscosity, options); });
  require(same_on_every_rank(impl_->comm, agreed_values(geometry, viscosity, options)), ErrorCode::invalid_argument,
          kWhere, "the ranks pass different boxes, viscosities or options; every rank must pass the same ones");
}

DistributedPseRpy::~DistributedPseRpy() = default;

const Communicator& DistributedPseRpy::communicator() const {
  return impl_->comm;
}
double DistributedPseRpy::viscosity() const {
  return impl_->viscosity;
}
const rpy::Geometry& DistributedPseRpy::geometry() const {
  return impl_->geometry;
}
std::size_t DistributedPseRpy::local_size() const {
  return impl_->global_n > 0 ? impl_->local_n : 0;
}
std::size_t DistributedPseRpy::global_size() const {
  return impl_->global_n;
}
std::size_t DistributedPseRpy::offset() const {
  return impl_->global_n > 0 ? impl_->offset : 0;
}
std::size_t DistributedPseRpy::memory_bytes() const {
  require(impl_->global_n > 0, ErrorCode::invalid_input, "DistributedPseRpy::memory_bytes",
          "positions not set (call set_positions first)");
  return impl_->memory;
}
const CommunicationStats& DistributedPseRpy::communication() const {
  return impl_->stats;
}

const PseExchangeCounts& DistributedPseRpy::exchange_counts() const {
  return impl_->counts;
}

const rpy::pse::PseParameters& DistributedPseRpy::parameters() const {
  require(impl_->global_n > 0, ErrorCode::invalid_input, "DistributedPseRpy::parameters",
          "positions not set (call set_positions first)");
  return impl_->params;
}

void DistributedPseRpy::set_positions(std::span<const double> local_positions, double radius) {
  impl_->global_n = 0;  // no positions until this call succeeds on every rank
  impl_->comm.run([&] { require_positive(radius, kSetPositions, "radius"); });
  const std::vector<double> radii(local_positions.size() / 3, radius);
  set_positions(local_positions, radii);
}

void DistributedPseRpy::set_positions(std::span<const double> local_positions, std::span<const double> local_radii) {
  Impl& im = *impl_;
  im.global_n = 0;  // no positions until this call succeeds on every rank
  im.comm.run([&] { detail::check_local_particles(local_positions, local_radii, kSetPositions); });
  const std::size_t total = im.share(local_radii.size());
  const double radius = im.common_radius(local_radii);
  // Into [0, L) as MobilityOperator::set_positions wraps them (the serial operator's grid windows).
  std::vector<double> x(local_positions.begin(), local_positions.end());
  for (std::size_t k = 0; k < x.size(); ++k) x[k] = rpy::detail::wrap_into_box(x[k], im.geometry.box()[k % 3]);
  im.global_n = total;  // plan() reads it
  try {
    im.plan(radius);
    im.wave->set_positions(x);
    im.real->set_positions(im.comm, im.geometry, x);
  } catch (...) {
    im.global_n = 0;
    throw;
  }
  im.counts = {im.wave->sent(), im.wave->received(), im.real->halo_size()};
  im.record_set_positions();
}

void DistributedPseRpy::apply(std::span<const double> local_forces, std::span<const double> local_torques,
                              std::span<double> local_velocities, std::span<double> local_angular_velocities) const {
  const Impl& im = *impl_;
  require(im.global_n > 0, ErrorCode::invalid_input, kApply, "positions not set (call set_positions first)");
  const std::size_t n3 = 3 * im.local_n;
  const Impl::ProductRecord record(im);
  im.comm.run([&] {
    require_size(local_forces, n3, kApply, "local forces");
    require_size(local_torques, n3, kApply, "local torques");
    require_size(std::span<const double>(local_velocities.data(), local_velocities.size()), n3, kApply,
                 "local velocities");
    require_size(std::span<const double>(local_angular_velocities.data(), local_angular_velocities.size()), n3, kApply,
                 "local angular velocities");
    require_finite(local_forces, kApply, "local forces", 3);
    require_finite(local_torques, kApply, "local torques", 3);
  });
  // MobilityOperator::apply's load scale for [F; T] (largest_rotation_load with the common radius),
  // from the largest load of all ranks.
  const double largest = rpy::detail::largest_rotation_load(local_forces, local_torques, im.params.radius);
  double global_largest = 0.0;
  check_mpi(MPI_Allreduce(&largest, &global_largest, 1, MPI_DOUBLE, MPI_MAX, im.comm.get()), "MPI_Allreduce");
  const int k = rpy::detail::load_scale_exponent({std::span<const double>(&global_largest, 1)});
  std::vector<double> f(n3), t(n3);
  for (std::size_t i = 0; i < n3; ++i) {
    f[i] = std::ldexp(local_forces[i], -k);
    t[i] = std::ldexp(local_torques[i], -k);
  }
  // PseRpy::do_apply_rotation: M_w [F; T], then M_r's translational and rotational blocks added.
  im.wave->apply_rotation(f.data(), t.data(), local_velocities.data(), local_angular_velocities.data(), im.local_n);
  im.real->apply_rotation(im.comm, f.data(), t.data(), local_velocities.data(), local_angular_velocities.data());
  for (double& u : local_velocities) u = std::ldexp(u, k);
  for (double& w : local_angular_velocities) w = std::ldexp(w, k);
  im.comm.run([&] {
    rpy::detail::require_finite_result(local_velocities, kApply, "velocities", "forces and torques");
    rpy::detail::require_finite_result(local_angular_velocities, kApply, "angular velocities", "forces and torques");
  });
}

void DistributedPseRpy::apply(std::span<const double> local_forces, std::span<double> local_velocities) const {
  const Impl& im = *impl_;
  im.check_arrays(local_forces, local_velocities, kApply);
  const Impl::ProductRecord record(im);
  // MobilityOperator::apply_block's load scale 2^k (exact), from the largest force of all ranks.
  double largest = 0.0, global_largest = 0.0;
  for (const double f : local_forces) largest = std::max(largest, std::abs(f));
  check_mpi(MPI_Allreduce(&largest, &global_largest, 1, MPI_DOUBLE, MPI_MAX, im.comm.get()), "MPI_Allreduce");
  const int k = rpy::detail::load_scale_exponent({std::span<const double>(&global_largest, 1)});
  std::vector<double> forces(local_forces.begin(), local_forces.end());
  for (double& f : forces) f = std::ldexp(f, -k);
  // [PSE] eq. 10: M_w F, then M_r F added (the order of PseRpy::do_apply).
  im.wave->apply(forces.data(), local_velocities.data(), im.local_n);
  im.real->apply(im.comm, forces.data(), local_velocities.data());
  for (double& u : local_velocities) u = std::ldexp(u, k);
  im.comm.run([&] { rpy::detail::require_finite_result(local_velocities, kApply, "velocities", "forces"); });
}

rpy::SqrtReport DistributedPseRpy::sample(std::uint64_t seed, std::uint64_t step, std::span<double> local_w) const {
  constexpr const char* where = "DistributedPseRpy::sample";
  const Impl& im = *impl_;
  require(im.global_n > 0, ErrorCode::invalid_input, where, "positions not set (call set_positions first)");
  const Impl::ProductRecord record(im);
  im.comm.run([&] {
    require_size(std::span<const double>(local_w.data(), local_w.size()), 3 * im.local_n, where, "local output");
  });
  // z1: PseRpy's real-space noise of this rank's particles, by global index; z2 keyed by
  // (seed, step) as PseRpy::sample keys it.
  std::vector<double> z1(3 * im.local_n);
  fill_normal(z1, im.offset, seed, step, rpy::pse::detail::kStreamReal);
  return im.split_sample(z1, {seed, step}, local_w);
}

rpy::SqrtReport DistributedPseRpy::apply_sqrt(std::span<const double> local_z, std::span<double> local_w,
                                              const rpy::SqrtOptions& options) const {
  constexpr const char* where = "DistributedPseRpy::apply_sqrt";
  const Impl& im = *impl_;
  require(im.global_n > 0, ErrorCode::invalid_input, where, "positions not set (call set_positions first)");
  const Impl::ProductRecord record(im);
  im.comm.run([&] {
    check_split_options(options, where);
    require_size(local_z, 3 * im.local_n, where, "local noise");
    require_size(std::span<const double>(local_w.data(), local_w.size()), 3 * im.local_n, where, "local output");
    require_finite(local_z, where, "local noise", 3);
  });
  // PseRpy::do_apply_sqrt: z is z1, z2 keyed by the hash of the whole z and step 0.
  const std::vector<double> z1(local_z.begin(), local_z.end());
  const rpy::SqrtReport report = im.split_sample(z1, {im.noise_hash({local_z}), 0}, local_w);
  im.comm.run([&] { rpy::detail::require_finite_result(local_w, where, "local output", "noise"); });
  return report;
}

void DistributedPseRpy::Impl::check_grand_noise(std::span<const double> z_t, std::span<const double> z_r,
                                                std::span<double> w_t, std::span<double> w_r,
                                                const rpy::SqrtOptions& sampler, const char* where) const {
  require(global_n > 0, ErrorCode::invalid_input, where, "positions not set (call set_positions first)");
  const std::size_t n3 = 3 * local_n;
  const auto output = [](std::span<double> w) { return std::span<const double>(w.data(), w.size()); };
  comm.run([&] {
    check_split_options(sampler, where);
    require_size(z_t, n3, where, "local translational noise");
    require_size(z_r, n3, where, "local rotational noise");
    require_size(output(w_t), n3, where, "local translational output");
    require_size(output(w_r), n3, where, "local rotational output");
    require_finite(z_t, where, "local translational noise", 3);
    require_finite(z_r, where, "local rotational noise", 3);
  });
}

rpy::SqrtReport DistributedPseRpy::Impl::grand_split_sample(std::span<const double> z_t, std::span<const double> z_r,
                                                            std::uint64_t hash, std::span<double> w_t,
                                                            std::span<double> w_r) const {
  // PseRpy::do_apply_sqrt_rotation: w' = (S M_r S)^{1/2} z on z = [z_t; z_r], [w_t; w_r] = S^-1 w'.
  const std::size_t n3 = 3 * local_n;
  std::vector<double> z(2 * n3), w(2 * n3);
  std::copy(z_t.begin(), z_t.end(), z.begin());
  std::copy(z_r.begin(), z_r.end(), z.begin() + static_cast<std::ptrdiff_t>(n3));
  rpy::SqrtReport report = real_sqrt_rotation(z, w.data());
  for (std::size_t k = 0; k < n3; ++k) {
    w_t[k] = w[k];
    w_r[k] = w[n3 + k] / params.radius;
  }
  // + the wave part's noise, the translational field keyed by the hash of the whole [z_t; z_r] and
  // step 0 (as apply_sqrt keys it by the whole z).
  wave->add_noise_rotation({hash, 0}, w_t.data(), w_r.data(), local_n);
  report.method = rpy::SqrtMethod::split;
  report.operator_applications += 1;
  return report;
}

rpy::SqrtReport DistributedPseRpy::Impl::grand_sample(std::span<const double> z_t, std::span<const double> z_r,
                                                      const std::span<const std::uint64_t>* indices,
                                                      std::span<double> w_t, std::span<double> w_r,
                                                      const rpy::SqrtOptions& sampler) const {
  constexpr const char* where = "DistributedPseRpy::apply_sqrt_rotation";
  check_grand_noise(z_t, z_r, w_t, w_r, sampler, where);
  const ProductRecord record(*this);
  if (indices != nullptr) comm.run([&] { check_indices(*indices, where); });
  const std::uint64_t hash = indices == nullptr ? noise_hash({z_t, z_r}) : noise_hash({z_t, z_r}, *indices, where);
  const rpy::SqrtReport report = grand_split_sample(z_t, z_r, hash, w_t, w_r);
  comm.run([&] {
    rpy::detail::require_finite_result(w_t, where, "local translational output", "noise");
    rpy::detail::require_finite_result(w_r, where, "local rotational output", "noise");
  });
  return report;
}

rpy::SqrtReport DistributedPseRpy::apply_sqrt_rotation(std::span<const double> local_z_translation,
                                                       std::span<const double> local_z_rotation,
                                                       std::span<double> local_w_translation,
                                                       std::span<double> local_w_rotation,
                                                       const rpy::SqrtOptions& options) const {
  return impl_->grand_sample(local_z_translation, local_z_rotation, nullptr, local_w_translation, local_w_rotation,
                             options);
}

rpy::SqrtReport DistributedPseRpy::apply_sqrt_rotation(std::span<const double> local_z_translation,
                                                       std::span<const double> local_z_rotation,
                                                       std::span<const std::uint64_t> local_indices,
                                                       std::span<double> local_w_translation,
                                                       std::span<double> local_w_rotation,
                                                       const rpy::SqrtOptions& options) const {
  return impl_->grand_sample(local_z_translation, local_z_rotation, &local_indices, local_w_translation,
                             local_w_rotation, options);
}

rpy::SqrtReport DistributedPseRpy::apply_with_noise(std::span<const double> local_forces, double noise_scale,
                                                    std::uint64_t seed, std::uint64_t step,
                                                    std::span<double> local_velocities) const {
  return impl_->fused(local_forces, noise_scale, seed, step, nullptr, local_velocities);
}

rpy::SqrtReport DistributedPseRpy::apply_with_noise(std::span<const double> local_forces, double noise_scale,
                                                    std::uint64_t seed, std::uint64_t step,
                                                    std::span<const std::uint64_t> local_indices,
                                                    std::span<double> local_velocities) const {
  return impl_->fused(local_forces, noise_scale, seed, step, &local_indices, local_velocities);
}

rpy::SqrtReport DistributedPseRpy::Impl::fused(std::span<const double> forces, double noise_scale, std::uint64_t seed,
                                               std::uint64_t step, const std::span<const std::uint64_t>* indices,
                                               std::span<double> velocities) const {
  constexpr const char* where = "DistributedPseRpy::apply_with_noise";
  check_arrays(forces, velocities, where);
  const ProductRecord record(*this);
  comm.run([&] {
    require(std::isfinite(noise_scale) && noise_scale >= 0.0, ErrorCode::invalid_argument, where,
            "noise_scale must be finite and >= 0, got " + format_number(noise_scale));
    if (indices != nullptr) check_indices(*indices, where);
  });
  // PseRpy::apply_with_noise: y = M_r^{1/2} z1 (z1 of (seed, step)), one wave-space pass for
  // M_w F + noise_scale M_w^{1/2} z2, then M_r F, then noise_scale y.
  rpy::SqrtReport report;
  report.method = rpy::SqrtMethod::split;
  std::vector<double> y;
  if (noise_scale > 0.0) {
    std::vector<double> z1(3 * local_n);
    if (indices == nullptr)
      fill_normal(z1, offset, seed, step, rpy::pse::detail::kStreamReal);
    else
      rpy::fill_normal(*indices, z1, seed, step, rpy::pse::detail::kStreamReal);
    y.resize(z1.size());
    report = real_sqrt(z1, y.data());
    report.method = rpy::SqrtMethod::split;
  }
  const rpy::pse::detail::NoiseKey key{seed, step};
  wave->apply(forces.data(), velocities.data(), local_n, noise_scale > 0.0 ? &key : nullptr, noise_scale);
  real->apply(comm, forces.data(), velocities.data());
  for (std::size_t i = 0; i < y.size(); ++i) velocities[i] += noise_scale * y[i];
  report.operator_applications += 1;
  return report;
}

}  // namespace rpyfmm::mpi
