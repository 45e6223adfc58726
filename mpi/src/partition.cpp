// rpyfmm — SfcPartition: Morton or Hilbert keys (hilbert_key.cpp) in the global cube, weighted cuts
// of the global key order by a distributed multi-way search, and the MPI_Alltoallv exchanges to the
// owners and back (partition.hpp, docs/mpi.md).
#include "rpyfmm/mpi/partition.hpp"

#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <string>
#include <utility>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::mpi {
namespace {

// A position in the global order as one integer: key · N + index (N the global count), so that
// the cuts are searched for on [0, 2^63 · N). 128 bits (a GCC/Clang extension).
__extension__ using Composite = unsigned __int128;

constexpr const char* kWhere = "rpyfmm::mpi::SfcPartition";
constexpr std::uint32_t kCells = 1u << kMortonBitsPerAxis;

// Spreads the 21 low bits of v to every third bit (bit b to bit 3b).
std::uint64_t spread_bits(std::uint32_t v) {
  std::uint64_t x = v & 0x1fffffu;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}

int ceil_log2(std::uint64_t n) {
  int bits = 0;
  while (bits < 64 && (std::uint64_t{1} << bits) < n) ++bits;
  return bits;
}

void check_input(std::span<const double> positions, std::span<const double> weights, SfcCurve curve) {
  require(curve == SfcCurve::morton || curve == SfcCurve::hilbert, ErrorCode::invalid_argument, kWhere,
          "curve must be SfcCurve::morton or SfcCurve::hilbert, got " + std::to_string(static_cast<int>(curve)));
  require(positions.size() % 3 == 0, ErrorCode::invalid_input, kWhere,
          "local positions have " + std::to_string(positions.size()) + " entries, not a multiple of 3");
  require_finite(positions, kWhere, "local positions", 3);
  const std::size_t n = positions.size() / 3;
  if (weights.empty()) return;
  require_size(weights, n, kWhere, "local weights");
  for (std::size_t i = 0; i < n; ++i) {
    if (!(std::isfinite(weights[i]) && weights[i] >= 0.0)) {
      fail(ErrorCode::invalid_input, kWhere,
           "weight of local particle " + std::to_string(i) + " must be finite and >= 0, got " +
               format_number(weights[i]));
    }
  }
}

// The fixed point of the weights: q_i = round(w_i · 2^shift) <= 2^bits with bits = 62 - ceil(log2 N),
// so that the sum of all N fits 62 bits; all weights 0 count as 1 each.
struct WeightScale {
  int shift = 0;
  bool unit_weights = false;
  [[nodiscard]] std::uint64_t quantize(double w) const {
    return unit_weights ? 1 : static_cast<std::uint64_t>(std::llround(std::ldexp(w, shift)));
  }
};

WeightScale weight_scale(double w_max, std::uint64_t n_global) {
  WeightScale s;
  if (!(w_max > 0.0)) {
    s.unit_weights = true;
    return s;
  }
  int e = 0;
  (void)std::frexp(w_max, &e);  // w_max < 2^e
  s.shift = (62 - ceil_log2(n_global)) - e;
  return s;
}

// The global order's composite position of (key, index).
Composite composite(const SfcKey& k, std::uint64_t n_global) {
  return static_cast<Composite>(k.key) * n_global + k.index;
}

// The local particles' q before each of `count` increasing probes lo + j step (j = 1 .. count),
// appended to `sums`: one binary search per probe, each starting where the previous one ended.
void append_weights_before(Composite lo, Composite step, std::size_t count, std::span<const SfcKey> sorted,
                           std::span<const std::uint64_t> prefix, std::uint64_t n_global,
                           std::vector<std::uint64_t>& sums) {
  auto it = sorted.begin();
  for (std::size_t j = 1; j <= count; ++j) {
    const Composite v = lo + step * j;
    it = std::partition_point(it, sorted.end(), [&](const SfcKey& k) { return composite(k, n_global) < v; });
    sums.push_back(prefix[static_cast<std::size_t>(it - sorted.begin())]);
  }
}

// One cut's search interval: weight before lo < target <= weight before hi; found when hi = lo + 1
// (or hi = 0 for target 0). A round splits (lo, hi] into sub-intervals of ceil(width / k) and
// probes their upper ends below hi.
struct CutInterval {
  Composite lo = 0, hi = 0;
  std::uint64_t target = 0;
  [[nodiscard]] bool open() const { return hi - lo > 1; }
  [[nodiscard]] Composite step(std::size_t ways) const { return (hi - lo + ways - 1) / ways; }
  [[nodiscard]] std::size_t probes(std::size_t ways) const {
    return static_cast<std::size_t>((hi - lo - 1) / step(ways));
  }
  // Keeps the sub-interval whose upper end is the first probe with a weight of at least target
  // before it (the last one, up to hi, when there is none).
  void narrow(std::size_t ways, std::span<const std::uint64_t> global) {
    const Composite s = step(ways);
    const auto first = static_cast<std::size_t>(
        std::find_if(global.begin(), global.end(), [&](std::uint64_t w) { return w >= target; }) - global.begin());
    if (first < global.size()) hi = lo + s * (first + 1);
    lo += s * first;
  }
};

// The ways of a round with `open` cuts: as many as the budget of sums allows, 2 to kCutMaxWays.
std::size_t ways_of_round(std::size_t open, std::size_t sums_per_round) {
  return std::max<std::size_t>(2, 1 + std::min(sums_per_round / open, kCutMaxWays - 1));
}

// The cut intervals at the start: lo = 0, hi = 2^63 N, the ends of the composites' range.
std::vector<CutInterval> initial_intervals(std::size_t parts, std::uint64_t total_q, std::uint64_t n_global) {
  const Composite end = (static_cast<Composite>(1) << 63) * std::max<std::uint64_t>(n_global, 1);
  std::vector<CutInterval> cuts(parts - 1);
  for (std::size_t r = 1; r < parts; ++r) {
    const Composite t = (static_cast<Composite>(total_q) * r + parts - 1) / parts;  // ceil(r Q / P)
    cuts[r - 1] = CutInterval{0, t == 0 ? 0 : end, static_cast<std::uint64_t>(t)};
  }
  return cuts;
}

struct Cuts {
  std::vector<Composite> at;
  int rounds = 0;
};

// Collective: the cuts v_r (r = 1 .. P-1), each the smallest composite with a weight of at least
// ceil(r Q / P) before it, by a multi-way search in lock step (docs/mpi.md, "Space-filling-curve
// partition"): per round, one MPI_Allreduce of the weights before k - 1 probes of every open cut,
// k = ways_of_round. The answer is unique, so it is the same for every k. Integer sums: the cuts
// depend on the global input only. Local work per round O(open (k - 1) log n).
Cuts find_cuts(const Communicator& comm, std::span<const SfcKey> sorted, std::span<const std::uint64_t> prefix,
               std::uint64_t total_q, std::uint64_t n_global, std::size_t sums_per_round) {
  const auto parts = static_cast<std::size_t>(comm.size());
  if (parts == 1) return {};
  std::vector<CutInterval> cuts = initial_intervals(parts, total_q, n_global);
  std::vector<std::uint64_t> local, global;
  int rounds = 0;
  for (;;) {
    const auto open = static_cast<std::size_t>(
        std::count_if(cuts.begin(), cuts.end(), [](const CutInterval& c) { return c.open(); }));
    if (open == 0) break;
    const std::size_t ways = ways_of_round(open, sums_per_round);
    local.clear();
    for (const CutInterval& c : cuts) {
      if (c.open()) append_weights_before(c.lo, c.step(ways), c.probes(ways), sorted, prefix, n_global, local);
    }
    global.resize(local.size());
    check_mpi(
        MPI_Allreduce(local.data(), global.data(), static_cast<int>(local.size()), MPI_UINT64_T, MPI_SUM, comm.get()),
        "MPI_Allreduce");
    ++rounds;
    std::size_t at = 0;
    for (CutInterval& c : cuts) {
      if (!c.open()) continue;
      const std::size_t probes = c.probes(ways);
      c.narrow(ways, std::span<const std::uint64_t>(global).subspan(at, probes));
      at += probes;
    }
  }
  Cuts out{std::vector<Composite>(cuts.size()), rounds};
  for (std::size_t r = 0; r < cuts.size(); ++r) out.at[r] = cuts[r].hi;
  return out;
}

int checked_int(std::size_t n, const char* what) {
  require(n <= static_cast<std::size_t>(INT_MAX), ErrorCode::not_supported, kWhere,
          std::string(what) + " of " + std::to_string(n) + " particles exceeds MPI's int counts");
  return static_cast<int>(n);
}

// Displacements of counts (exclusive prefix sums), refused beyond int.
std::vector<int> displacements(std::span<const int> counts, const char* what) {
  std::vector<int> d(counts.size());
  std::size_t sum = 0;
  for (std::size_t r = 0; r < counts.size(); ++r) {
    d[r] = static_cast<int>(sum);
    sum += static_cast<std::size_t>(counts[r]);
  }
  (void)checked_int(sum, what);
  return d;
}

// A contiguous MPI datatype of `bytes` bytes, freed on scope exit.
class RecordType {
 public:
  explicit RecordType(int bytes) {
    check_mpi(MPI_Type_contiguous(bytes, MPI_BYTE, &type_), "MPI_Type_contiguous");
    check_mpi(MPI_Type_commit(&type_), "MPI_Type_commit");
  }
  RecordType(const RecordType&) = delete;
  RecordType& operator=(const RecordType&) = delete;
  ~RecordType() { MPI_Type_free(&type_); }
  [[nodiscard]] MPI_Datatype get() const { return type_; }

