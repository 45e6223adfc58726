// rpyfmm::fmm — adaptive octree with the U, V, W, X lists of Cheng, Greengard & Rokhlin
// (J. Comput. Phys. 155 (1999) §2; Guan, dissertation, §2.1; docs/theory/fmm.md, "The tree and
// the four lists").
//
// Boxes are stored level by level; empty boxes are never created. All adjacency and offset tests
// use integer box coordinates (level, ix, iy, iz). The tree is *not* level-restricted: the lists
// follow the general CGR definitions
//   U_b (leaf b): b and every leaf adjacent to b (any level)
//   V_b: children of the colleagues of b's parent that are not adjacent to b (implicit: the
//        merge-and-shift pass enumerates them from the parent's colleagues)
//   W_b (leaf b): descendants of b's colleagues whose parent is adjacent to b but that are
//        not adjacent to b themselves
//   X_b: all c with b in W_c.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace rpyfmm::fmm::detail {

struct Box {
  int level = 0;
  std::int64_t ix = 0, iy = 0, iz = 0;  // integer coordinates at this level
  int parent = -1;
  std::array<int, 8> child{-1, -1, -1, -1, -1, -1, -1, -1};  // octant bit0 +x, bit1 +y, bit2 +z
  std::size_t src_begin = 0, src_end = 0;                    // range in the sorted sources
  std::size_t tgt_begin = 0, tgt_end = 0;                    // range in the sorted targets
  bool leaf = true;
  [[nodiscard]] std::size_t nsrc() const noexcept { return src_end - src_begin; }
  [[nodiscard]] std::size_t ntgt() const noexcept { return tgt_end - tgt_begin; }
};

/// Compressed lists: items of box b are items[begin[b] .. begin[b+1]).
struct BoxLists {
  std::vector<std::size_t> begin;
  std::vector<int> items;
  [[nodiscard]] std::span<const int> of(int b) const noexcept {
    return {items.data() + begin[b], items.data() + begin[b + 1]};
  }
};

struct OctreeParams {
  std::size_t leaf_capacity = 100;  // split a box holding more points than this
  double min_leaf_side = 0.0;       // never create boxes of side below this
  double root_scale = 1.0;          // root side / bounding-cube side; > 1: anchored at the low corner
  int max_level = 30;
};

class Octree {
 public:
  /// Builds the tree over `sources` (3N, xyz interleaved) and `targets` (3M; empty = the sources):
  /// build_boxes, then finish_build.
  void build(std::span<const double> sources, std::span<const double> targets, const OctreeParams& params);
  /// The first part of build: the boxes, the permutations into tree order and the leaves. Enough
  /// for the tree's shape (boxes(), leaves(), nlevels()), e.g. to decide on other parameters.
  void build_boxes(std::span<const double> sources, std::span<const double> targets, const OctreeParams& params);
  /// The rest of build after build_boxes with the same points: sorted coordinates and the lists.
  void finish_build(std::span<const double> sources, std::span<const double> targets);

  [[nodiscard]] bool targets_are_sources() const noexcept { return same_; }
  [[nodiscard]] int nlevels() const noexcept { return int(level_begin_.size()) - 1; }
  [[nodiscard]] int level_begin(int l) const noexcept { return level_begin_[l]; }
  [[nodiscard]] int level_end(int l) const noexcept { return level_begin_[l + 1]; }
  [[nodiscard]] const std::vector<Box>& boxes() const noexcept { return boxes_; }
  [[nodiscard]] double side(int level) const noexcept { return root_side_ / double(std::int64_t(1) << level); }
  [[nodiscard]] double root_side() const noexcept { return root_side_; }
  [[nodiscard]] std::array<double, 3> center(int b) const noexcept;
  /// True when the closed boxes a and b touch or overlap (any levels).
  [[nodiscard]] bool adjacent(int a, int b) const noexcept;

  /// Sorted position -> original index.
  [[nodiscard]] const std::vector<std::size_t>& source_order() const noexcept { return src_perm_; }
  [[nodiscard]] const std::vector<std::size_t>& target_order() const noexcept { return same_ ? src_perm_ : tgt_perm_; }
  /// Sorted coordinates, xyz interleaved.
  [[nodiscard]] const std::vector<double>& sorted_sources() const noexcept { return src_xyz_; }
  [[nodiscard]] const std::vector<double>& sorted_targets() const noexcept { return same_ ? src_xyz_ : tgt_xyz_; }

  [[nodiscard]] const BoxLists& colleagues() const noexcept { return coll_; }
  [[nodiscard]] const BoxLists& ulist() const noexcept { return u_; }
  [[nodiscard]] const BoxLists& wlist() const noexcept { return w_; }
  [[nodiscard]] const BoxLists& xlist() const noexcept { return x_; }
  [[nodiscard]] const std::vector<int>& leaves() const noexcept { return leaves_; }
  /// Bytes held by the tree, its permutations and lists.
  [[nodiscard]] std::size_t memory_bytes() const noexcept;

 private:
  void split_level(int level, const OctreeParams& params, std::span<const double> src, std::span<const double> tgt);
  void add_children(int b, const std::array<std::size_t, 16>& counts);
  void build_lists();

  bool same_ = true;
  double root_lo_[3] = {0, 0, 0};
  double root_side_ = 1.0;
  std::vector<Box> boxes_;
  std::vector<int> level_begin_;
  std::vector<std::size_t> src_perm_, tgt_perm_;
  std::vector<double> src_xyz_, tgt_xyz_;
  BoxLists coll_, u_, w_, x_;
  std::vector<int> leaves_;
};

}  // namespace rpyfmm::fmm::detail
