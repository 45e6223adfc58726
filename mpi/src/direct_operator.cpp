// rpyfmm — DistributedDirectRpy: source blocks passed in rank order, DirectRpy's sums on each
// rank's own targets (direct_operator.hpp, docs/mpi.md).
#include "rpyfmm/mpi/direct_operator.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <string>

// rpy/src (private to rpyfmm::rpy and this layer): DirectRpy's block sums, translational and
// rotational, length units and load scaling, so that the distributed sums are DirectRpy's
// operation for operation.
#include "direct_block_sums.hpp"
#include "length_units.hpp"
#include "load_scaling.hpp"
#include "particle_set.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/rpy_rotation_kernel.hpp"

namespace rpyfmm::mpi {
namespace {

constexpr const char* kSetPositions = "DistributedDirectRpy::set_positions";
constexpr const char* kApply = "DistributedDirectRpy::apply";
constexpr const char* kApplyBlock = "DistributedDirectRpy::apply_block";
constexpr std::size_t kBlock = rpy::detail::kDirectBlock;
// Doubles per particle of a source block as broadcast: x, y, z, a (length units), then fx, fy, fz
// (load-scaled) of each of the nrhs right-hand sides, each an array over the block's particles; with
// rotation (one right-hand side) then tx, ty, tz (load-scaled and divided by the length unit, as
// DirectRpy passes them to its rotational sums).
constexpr std::size_t kPositionColumns = 4;
constexpr std::size_t packed_columns(std::size_t nrhs, bool rotation) {
  return kPositionColumns + 3 * nrhs + (rotation ? 3 : 0);
}
constexpr std::size_t kPackedForces = packed_columns(1, false);
constexpr std::size_t kPackedRotation = packed_columns(1, true);
// The broadcast in flight is polled (MPI_Test lets it progress) between batches of targets: about
// eight batches per block, each at least 64 targets per thread (add_direct_block_sums hands out
// targets to the threads 16 at a time, so every thread stays busy).
std::size_t target_batch(std::size_t local_n) {
  const auto threads = static_cast<std::size_t>(std::max(1, omp_get_max_threads()));
  return std::max(local_n / 8 + 1, 64 * threads);
}
// Runs the MPI calls of `body`, adding their wall time to `seconds`.
template <class Body>
void timed(double& seconds, Body&& body) {
  const double start = MPI_Wtime();
  body();
  seconds += MPI_Wtime() - start;
}

}  // namespace

// Sources received and not summed yet: fewer than kBlock left over from earlier blocks (the start
// of one of DirectRpy's source blocks that straddles two ranks' shares), then the latest block.
// Structure of arrays: the columns of the broadcast blocks (packed_columns), then inv_a = 1 / a
// computed here as DirectRpy computes it; and the sources' global indices, by which the rotational
// sums skip the self pair.
class DistributedDirectRpy::SourceWindow {
 public:
  SourceWindow(std::size_t capacity, std::size_t packed)
      : packed_(packed), data_((packed + 1) * capacity), id_(capacity), capacity_(capacity) {}

  // `packed`: the packed_ arrays of n doubles of the next sources in the global order.
  void append(const double* packed, std::size_t n) {
    for (std::size_t k = 0; k < packed_; ++k) std::copy_n(packed + k * n, n, column(k) + size_);
    const double* a = column(kA) + size_;
    double* inv_a = column(packed_) + size_;
    for (std::size_t j = 0; j < n; ++j) inv_a[j] = 1.0 / a[j];
    std::iota(id_.data() + size_, id_.data() + size_ + n, first_ + size_);
    size_ += n;
  }
  // Drops the first m sources (summed), keeping the rest at the front.
  void drop_front(std::size_t m) {
    for (std::size_t k = 0; k <= packed_; ++k) std::copy(column(k) + m, column(k) + size_, column(k));
    std::copy(id_.data() + m, id_.data() + size_, id_.data());
    size_ -= m;
    first_ += m;
  }
  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] rpy::detail::DirectParticles particles() const {
    return {column(0), column(1), column(2), column(kA), column(packed_)};
  }
  // The forces of the nrhs right-hand sides the window holds.
  [[nodiscard]] std::vector<rpy::detail::DirectForces> forces(std::size_t nrhs) const {
    std::vector<rpy::detail::DirectForces> out(nrhs);
    for (std::size_t k = 0; k < nrhs; ++k) {
      const std::size_t f = kPositionColumns + 3 * k;
      out[k] = {column(f), column(f + 1), column(f + 2)};
    }
    return out;
  }
  // The first m sources with their torques (packed_ == kPackedRotation, one right-hand side); radii
  // nullptr with equal_radii, as DirectRpy passes them.
  [[nodiscard]] rpy::detail::GrandSources grand_sources(std::size_t m, bool equal_radii) const {
    return {m,          column(0), column(1), column(2), equal_radii ? nullptr : column(kA),
            id_.data(), column(4), column(5), column(6), column(7),
            column(8),  column(9)};
  }

