// rpyfmm — a weighted space-filling-curve partition of particles distributed over MPI ranks, and
// the redistribution of per-particle data that goes with it (docs/mpi.md, "Space-filling-curve
// partition").
//
// Particles get keys along a space-filling curve in the global bounding cube: Morton keys (Morton,
// 1966; the Z-order of Warren and Salmon, 1993), the default, or Hilbert keys (Butz, 1971). The
// global order by (key, global index) is cut into P contiguous ranges of balanced weight, rank r
// owning the r-th range. Every rank's share of any per-particle column is then moved to the owners
// in key order by one MPI_Alltoallv, and results are moved back to the original ranks and order by
// the inverse exchange, bit for bit.
//
// On both curves a key's prefix of 3l bits is one cell of level l of the octree over the cube, so
// a rank's range is a union of whole cells on each level (the property the distributed octree of
// the FMM needs). A Morton key is a bit interleave; consecutive Hilbert cells are face neighbours,
// so Hilbert ranges are more compact (docs/mpi.md measures what that does to the halos).
#pragma once

#include <mpi.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"

namespace rpyfmm::mpi {

/// Bits of each coordinate in a key (Morton or Hilbert): 3 × 21 = 63 bits, cells of side / 2^21.
inline constexpr int kMortonBitsPerAxis = 21;

/// The cube [origin, origin + 2 half_side]^3 in which the keys are taken: origin the smallest
/// coordinate on each axis over all ranks, 2 half_side the largest extent over the three axes (0 for
/// one point). Half the side, so that spreads up to the largest double are represented.
struct KeyCube {
  std::array<double, 3> origin{0.0, 0.0, 0.0};
  double half_side = 0.0;
};

/// The Morton key of the cell (ix, iy, iz), each < 2^21: bit b of ix, iy, iz becomes bit 3b + 2,
/// 3b + 1, 3b of the key (x most significant within a level), so keys sort cells level by level.
[[nodiscard]] std::uint64_t morton_key(std::uint32_t ix, std::uint32_t iy, std::uint32_t iz);

/// The Hilbert key of the cell (ix, iy, iz), each < 2^21 (Butz's algorithm as formulated by
/// Hamilton, "Compact Hilbert indices", Dalhousie Univ. Tech. Rep. CS-2006-07, 2006, Sec. 2):
/// 21 digits of 3 bits from the coarsest level, digit l the rank of the cell's octant of level l
/// along its parent's subcurve. A prefix of 3l bits is one cell of level l, and cells consecutive in
/// key order at any level are face neighbours. Curve starts at cell (0, 0, 0).
[[nodiscard]] std::uint64_t hilbert_key(std::uint32_t ix, std::uint32_t iy, std::uint32_t iz);

/// The curve along which SfcPartition orders the particles. Every rank must pass the same.
enum class SfcCurve { morton, hilbert };

/// The cell index along one axis of coordinate `c`: floor((c/2 - origin/2) / half_side · 2^21), the
/// upper face in the last cell, 0 when half_side is 0. On halves, so that spreads up to the largest
/// double do not overflow; the same input gives the same index on every rank.
[[nodiscard]] std::uint32_t morton_cell(double c, double origin, double half_side);

/// Collective: the cube of all ranks' positions (3n each, n may be 0 on any rank; one
/// MPI_Allreduce). No particle anywhere gives origin 0 and side 0. Positions must be finite
/// (partition() checks them collectively; this function does not).
[[nodiscard]] KeyCube global_key_cube(const Communicator& comm, std::span<const double> positions);

/// Not collective: the keys of `positions` (3n) in `cube` along `curve` (of the cells that
/// morton_cell gives on each axis).
[[nodiscard]] std::vector<std::uint64_t> sfc_keys(const KeyCube& cube, std::span<const double> positions,
                                                  SfcCurve curve);
/// sfc_keys along the Morton curve.
[[nodiscard]] std::vector<std::uint64_t> morton_keys(const KeyCube& cube, std::span<const double> positions);

/// One per-particle column to move: `per` doubles per particle, particle-major (positions: per 3).
struct Column {
  std::span<const double> values;
  std::size_t per = 1;
};

/// A particle's place in the global order: its key on the partition's curve, then its global index
/// (the concatenation of the ranks' input shares in rank order) to break ties between equal keys.
struct SfcKey {
  std::uint64_t key = 0;
  std::uint64_t index = 0;
  friend auto operator<=>(const SfcKey&, const SfcKey&) = default;
};

/// The cuts' search (docs/mpi.md, "Space-filling-curve partition") splits every open cut's interval
/// into k parts per round and sums the weights before the k - 1 probes of all open cuts in one
/// MPI_Allreduce, k = max(2, 1 + min(sums / open cuts, kCutMaxWays - 1)):
/// kCutMaxWays = 256 (8 of the 63 + ceil(log2 N) bits per round: at most 11 rounds up to N = 2^25),
/// more ways saving few rounds for local work that grows with k; kCutSumsPerRound = 2^16 sums
/// (512 KiB) per round, bounding a round's message at large P (k = 256 up to P = 258, bisection,
/// k = 2, from P = 2^15 + 2 on).
inline constexpr std::size_t kCutMaxWays = 256;
inline constexpr std::size_t kCutSumsPerRound = std::size_t{1} << 16;

class SfcPartition {
 public:
  /// Collective. Partitions the particles that this rank holds (3n positions; n may be 0 on any
  /// rank, and on all of them) with weights (n entries, finite and >= 0; empty: 1 for each of this
  /// rank's particles; all 0 everywhere: 1 each). Fails on every rank (Communicator::agree) for a
  /// wrong size, a NaN or infinite coordinate or weight, a negative weight, or a curve that is not
  /// an SfcCurve on any rank, or different curves on different ranks. Memory O(n + n_owned + P) per
  /// rank. The communicator must outlive the partition. `cut_sums_per_round` (>= 1, the same on
  /// every rank) bounds the sums of one round of the cuts' search (above); 1 gives the bisection.
  /// The cuts are the same for every value, only the number of rounds changes.
  SfcPartition(MPI_Comm comm, std::span<const double> positions, std::span<const double> weights = {},
               SfcCurve curve = SfcCurve::morton, std::size_t cut_sums_per_round = kCutSumsPerRound);