 private:
  MPI_Datatype type_ = MPI_DATATYPE_NULL;
};

}  // namespace

std::uint64_t morton_key(std::uint32_t ix, std::uint32_t iy, std::uint32_t iz) {
  return spread_bits(ix) << 2 | spread_bits(iy) << 1 | spread_bits(iz);
}

std::uint32_t morton_cell(double c, double origin, double half_side) {
  if (!(half_side > 0.0)) return 0;
  const double t = (0.5 * c - 0.5 * origin) / half_side;  // in [0, 1]: the subtraction is monotone
  const double cell = std::floor(std::ldexp(t, kMortonBitsPerAxis));
  if (!(cell > 0.0)) return 0;
  return cell >= kCells ? kCells - 1 : static_cast<std::uint32_t>(cell);
}

KeyCube global_key_cube(const Communicator& comm, std::span<const double> positions) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::array<double, 6> local{kInf, kInf, kInf, kInf, kInf, kInf};  // minima, then minus maxima
  for (std::size_t i = 0; i + 2 < positions.size(); i += 3) {
    for (std::size_t d = 0; d < 3; ++d) {
      local[d] = std::min(local[d], positions[i + d]);
      local[3 + d] = std::min(local[3 + d], -positions[i + d]);
    }
  }
  std::array<double, 6> global{};
  check_mpi(MPI_Allreduce(local.data(), global.data(), 6, MPI_DOUBLE, MPI_MIN, comm.get()), "MPI_Allreduce");
  KeyCube cube;
  if (global[0] == kInf) return cube;  // no particle anywhere
  for (std::size_t d = 0; d < 3; ++d) {
    cube.origin[d] = global[d];
    cube.half_side = std::max(cube.half_side, 0.5 * -global[3 + d] - 0.5 * global[d]);
  }
  return cube;
}