 private:
  static constexpr std::size_t kA = 3;
  [[nodiscard]] double* column(std::size_t k) { return data_.data() + k * capacity_; }
  [[nodiscard]] const double* column(std::size_t k) const { return data_.data() + k * capacity_; }

  std::size_t packed_;
  std::vector<double> data_;
  std::vector<std::size_t> id_;
  std::size_t capacity_;
  std::size_t size_ = 0;
  std::size_t first_ = 0;  // the global index of the first source held
};

DistributedDirectRpy::DistributedDirectRpy(MPI_Comm comm, double viscosity)
    : comm_(comm), viscosity_(detail::agreed_viscosity(comm_, viscosity, "DistributedDirectRpy")) {}

void DistributedDirectRpy::set_positions(std::span<const double> local_positions, double radius) {
  global_n_ = 0;  // no positions until this call succeeds on every rank
  sampler_blocks_.clear();
  set_positions(local_positions, detail::common_radii(comm_, local_positions, radius, kSetPositions));
}

void DistributedDirectRpy::set_positions(std::span<const double> local_positions, std::span<const double> local_radii) {
  global_n_ = 0;  // no positions until this call succeeds on every rank
  sampler_blocks_.clear();
  stats_ = CommunicationStats{};
  comm_.run([&] { detail::check_local_particles(local_positions, local_radii, kSetPositions); });
  const auto ranks = static_cast<std::size_t>(comm_.size());
  std::vector<std::size_t> all;
  timed(stats_.set_positions_seconds, [&] { all = detail::gather_counts(comm_, local_radii.size()); });
  // Same values on every rank, so every rank throws alike here without agreement.
  std::uint64_t total = 0;
  for (std::size_t n : all) {
    // The blocks of a force-only product (kPackedForces doubles per particle); a product with
    // torques, whose blocks are larger, checks its own (apply with rotation).
    require(n <= static_cast<std::size_t>(INT_MAX) / kPackedForces, ErrorCode::not_supported, kSetPositions,
            "a rank holds " + std::to_string(n) + " particles: more than MPI's int counts address in one block (" +
                std::to_string(INT_MAX / kPackedForces) + ")");
    total += n;
  }
  require(total > 0, ErrorCode::invalid_input, kSetPositions,
          "no particles on any of the " + std::to_string(ranks) + " ranks (N = 0)");
  counts_ = std::move(all);
  local_n_ = counts_[static_cast<std::size_t>(comm_.rank())];
  offset_ = 0;
  for (int r = 0; r < comm_.rank(); ++r) offset_ += counts_[static_cast<std::size_t>(r)];

  detail::WholeSet set;
  timed(stats_.set_positions_seconds,
        [&] { set = detail::gather_whole_set(comm_, local_positions, local_radii, offset_); });
  // MobilityOperator's flag: every radius equal to the first (radii are > 0, so no -0 == +0).
  equal_radii_ = set.radii.a_min == set.radii.a_max;
  largest_radius_ = set.radii.a_max;
  comm_.run([&] {
    // DirectRpy::on_positions_set on this rank's share, with the whole set's units.
    const rpy::detail::LengthUnits units =
        rpy::detail::choose_length_units(set.box, local_radii, set.radii, kSetPositions);
    rpy::detail::store_direct_particles(local_positions, local_radii, units, {x_, y_, z_, a_, inv_a_});
    scale_exponent_ = units.exponent;
  });
  positions_.assign(local_positions.begin(), local_positions.end());
  radii_.assign(local_radii.begin(), local_radii.end());
  global_n_ = total;
}

