// rpyfmm — PSE real-space product U = M_r F on the CPU: neighbour lists from a
// cell list (cells of edge >= r_cut, minimum image), rows computed in parallel
// (each thread writes only its own rows: no races, deterministic). Private.
//
// Particles are renumbered internally in cell order ("slots"): positions are kept by slot
// (structure of arrays), the neighbour lists hold slots, and apply() gathers the forces into
// slot order once, so that a row reads its neighbours' positions and forces from a few nearby
// cache lines instead of from all over the input arrays (design note 16). Where the AVX-512
// kernels run, each pair is evaluated once for both of its rows (half lists, design note 22).
// The first product after set_positions keeps each pair's block (F, G, r^) in a pair cache that the later products with
// the same positions read instead of evaluating the pair again (design note 23): per half-list chunk with the AVX-512
// kernels, per entry of the full rows with the portable ones.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "rpyfmm/rpy/pse/pse_parameters.hpp"
#include "rpyfmm/rpy/pse/real_space.hpp"

namespace rpyfmm::rpy::pse::detail {

/// Storage of the pair cache: none, or the five lanes F, G, e_x, e_y, e_z of each pair in float
/// or in double.
enum class PairCache { off, single_precision, double_precision };

class RealSpaceSum {
 public:
  /// `cache`: the pair cache's precision (off: every product evaluates the pairs);
  /// `cache_limit_bytes`: it is kept only for positions whose cache fits in this many bytes.
  /// `full_lists`: always list both directions of every pair (full rows, as the CUDA kernels
  /// read them), never the half rows of the AVX-512 path, whose full rows would be derived by a
  /// serial pass at every set_positions: at 1e6 particles the full build costs 0.26 s on 1
  /// thread and 0.15 s on 2 (half build 0.15 / 0.085 s plus 0.058 s serial), and scales on.
  RealSpaceSum(const PseParameters& p, const std::array<double, 3>& box, double viscosity, bool use_table,
               PairCache cache = PairCache::off, std::size_t cache_limit_bytes = 0, bool full_lists = false);

  /// Cell order and neighbour lists (CSR over slots, ascending) for positions wrapped into the box.
  void set_positions(std::span<const double> x);
  /// U (+)= M_r F for nrhs right-hand sides (3N each, stored one after another). Where the pair
  /// cache is kept, the first product after set_positions fills it, and every product applies the
  /// blocks as kept (rounded to the cache's precision).
  void apply(const double* forces, double* out, std::size_t nrhs, bool accumulate) const;
  /// U = M_r F with F and U in slot order (3 per slot, slot = position in cell order), nrhs of
  /// them: the same products without the gather from and the scatter to input order, for
  /// iterations that stay in slot order (the split sampler's Lanczos). Fills the pair cache at once.
  void apply_slots(const double* forces, double* out, std::size_t nrhs) const;
  /// out[3 s + d] = in[3 i(s) + d] (input -> slot order) and its inverse, one 3N vector.
  void to_slots(const double* in, double* out) const;
  void from_slots(const double* in, double* out) const;
  /// Bytes of the pair cache for the current positions (0: not kept, see the constructor).
  [[nodiscard]] std::size_t cache_bytes() const { return cache_on_ ? cache_bytes_ : 0; }

  [[nodiscard]] const PseRealSpaceTable& table() const { return table_; }
  /// The neighbour lists in input numbering (CSR, j ascending).
  void input_order_lists(std::vector<std::size_t>& begin, std::vector<int>& list) const;
  /// The slot order (order[s]: the input index of slot s) and the full neighbour lists in slot
  /// numbering (CSR: row s is list[begin[s] .. begin[s + 1]), ascending), as the CUDA kernels
  /// read them. Valid until the next set_positions.
  struct SlotLists {
    std::span<const std::size_t> order;
    std::span<const std::size_t> begin;
    std::span<const int> list;
  };
  [[nodiscard]] SlotLists slot_lists() const;
  [[nodiscard]] double self() const { return self_; }
  [[nodiscard]] double mobility_unit() const { return m0_; }