std::vector<std::uint64_t> sfc_keys(const KeyCube& cube, std::span<const double> positions, SfcCurve curve) {
  const auto key_of = curve == SfcCurve::hilbert ? hilbert_key : morton_key;
  std::vector<std::uint64_t> keys(positions.size() / 3);
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const double* p = positions.data() + 3 * i;
    keys[i] =
        key_of(morton_cell(p[0], cube.origin[0], cube.half_side), morton_cell(p[1], cube.origin[1], cube.half_side),
               morton_cell(p[2], cube.origin[2], cube.half_side));
  }
  return keys;
}

std::vector<std::uint64_t> morton_keys(const KeyCube& cube, std::span<const double> positions) {
  return sfc_keys(cube, positions, SfcCurve::morton);
}

namespace {

// Collective: the global index of this rank's first particle (the input shares concatenated in
// rank order) and the number of particles on all ranks.
std::pair<std::uint64_t, std::uint64_t> global_offset_and_size(const Communicator& comm, std::uint64_t local_size) {
  std::vector<std::uint64_t> counts(static_cast<std::size_t>(comm.size()));
  check_mpi(MPI_Allgather(&local_size, 1, MPI_UINT64_T, counts.data(), 1, MPI_UINT64_T, comm.get()), "MPI_Allgather");
  const std::uint64_t offset = std::accumulate(counts.begin(), counts.begin() + comm.rank(), std::uint64_t{0});
  return {offset, std::accumulate(counts.begin(), counts.end(), std::uint64_t{0})};
}

// Collective: the largest weight on any rank (1 where a rank with particles passed none).
double global_max_weight(const Communicator& comm, std::span<const double> weights, std::size_t local_size) {
  double w_max = 0.0, local_w_max = weights.empty() && local_size > 0 ? 1.0 : 0.0;
  for (double w : weights) local_w_max = std::max(local_w_max, w);
  check_mpi(MPI_Allreduce(&local_w_max, &w_max, 1, MPI_DOUBLE, MPI_MAX, comm.get()), "MPI_Allreduce");
  return w_max;
}

// This rank's particles sorted by (key, global index): their records, the input particle of each
// slot (send_order) and the prefix sums of their quantized weights (prefix[s] = q of the first s).
struct LocalOrder {
  std::vector<SfcKey> sorted;
  std::vector<std::size_t> send_order;
  std::vector<std::uint64_t> prefix;
};

LocalOrder sort_local(const KeyCube& cube, SfcCurve curve, std::span<const double> positions,
                      std::span<const double> weights, std::uint64_t offset, const WeightScale& scale) {
  const std::vector<std::uint64_t> keys = sfc_keys(cube, positions, curve);
  const std::size_t n = keys.size();
  LocalOrder local{std::vector<SfcKey>(n), std::vector<std::size_t>(n), std::vector<std::uint64_t>(n + 1, 0)};
  std::iota(local.send_order.begin(), local.send_order.end(), std::size_t{0});  // keys ascend with index on ties
  std::stable_sort(local.send_order.begin(), local.send_order.end(),
                   [&](std::size_t a, std::size_t b) { return keys[a] < keys[b]; });
  for (std::size_t s = 0; s < n; ++s) {
    const std::size_t i = local.send_order[s];
    local.sorted[s] = SfcKey{keys[i], offset + i};
    local.prefix[s + 1] = local.prefix[s] + scale.quantize(weights.empty() ? 1.0 : weights[i]);
  }
  return local;
}

// The cuts as (key, index) records.
std::vector<SfcKey> splitters_of(std::span<const Composite> cuts, std::uint64_t n_global) {
  const std::uint64_t n = std::max<std::uint64_t>(n_global, 1);
  std::vector<SfcKey> splitters;
  for (Composite c : cuts) {
    splitters.push_back(SfcKey{static_cast<std::uint64_t>(c / n), static_cast<std::uint64_t>(c % n)});
  }
  return splitters;
}

// The owner of each of this rank's particles in (key, index) order, nondecreasing: by the cuts,
// rank r takes [cut r-1, cut r).
std::vector<std::size_t> owners_by_cuts(std::span<const Composite> cuts, std::span<const SfcKey> sorted,
                                        std::uint64_t n_global) {
  std::vector<std::size_t> owner(sorted.size());
  for (std::size_t s = 0, r = 0; s < sorted.size(); ++s) {
    const Composite c = composite(sorted[s], n_global);
    while (r < cuts.size() && cuts[r] <= c) ++r;
    owner[s] = r;
  }
  return owner;
}

// The same by the splitters' keys alone (SfcPartition::aligned_with): the number of splitters
// whose key is at most the particle's.
std::vector<std::size_t> owners_by_keys(std::span<const SfcKey> splitters, std::span<const SfcKey> sorted) {
  std::vector<std::size_t> owner(sorted.size());
  for (std::size_t s = 0, r = 0; s < sorted.size(); ++s) {
    while (r < splitters.size() && splitters[r].key <= sorted[s].key) ++r;
    owner[s] = r;
  }
  return owner;
}

// Collective. How many of this rank's particles go to each owner, and every owner's count and
// quantized weight over all ranks.
struct Owners {
  std::vector<std::size_t> send_count;
  std::vector<std::uint64_t> counts, q;
};

Owners count_owners(const Communicator& comm, std::span<const std::size_t> owner,
                    std::span<const std::uint64_t> prefix) {
  const auto parts = static_cast<std::size_t>(comm.size());
  std::vector<std::uint64_t> local_totals(2 * parts, 0);  // counts, then q
  Owners owners{std::vector<std::size_t>(parts, 0), {}, {}};
  for (std::size_t s = 0; s < owner.size(); ++s) {
    ++owners.send_count[owner[s]];
    local_totals[parts + owner[s]] += prefix[s + 1] - prefix[s];
  }
  for (std::size_t r = 0; r < parts; ++r) local_totals[r] = owners.send_count[r];
  std::vector<std::uint64_t> totals(2 * parts);
  check_mpi(
      MPI_Allreduce(local_totals.data(), totals.data(), static_cast<int>(2 * parts), MPI_UINT64_T, MPI_SUM, comm.get()),
      "MPI_Allreduce");
  owners.counts.assign(totals.begin(), totals.begin() + static_cast<std::ptrdiff_t>(parts));
  owners.q.assign(totals.begin() + static_cast<std::ptrdiff_t>(parts), totals.end());
  return owners;
}

}  // namespace