std::vector<double> DistributedDirectRpy::packed_block(std::span<const double> local_forces,
                                                       std::span<const double> local_torques,
                                                       std::span<const int> load_exponents) const {
  const std::size_t n = local_n_;
  const std::size_t nrhs = load_exponents.size();
  const bool rotation = !local_torques.empty();
  std::vector<double> packed(packed_columns(nrhs, rotation) * n);
  std::copy(x_.begin(), x_.end(), packed.begin());
  std::copy(y_.begin(), y_.end(), packed.begin() + static_cast<std::ptrdiff_t>(n));
  std::copy(z_.begin(), z_.end(), packed.begin() + static_cast<std::ptrdiff_t>(2 * n));
  std::copy(a_.begin(), a_.end(), packed.begin() + static_cast<std::ptrdiff_t>(3 * n));
  // MobilityOperator::apply_block's load scaling: 2^-k F, exact, with each right-hand side's own k
  // (as a product of it alone). The torques as DirectRpy::do_apply_rotation receives and stores
  // them: 2^-k T, then 2^-e for the length units 2^e (two steps, as there, so that a subnormal
  // rounds alike).
  for (std::size_t r = 0; r < nrhs; ++r) {
    const double* f = local_forces.data() + 3 * n * r;
    double* out = packed.data() + (kPositionColumns + 3 * r) * n;
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t c = 0; c < 3; ++c) out[c * n + i] = std::ldexp(f[3 * i + c], -load_exponents[r]);
  }
  if (rotation) {
    double* out = packed.data() + packed_columns(nrhs, false) * n;
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t c = 0; c < 3; ++c)
        out[c * n + i] = std::ldexp(std::ldexp(local_torques[3 * i + c], -load_exponents[0]), -scale_exponent_);
  }
  return packed;
}

void DistributedDirectRpy::sum_block(const SourceWindow& window, std::size_t nrhs, std::size_t usable,
                                     std::vector<double>& acc, std::vector<double>& rotation_acc,
                                     MPI_Request* pending) const {
  const std::size_t batch = target_batch(local_n_);
  const std::vector<rpy::detail::DirectForces> forces = window.forces(nrhs);
  for (std::size_t first = 0; first < local_n_; first += batch) {
    const std::size_t count = std::min(batch, local_n_ - first);
    const rpy::detail::DirectParticles targets{x_.data() + first, y_.data() + first, z_.data() + first,
                                               a_.data() + first, inv_a_.data() + first};
    rpy::detail::add_direct_block_sums(targets, count, window.particles(), forces, usable, equal_radii_,
                                       acc.data() + 3 * nrhs * first);
    if (!rotation_acc.empty())
      rpy::detail::add_rotation_block_sums(targets, offset_ + first, count, window.grand_sources(usable, equal_radii_),
                                           rotation_acc.data() + 6 * first);
    if (pending != nullptr) {
      int done = 0;
      timed(stats_.apply_seconds, [&] { check_mpi(MPI_Test(pending, &done, MPI_STATUS_IGNORE), "MPI_Test"); });
    }
  }
}

void DistributedDirectRpy::apply(std::span<const double> local_forces, std::span<double> local_velocities) const {
  product(kApply, 1, false, local_forces, {}, local_velocities, {});
}

void DistributedDirectRpy::apply_block(std::span<const double> local_forces, std::span<double> local_velocities,
                                       std::size_t nrhs) const {
  require(global_n_ > 0, ErrorCode::invalid_input, kApplyBlock, "positions not set (call set_positions first)");
  detail::agree_on_nrhs(comm_, nrhs, kApplyBlock);
  // A rank's source block carries packed_columns(nrhs) doubles per particle in one broadcast of an
  // int count. counts_ and nrhs are the same on every rank, so every rank throws alike here.
  const std::size_t largest_share = *std::max_element(counts_.begin(), counts_.end());
  const std::size_t most = (static_cast<std::size_t>(INT_MAX) / largest_share - kPositionColumns) / 3;
  require(nrhs <= most, ErrorCode::not_supported, kApplyBlock,
          std::to_string(nrhs) + " right-hand sides: a source block of a rank holding " +
              std::to_string(largest_share) + " particles would carry more doubles than MPI's int counts address (" +
              std::to_string(INT_MAX) + "); at most " + std::to_string(most) + " right-hand sides per call here");
  product(kApplyBlock, nrhs, false, local_forces, {}, local_velocities, {});
}