  /// Collective over `sources`' communicator: partitions the particles that this rank holds (3n
  /// positions, n may be 0 on any rank; each of weight 1) by the cuts of `sources`, so that owners
  /// of sources and of these particles are aligned. Keys are taken in sources.cube() along
  /// sources.curve(); a coordinate outside the cube is clamped to its boundary cell on that axis
  /// (morton_cell), so every particle has a key. A particle of key k goes to the rank r with
  /// splitters()[r-1].key <= k < splitters()[r].key (no bound below rank 0 or above rank P - 1):
  /// the last rank whose range reaches key k where a cut falls between sources of equal key k; a
  /// rank with an empty range gets none. owned() holds (key, global index of this set), increasing;
  /// splitters() are those of `sources`, owned_counts() and owned_weight_units() the counts.
  /// Fails on every rank for a wrong size or a NaN or infinite coordinate on any rank.
  [[nodiscard]] static SfcPartition aligned_with(const SfcPartition& sources, std::span<const double> positions);

  [[nodiscard]] SfcCurve curve() const { return curve_; }
  [[nodiscard]] const KeyCube& cube() const { return cube_; }
  /// The particles this rank holds in the input (n) and owns after the partition.
  [[nodiscard]] std::size_t input_size() const { return input_size_; }
  [[nodiscard]] std::size_t owned_size() const { return owned_.size(); }
  [[nodiscard]] std::uint64_t global_size() const { return global_size_; }
  /// The owned particles' (key, global index), increasing.
  [[nodiscard]] std::span<const SfcKey> owned() const { return owned_; }
  /// P - 1 cuts: rank r owns the particles with splitters()[r-1] <= (key, index) < splitters()[r]
  /// (no lower bound for rank 0, no upper for rank P - 1). Equal cuts leave a rank empty.
  [[nodiscard]] std::span<const SfcKey> splitters() const { return splitters_; }
  /// The rounds (MPI_Allreduce calls) of the cuts' search: 0 on one rank or when every cut is at 0,
  /// at most ceil((63 + ceil(log2 N)) / log2 k) with k the fewest ways of a round.
  [[nodiscard]] int cut_rounds() const { return cut_rounds_; }
  /// Every rank's number of owned particles and owned weight (in the input's units; the weights as
  /// the partition balanced them, rounded to the fixed point described at weight_unit()).
  [[nodiscard]] std::span<const std::uint64_t> owned_counts() const { return owned_counts_; }
  [[nodiscard]] std::vector<double> owned_weights() const;
  /// The same in units of weight_unit(): exact integer sums of the q_i below.
  [[nodiscard]] std::span<const std::uint64_t> owned_weight_units() const { return owned_q_; }
  /// The largest q_i over all ranks.
  [[nodiscard]] std::uint64_t max_weight_units() const { return max_q_; }
  /// The weights are balanced as integers q_i = round(w_i / weight_unit()), with the unit a power of
  /// two chosen so that their sum fits 62 bits; integer sums make the partition independent of the
  /// distribution of the input. The largest weight is exact to 2^-(62 - ceil(log2 N)) of itself.
  /// The unit underflows to 0 for a largest weight below about 2^-1010; owned_weights() does not.
  [[nodiscard]] double weight_unit() const { return std::ldexp(1.0, -weight_shift_); }
  /// max over ranks of the owned weight / its mean (1 for no weight at all). The cuts guarantee
  /// max part <= ceil(Q / P) + max q_i in units of weight_unit(), Q the total.
  [[nodiscard]] double imbalance() const;