SfcPartition::SfcPartition(MPI_Comm comm, std::span<const double> positions, std::span<const double> weights,
                           SfcCurve curve, std::size_t cut_sums_per_round)
    : comm_(comm), curve_(curve) {
  comm_.run([&] {
    check_input(positions, weights, curve);
    require(cut_sums_per_round >= 1, ErrorCode::invalid_argument, kWhere, "cut_sums_per_round must be >= 1, got 0");
  });
  // The curve and cut_sums_per_round (as two 32-bit halves, each exact in a double) must agree: one
  // check, and a second only to name what differs.
  const auto curve_value = static_cast<double>(curve);
  if (!same_on_every_rank(comm_, {curve_value, static_cast<double>(cut_sums_per_round >> 32),
                                  static_cast<double>(cut_sums_per_round & 0xffffffffu)})) {
    if (!same_on_every_rank(comm_, {curve_value}))
      fail(ErrorCode::invalid_argument, kWhere, "the ranks pass different curves");
    fail(ErrorCode::invalid_argument, kWhere, "the ranks pass different cut_sums_per_round");
  }
  input_size_ = positions.size() / 3;
  const auto [offset, global_size] = global_offset_and_size(comm_, input_size_);
  global_size_ = global_size;

  cube_ = global_key_cube(comm_, positions);
  const double w_max = global_max_weight(comm_, weights, input_size_);
  const WeightScale scale = weight_scale(w_max, global_size_);
  weight_shift_ = scale.unit_weights ? 0 : scale.shift;
  max_q_ = global_size_ == 0 ? 0 : scale.quantize(scale.unit_weights ? 1.0 : w_max);

  LocalOrder local = sort_local(cube_, curve_, positions, weights, offset, scale);
  send_order_ = std::move(local.send_order);
  std::uint64_t total_q = 0;
  check_mpi(MPI_Allreduce(&local.prefix.back(), &total_q, 1, MPI_UINT64_T, MPI_SUM, comm_.get()), "MPI_Allreduce");
  const Cuts cuts = find_cuts(comm_, local.sorted, local.prefix, total_q, global_size_, cut_sums_per_round);
  splitters_ = splitters_of(cuts.at, global_size_);
  cut_rounds_ = cuts.rounds;

  settle_owners(owners_by_cuts(cuts.at, local.sorted, global_size_), local.sorted, local.prefix);
}