void DistributedDirectRpy::apply(std::span<const double> local_forces, std::span<const double> local_torques,
                                 std::span<double> local_velocities, std::span<double> local_angular_velocities) const {
  // A source block with torques carries kPackedRotation doubles per particle in one broadcast of an
  // int count. counts_ is the same on every rank, so every rank throws alike here.
  const std::size_t largest_share = global_n_ > 0 ? *std::max_element(counts_.begin(), counts_.end()) : 0;
  require(largest_share <= static_cast<std::size_t>(INT_MAX) / kPackedRotation, ErrorCode::not_supported, kApply,
          "with torques: a rank holds " + std::to_string(largest_share) +
              " particles, more than MPI's int counts address in one block with torques (" +
              std::to_string(INT_MAX / kPackedRotation) + ")");
  product(kApply, 1, true, local_forces, local_torques, local_velocities, local_angular_velocities);
}

std::vector<int> DistributedDirectRpy::load_exponents(bool rotation, std::span<const double> local_forces,
                                                      std::span<const double> local_torques, std::size_t nrhs) const {
  // MobilityOperator::apply_block's load scale of each right-hand side, from its largest force of
  // all ranks; with rotation MobilityOperator::apply's, from the largest force and torque
  // (largest_rotation_load).
  std::vector<double> largest(nrhs, 0.0), global_largest(nrhs, 0.0);
  if (rotation) {
    largest[0] = rpy::detail::largest_rotation_load(local_forces, local_torques, largest_radius_);
  } else {
    for (std::size_t r = 0; r < nrhs; ++r)
      for (double f : local_forces.subspan(3 * local_n_ * r, 3 * local_n_))
        largest[r] = std::max(largest[r], std::abs(f));
  }
  timed(stats_.apply_seconds, [&] {
    check_mpi(
        MPI_Allreduce(largest.data(), global_largest.data(), static_cast<int>(nrhs), MPI_DOUBLE, MPI_MAX, comm_.get()),
        "MPI_Allreduce");
  });
  std::vector<int> k(nrhs);
  for (std::size_t r = 0; r < nrhs; ++r)
    k[r] = rpy::detail::load_scale_exponent({std::span<const double>(&global_largest[r], 1)});
  return k;
}