 private:
  PseParameters p_;
  std::array<double, 3> box_;
  double m0_;    // 1 / (6 pi mu a)
  double self_;  // F(0)
  bool use_table_;
  PseRealSpaceTable table_;
  std::vector<std::size_t> order_;          // slot -> input index (particles sorted by cell)
  std::array<std::vector<double>, 3> pos_;  // positions by slot, one array per axis
  std::vector<std::size_t> begin_;          // per slot: range in list_
  std::vector<int> list_;                   // neighbour slots within r_cut (r > 0 or coincident)
  mutable std::vector<double> work_;        // forces gathered into slot order (3 arrays per rhs)
  mutable std::vector<double> packed_;      // AVX-512 kernel: x, y, z, fx, fy, fz, 0, 0 per slot and rhs
                                            // (fx, fy, fz, 0 where the pair cache is read)

  // The list build's per-block parts (kept: their memory is reused by the next set_positions).
  std::vector<std::vector<int>> block_lists_;

  // Half lists (AVX-512 path, design note 22): each pair once, from its lower slot, which adds
  // the pair's block to both rows. upper_[s]: the first entry of row s with a larger slot (the
  // rows are ascending, so the half list is the row's tail). A row writes to its own slot and to
  // larger slots among the 27 cells around it; the cell grid is cut along x and y (where they
  // have >= 4 cells) into blocks of >= 2 cells, an even number per axis, and blocks of one
  // colour (their parities along the cut axes) never write to the same slot, so each colour
  // runs in parallel without atomics. Without a cell grid (fewer than 3 cells along an axis)
  // the full rows run.
  struct SlotRange {
    std::size_t begin, end;
  };
  bool half_ = false;         // half-list blocks planned (the AVX-512 path then uses them)
  bool avx512_rows_ = false;  // the AVX-512 rows run (simd_level() at set_positions)
  // list_ holds only the half rows (t > s) when the half-list path is expected at
  // set_positions (AVX-512 with the table on a cell grid); full rows, which the portable rows,
  // the closed forms and the CUDA lists need, are then derived once on demand.
  bool half_lists_ = false;
  bool full_lists_only_ = false;  // constructor's full_lists: half_lists_ stays false
  struct Rows {
    const std::size_t* begin;
    const int* list;
  };
  [[nodiscard]] Rows full_rows() const;
  mutable bool full_ready_ = true;
  mutable std::vector<std::size_t> full_begin_;
  mutable std::vector<int> full_list_;
  std::vector<std::size_t> upper_;
  // Pair cache (design note 23). AVX-512 layout: per half row s, chunks [chunk_begin_[s],
  // chunk_begin_[s + 1]) of eight pairs, each five vectors of eight lanes (F - F(0), G - G(0),
  // e_x, e_y, e_z as the half-list kernel computes them, padding lanes included). Row layout
  // (portable rows): the same five values per entry of the full rows, in five arrays. Float or
  // double; filled by the first product after set_positions and read by the later ones. The fill rounds the values to
  // the cache's precision before using them, so that every product applies the same operator.
  PairCache cache_ = PairCache::off;
  std::size_t cache_limit_ = 0;
  bool cache_on_ = false;    // cache kept for these positions (within the limit)
  bool cache_rows_ = false;  // layout: per entry of the full rows (portable rows), else half-list chunks
  std::size_t cache_bytes_ = 0;
  std::vector<std::size_t> chunk_begin_;
  std::unique_ptr<double[]> cache_store_;  // 64-byte aligned inside (cache_data())
  std::size_t cache_capacity_ = 0;         // doubles allocated
  mutable bool cache_ready_ = false;
  [[nodiscard]] void* cache_data() const;
  /// apply / apply_slots: particle i(s) = map[s] (input order), or s where map is null;
  void apply_mapped(const double* forces, double* out, std::size_t nrhs, bool accumulate, const std::size_t* map) const;
  std::array<std::vector<std::vector<SlotRange>>, 4> half_blocks_;  // per colour: blocks of slot ranges
  mutable std::vector<double> acc_;                                 // half-list sums, 4 doubles per slot and rhs
  void plan_half_blocks(const std::array<int, 3>& nc, const std::vector<std::size_t>& cell_begin);
  /// The half rows on `packed` rows (x, y, z, fx, fy, fz, 0, 0), filling the pair cache where it
  /// is kept and not yet filled; and the half rows from the filled cache on force rows (fx, fy,
  /// fz, 0).
  void apply_half_avx512(const double* packed, const double* table, double inv_dr, const double L[3],
                         const double inv_L[3], std::size_t nrhs, double* acc) const;
  void apply_cached_avx512(const double* forces, std::size_t nrhs, double* acc) const;
};

}  // namespace rpyfmm::rpy::pse::detail