SfcPartition::SfcPartition(const SfcPartition& sources, AlignedTag /*tag*/)
    : comm_(sources.comm_), curve_(sources.curve_), cube_(sources.cube_), splitters_(sources.splitters_) {}

SfcPartition SfcPartition::aligned_with(const SfcPartition& sources, std::span<const double> positions) {
  SfcPartition part(sources, AlignedTag{});
  part.comm_.run([&] { check_input(positions, {}, part.curve_); });
  part.input_size_ = positions.size() / 3;
  const auto [offset, global_size] = global_offset_and_size(part.comm_, part.input_size_);
  part.global_size_ = global_size;
  part.max_q_ = global_size == 0 ? 0 : 1;
  const WeightScale unit{.shift = 0, .unit_weights = true};
  LocalOrder local = sort_local(part.cube_, part.curve_, positions, {}, offset, unit);
  part.send_order_ = std::move(local.send_order);
  part.settle_owners(owners_by_keys(part.splitters_, local.sorted), local.sorted, local.prefix);
  return part;
}

void SfcPartition::settle_owners(std::span<const std::size_t> owner, std::span<const SfcKey> sorted,
                                 std::span<const std::uint64_t> prefix) {
  Owners owners = count_owners(comm_, owner, prefix);
  owned_counts_ = std::move(owners.counts);
  owned_q_ = std::move(owners.q);
  plan_exchange(owners.send_count);
  receive_owned(sorted);
}