void DistributedDirectRpy::product(const char* where, std::size_t nrhs, bool rotation,
                                   std::span<const double> local_forces, std::span<const double> local_torques,
                                   std::span<double> local_velocities,
                                   std::span<double> local_angular_velocities) const {
  // global_n_ is the same on every rank (set_positions succeeds or fails on all of them).
  require(global_n_ > 0, ErrorCode::invalid_input, where, "positions not set (call set_positions first)");
  const std::size_t n3 = 3 * local_n_;
  const auto output = [](std::span<double> out) { return std::span<const double>(out.data(), out.size()); };
  // MobilityOperator::apply's order: every size, then the inputs' entries.
  comm_.run([&] {
    require_size(local_forces, n3 * nrhs, where, "local forces");
    if (rotation) require_size(local_torques, n3, where, "local torques");
    require_size(output(local_velocities), n3 * nrhs, where, "local velocities");
    if (rotation) require_size(output(local_angular_velocities), n3, where, "local angular velocities");
    require_finite(local_forces, where, "local forces", 3);
    if (rotation) require_finite(local_torques, where, "local torques", 3);
  });
  stats_.apply_seconds = 0.0;
  stats_.apply_bytes_received = 0;
  const std::vector<int> k = load_exponents(rotation, local_forces, local_torques, nrhs);
  std::vector<double> own = packed_block(local_forces, rotation ? local_torques : std::span<const double>{}, k);
  const std::size_t columns = packed_columns(nrhs, rotation);

  // The ranks' blocks in rank order (empty shares skipped), each broadcast by its owner; two
  // receive buffers, the next block in flight while the current one is summed.
  std::vector<int> roots;
  for (std::size_t r = 0; r < counts_.size(); ++r)
    if (counts_[r] > 0) roots.push_back(static_cast<int>(r));
  const std::size_t largest_share = *std::max_element(counts_.begin(), counts_.end());
  std::array<std::vector<double>, 2> buffers;
  std::array<MPI_Request, 2> requests{MPI_REQUEST_NULL, MPI_REQUEST_NULL};
  const auto block_of = [&](std::size_t step) {
    return roots[step] == comm_.rank() ? own.data() : buffers[step % 2].data();
  };
  const auto post = [&](std::size_t step) {
    const int root = roots[step];
    if (root != comm_.rank()) buffers[step % 2].resize(columns * largest_share);
    const auto count = static_cast<int>(columns * counts_[static_cast<std::size_t>(root)]);
    timed(stats_.apply_seconds, [&] {
      check_mpi(MPI_Ibcast(block_of(step), count, MPI_DOUBLE, root, comm_.get(), &requests[step % 2]), "MPI_Ibcast");
    });
  };

  SourceWindow window(kBlock - 1 + largest_share, columns);
  std::vector<double> acc(n3 * nrhs, 0.0);
  std::vector<double> rotation_acc(rotation ? 2 * n3 : 0, 0.0);
  post(0);
  for (std::size_t step = 0; step < roots.size(); ++step) {
    const bool last = step + 1 == roots.size();
    if (!last) post(step + 1);
    timed(stats_.apply_seconds, [&] { check_mpi(MPI_Wait(&requests[step % 2], MPI_STATUS_IGNORE), "MPI_Wait"); });
    const auto root = static_cast<std::size_t>(roots[step]);
    const std::size_t n = counts_[root];
    if (roots[step] != comm_.rank()) stats_.apply_bytes_received += columns * n * sizeof(double);
    window.append(block_of(step), n);
    // Whole source blocks of DirectRpy only (counted from the first particle of the whole set),
    // but for the set's last block.
    const std::size_t usable = last ? window.size() : window.size() / kBlock * kBlock;
    MPI_Request* pending = last ? nullptr : &requests[(step + 1) % 2];
    sum_block(window, nrhs, usable, acc, rotation_acc, pending);
    window.drop_front(usable);
  }

  // Back from the length units (exact), then from the load scale: DirectRpy::sum_rows and
  // MobilityOperator::apply_block; with rotation DirectRpy::do_apply_rotation (U: the
  // translational sum, then the rotational one added, each in 2^e U; W: the sums and the self
  // term T_i / (8 pi eta a_i^3) in 2^(2e) W) and MobilityOperator::apply.
  stats_.applies_seconds += stats_.apply_seconds;
  const double inv_eta = 1.0 / viscosity_;
  const int e = scale_exponent_;
  for (std::size_t i = 0; i < local_n_; ++i) {
    for (std::size_t r = 0; r < nrhs; ++r) {
      const double* sums = acc.data() + 3 * (nrhs * i + r);
      for (std::size_t c = 0; c < 3; ++c)
        local_velocities[n3 * r + 3 * i + c] = std::ldexp(std::ldexp(inv_eta * sums[c], -e), k[r]);
    }
    if (!rotation) continue;
    const double* sums = rotation_acc.data() + 6 * i;
    for (std::size_t c = 0; c < 3; ++c) {
      const double u = std::ldexp(inv_eta * acc[3 * i + c], -e) + std::ldexp(inv_eta * sums[c], -e);
      // 2^-k 2^-e T, as DirectRpy holds it
      const double torque = own[(packed_columns(1, false) + c) * local_n_ + i];
      const double w = std::ldexp(inv_eta * (sums[3 + c] + rpy::rpy_rotation_self(a_[i]) * torque), -2 * e);
      local_velocities[3 * i + c] = std::ldexp(u, k[0]);
      local_angular_velocities[3 * i + c] = std::ldexp(w, k[0]);
    }
  }
  comm_.run([&] {
    const char* input = rotation ? "forces and torques" : "forces";
    rpy::detail::require_finite_result(local_velocities, where, "velocities", input);
    if (rotation) rpy::detail::require_finite_result(local_angular_velocities, where, "angular velocities", input);
  });
}

}  // namespace rpyfmm::mpi
