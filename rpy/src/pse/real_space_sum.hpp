// rpyfmm — PSE real-space product U = M_r F on the CPU ([PSE] eq. 10 with App. A;
// docs/theory/pse.md). Private.
//
// Pieces, one file each:
//  - neighbour_lists.{hpp,cpp}: the cell grid, the slot order (particles sorted by cell), the
//    neighbour lists (CSR over slots, ascending) and the full rows derived from half lists;
//  - list_filter.{hpp,cpp}: the candidate filters of the list build (AVX-512, AVX2);
//  - pair_rows.{hpp,cpp}: the portable rows (linear table, row-layout pair cache, closed forms);
//  - pair_rows_avx512.{hpp,cpp}: the AVX-512 rows (full rows, half rows, half rows from the cache);
//  - half_blocks.{hpp,cpp}: the colouring that lets half rows run in parallel without atomics;
//  - pair_cache.{hpp,cpp}: the pair cache's storage;
//  - real_space_sum.cpp, real_space_apply.cpp: this class, the drivers of set_positions and apply.
//
// Particles are renumbered internally in cell order ("slots"): positions are kept by slot
// (structure of arrays), the neighbour lists hold slots, and apply() gathers the forces into
// slot order once, so that a row reads its neighbours' positions and forces from a few nearby
// cache lines instead of from all over the input arrays. Rows are computed in parallel, each
// thread writing only its own rows (no races, deterministic).
//
// set_positions chooses, once, the row kernel (RowKernel), what the lists hold (ListLayout) and
// whether a pair cache is kept (PairCacheStore): where the AVX-512 kernels run, each pair is
// evaluated once for both of its rows (half lists), and the first product after set_positions
// keeps each pair's block (F, G, e) in the pair cache that the later products with the same
// positions read instead of evaluating the pair again.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <vector>

#include "half_blocks.hpp"
#include "neighbour_lists.hpp"
#include "pair_cache.hpp"
#include "rpyfmm/rpy/pse/pse_parameters.hpp"
#include "rpyfmm/rpy/pse/real_space.hpp"

namespace rpyfmm::rpy::pse::detail {

/// The rows that form the pair sums, chosen at set_positions from the instruction-set level
/// (simd_level()), the table option and the cell grid.
enum class RowKernel {
  /// AVX-512 with the table on a cell grid: each pair once, from its lower slot, adding its block
  /// to both rows; blocks of one colour run in parallel (half_blocks.hpp). Pair cache: chunks of
  /// eight pairs per half row.
  half_avx512,
  /// AVX-512 with the table, no cell grid (fewer than 3 cells along an axis): full rows, no cache.
  full_avx512,
  /// The portable rows with the table (simd_dispatch). Pair cache: per entry of the full rows.
  table,
  /// The closed forms per pair (PseOptions::real_space_table = false: the reference the table is
  /// measured against). No cache.
  closed_form,
};

/// What the neighbour lists hold.
enum class ListLayout {
  /// Both directions of every pair (begin_/list_ are the full rows).
  full,
  /// Only the pairs t > s (half_avx512 without the constructor's full_lists): half the distance
  /// checks. The full rows, which the closed forms, slot_lists() and input_order_lists() need,
  /// are derived on demand...
  half,
  /// ... after which the layout is this one (half rows in begin_/list_, full rows in
  /// full_begin_/full_list_).
  half_and_full,
};

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
  [[nodiscard]] std::size_t cache_bytes() const { return cache_.kept_bytes(); }

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
  bool full_lists_only_;  // constructor's full_lists: the layout is always ListLayout::full
  PseRealSpaceTable table_;

  // The plan of set_positions.
  RowKernel kernel_ = RowKernel::closed_form;
  mutable ListLayout lists_ = ListLayout::full;  // half -> half_and_full on demand (full_rows())

  std::vector<std::size_t> order_;             // slot -> input index (particles sorted by cell)
  std::array<std::vector<double>, 3> pos_;     // positions by slot, one array per axis
  std::vector<std::size_t> begin_;             // per slot: range in list_
  std::vector<int> list_;                      // neighbour slots within r_cut (r > 0 or coincident)
  std::vector<std::size_t> upper_;             // upper_[s]: the first entry of row s with a larger slot (its half row)
  std::vector<std::vector<int>> block_lists_;  // the list build's per-block parts (memory kept)
  mutable std::vector<std::size_t> full_begin_;  // full rows derived from half lists
  mutable std::vector<int> full_list_;
  HalfBlocks half_blocks_;  // half_avx512: per colour, blocks of slot ranges
  PairCacheStore cache_;

  mutable std::vector<double> work_;    // portable rows: forces gathered into slot order (3 arrays per rhs)
  mutable std::vector<double> packed_;  // AVX-512 rows: x, y, z, fx, fy, fz, 0, 0 per slot and rhs
                                        // (fx, fy, fz, 0 where the pair cache is read)
  mutable std::vector<double> acc_;     // half-list sums, 4 doubles per slot and rhs

  /// set_positions: the row kernel and the list layout for this grid and instruction-set level.
  void choose_plan(const CellGrid& grid);

  /// The full rows (derived once from half lists where those are kept).
  [[nodiscard]] Rows full_rows() const;

  // apply stages. apply / apply_slots: particle i(s) = map[s] (input order), or s where map is null.
  void apply_mapped(const double* forces, double* out, std::size_t nrhs, bool accumulate, const std::size_t* map) const;
  /// The table (null for the closed forms), 1 / its spacing, the box and its inverse.
  struct Frame {
    const double* table;
    double inv_dr;
    double L[3], inv_L[3];
  };
  [[nodiscard]] Frame frame() const;
  /// out_r[i(s)] (+)= M0 u for every slot s and rhs r, u = F(0) force(s, r, .) + row(s, r, u).
  template <class Force, class Row>
  void for_each_row(double* out, std::size_t nrhs, bool accumulate, const std::size_t* map, Force&& force,
                    Row&& row) const;

  // AVX-512 rows.
  /// packed_ rows of `width` doubles per slot and rhs (64-byte aligned), the force at `force_at`;
  /// acc: acc_ (half rows' sums, zeroed, 32-byte aligned).
  struct PackedRows {
    double* packed;
    double* acc;
    std::size_t width, force_at;
  };
  /// x, y, z, fx, fy, fz, 0, 0 per slot and rhs; fx, fy, fz, 0 where the filled cache is read.
  [[nodiscard]] PackedRows pack_rows(const double* forces, std::size_t nrhs, const std::size_t* map, bool cached) const;
  void apply_avx512(const double* forces, double* out, std::size_t nrhs, bool accumulate, const std::size_t* map) const;
  /// The half rows on packed rows (x, y, z, fx, fy, fz, 0, 0), filling the pair cache where it is
  /// kept and empty; the half rows from the filled cache on force rows (fx, fy, fz, 0).
  void apply_half_avx512(const double* packed, std::size_t nrhs, double* acc) const;
  void apply_cached_avx512(const double* forces, std::size_t nrhs, double* acc) const;

  // Portable rows, on the forces gathered into slot order.
  /// work_[(3 r + d) n + s] = F_r[3 i(s) + d].
  void gather_forces(const double* forces, std::size_t nrhs, const std::size_t* map) const;
  void apply_table_rows(double* out, std::size_t nrhs, bool accumulate, const std::size_t* map) const;
  void apply_closed_forms(double* out, std::size_t nrhs, bool accumulate, const std::size_t* map) const;
};

}  // namespace rpyfmm::rpy::pse::detail