// The counts and displacements of the exchange to the owners (MPI's int counts, checked).
void SfcPartition::plan_exchange(std::span<const std::size_t> send_count) {
  const auto parts = static_cast<std::size_t>(comm_.size());
  const auto rank = static_cast<std::size_t>(comm_.rank());
  comm_.run([&] {
    (void)checked_int(input_size_, "sending this rank's share");
    (void)checked_int(static_cast<std::size_t>(owned_counts_[rank]), "receiving this rank's range");
  });
  plan_.send_counts.resize(parts);
  for (std::size_t r = 0; r < parts; ++r) plan_.send_counts[r] = static_cast<int>(send_count[r]);
  plan_.recv_counts.resize(parts);
  check_mpi(MPI_Alltoall(plan_.send_counts.data(), 1, MPI_INT, plan_.recv_counts.data(), 1, MPI_INT, comm_.get()),
            "MPI_Alltoall");
  plan_.send_displs = displacements(plan_.send_counts, "sending this rank's share");
  plan_.recv_displs = displacements(plan_.recv_counts, "receiving this rank's range");
}

// The owned (key, index) records; each sender's block is sorted, so the owned order is their merge.
void SfcPartition::receive_owned(std::span<const SfcKey> sorted) {
  std::vector<SfcKey> received(static_cast<std::size_t>(owned_counts_[static_cast<std::size_t>(comm_.rank())]));
  const RecordType record(static_cast<int>(sizeof(SfcKey)));
  check_mpi(
      MPI_Alltoallv(sorted.data(), plan_.send_counts.data(), plan_.send_displs.data(), record.get(), received.data(),
                    plan_.recv_counts.data(), plan_.recv_displs.data(), record.get(), comm_.get()),
      "MPI_Alltoallv");
  recv_order_.resize(received.size());
  std::iota(recv_order_.begin(), recv_order_.end(), std::size_t{0});
  std::sort(recv_order_.begin(), recv_order_.end(),
            [&](std::size_t a, std::size_t b) { return received[a] < received[b]; });
  owned_.resize(received.size());
  for (std::size_t j = 0; j < owned_.size(); ++j) owned_[j] = received[recv_order_[j]];
}

std::vector<double> SfcPartition::owned_weights() const {
  std::vector<double> w(owned_q_.size());
  for (std::size_t r = 0; r < w.size(); ++r) w[r] = std::ldexp(static_cast<double>(owned_q_[r]), -weight_shift_);
  return w;
}

double SfcPartition::imbalance() const {
  const std::uint64_t total = std::accumulate(owned_q_.begin(), owned_q_.end(), std::uint64_t{0});
  if (total == 0) return 1.0;
  const std::uint64_t largest = *std::max_element(owned_q_.begin(), owned_q_.end());
  return static_cast<double>(largest) * static_cast<double>(owned_q_.size()) / static_cast<double>(total);
}