  /// Collective: each column of this rank's input particles (per · input_size() entries) moved to
  /// the owners, in the owned order (per · owned_size() entries). One MPI_Alltoallv for all columns.
  [[nodiscard]] std::vector<std::vector<double>> to_owners(std::span<const Column> columns) const;
  /// Collective: the inverse of to_owners: columns of the owned particles (per · owned_size()) back
  /// to the input ranks and order (per · input_size()), bit for bit.
  [[nodiscard]] std::vector<std::vector<double>> to_origin(std::span<const Column> columns) const;

 private:
  // The exchange to the owners: particles sent to and received from each rank, with displacements
  // (to_origin runs it with the two sides swapped).
  struct Plan {
    std::vector<int> send_counts, send_displs, recv_counts, recv_displs;
  };
  [[nodiscard]] std::vector<std::vector<double>> exchange(std::span<const Column> columns, bool forward) const;
  // aligned_with's: the communicator, curve, cube and cuts of `sources`, not yet any particle.
  struct AlignedTag {};
  SfcPartition(const SfcPartition& sources, AlignedTag tag);
  // Construction's last stages: the owners' counts and weights, the counts and displacements of
  // the exchange to the owners from how many particles go to each (MPI's int counts checked), then
  // the owned records received in (key, index) order.
  void settle_owners(std::span<const std::size_t> owner, std::span<const SfcKey> sorted,
                     std::span<const std::uint64_t> prefix);
  void plan_exchange(std::span<const std::size_t> send_count);
  void receive_owned(std::span<const SfcKey> sorted);

  Communicator comm_;
  SfcCurve curve_ = SfcCurve::morton;
  KeyCube cube_;
  std::size_t input_size_ = 0;
  std::uint64_t global_size_ = 0;
  int weight_shift_ = 0;  // weight_unit() = 2^-weight_shift_
  std::vector<SfcKey> owned_;
  std::vector<SfcKey> splitters_;
  int cut_rounds_ = 0;
  std::vector<std::uint64_t> owned_counts_, owned_q_;
  std::uint64_t max_q_ = 0;
  // Input particle of each send slot (the input sorted by SfcKey); received slot of each owned one.
  std::vector<std::size_t> send_order_, recv_order_;
  Plan plan_;
};

}  // namespace rpyfmm::mpi