std::vector<std::vector<double>> SfcPartition::to_owners(std::span<const Column> columns) const {
  return exchange(columns, true);
}

std::vector<std::vector<double>> SfcPartition::to_origin(std::span<const Column> columns) const {
  return exchange(columns, false);
}

std::vector<std::vector<double>> SfcPartition::exchange(std::span<const Column> columns, bool forward) const {
  const char* where = forward ? "rpyfmm::mpi::SfcPartition::to_owners" : "rpyfmm::mpi::SfcPartition::to_origin";
  const std::size_t n_in = forward ? input_size_ : owned_.size();
  const std::size_t n_out = forward ? owned_.size() : input_size_;
  // The columns' layout must be the same on every rank: a signature compared by min and max.
  std::size_t per_record = 0, signature = 0;
  for (std::size_t k = 0; k < columns.size(); ++k) {
    per_record += columns[k].per;
    signature += columns[k].per * (k + 1);
  }
  comm_.run([&] {
    for (std::size_t k = 0; k < columns.size(); ++k) {
      require(columns[k].per > 0, ErrorCode::invalid_argument, where, "column " + std::to_string(k) + " has per = 0");
      require_size(columns[k].values, columns[k].per * n_in, where, "column " + std::to_string(k));
    }
  });
  const std::array<long long, 3> mine{static_cast<long long>(columns.size()), static_cast<long long>(per_record),
                                      static_cast<long long>(signature)};
  std::array<long long, 6> local{mine[0], mine[1], mine[2], -mine[0], -mine[1], -mine[2]}, seen{};
  check_mpi(MPI_Allreduce(local.data(), seen.data(), 6, MPI_LONG_LONG, MPI_MIN, comm_.get()), "MPI_Allreduce");
  if (seen[0] != -seen[3] || seen[1] != -seen[4] || seen[2] != -seen[5]) {
    fail(ErrorCode::invalid_argument, where, "the ranks pass different numbers or widths of columns");
  }
  std::vector<std::vector<double>> out(columns.size());
  for (std::size_t k = 0; k < columns.size(); ++k) out[k].resize(columns[k].per * n_out);
  if (per_record == 0) return out;

  // Pack in the order of the slots of the sending side, exchange, unpack from the receiving side's.
  const std::vector<std::size_t>& pack_order = forward ? send_order_ : recv_order_;
  const std::vector<std::size_t>& unpack_order = forward ? recv_order_ : send_order_;
  std::vector<double> sent(per_record * n_in), got(per_record * n_out);
  for (std::size_t j = 0; j < n_in; ++j) {
    // forward: slot j holds input particle send_order_[j]; back: owned j goes to slot recv_order_[j]
    const std::size_t particle = forward ? pack_order[j] : j;
    double* slot = sent.data() + per_record * (forward ? j : pack_order[j]);
    for (const Column& c : columns) {
      std::copy_n(c.values.data() + c.per * particle, c.per, slot);
      slot += c.per;
    }
  }
  const RecordType record(checked_int(per_record * sizeof(double), "a record"));
  const Plan& p = plan_;
  check_mpi(forward ? MPI_Alltoallv(sent.data(), p.send_counts.data(), p.send_displs.data(), record.get(), got.data(),
                                    p.recv_counts.data(), p.recv_displs.data(), record.get(), comm_.get())
                    : MPI_Alltoallv(sent.data(), p.recv_counts.data(), p.recv_displs.data(), record.get(), got.data(),
                                    p.send_counts.data(), p.send_displs.data(), record.get(), comm_.get()),
            "MPI_Alltoallv");
  for (std::size_t j = 0; j < n_out; ++j) {
    // forward: owned j is received slot recv_order_[j]; back: slot j is input particle send_order_[j]
    const std::size_t particle = forward ? j : unpack_order[j];
    const double* slot = got.data() + per_record * (forward ? unpack_order[j] : j);
    for (std::size_t k = 0; k < columns.size(); ++k) {
      std::copy_n(slot, columns[k].per, out[k].data() + columns[k].per * particle);
      slot += columns[k].per;
    }
  }
  return out;
}

}  // namespace rpyfmm::mpi
