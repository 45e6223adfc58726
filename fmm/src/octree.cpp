// Adaptive octree construction and the U, W, X lists (Cheng, Greengard & Rokhlin 1999 §2; Guan,
// dissertation, §2.1; docs/theory/fmm.md).
#include "rpyfmm/fmm/detail/octree.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace rpyfmm::fmm::detail {

namespace {
inline int octant_of(const double* x, const double* c) noexcept {
  return (x[0] >= c[0] ? 1 : 0) | (x[1] >= c[1] ? 2 : 0) | (x[2] >= c[2] ? 4 : 0);
}

BoxLists flatten(std::vector<std::vector<int>>& lists) {
  BoxLists out;
  out.begin.resize(lists.size() + 1, 0);
  for (std::size_t i = 0; i < lists.size(); ++i) out.begin[i + 1] = out.begin[i] + lists[i].size();
  out.items.resize(out.begin.back());
  for (std::size_t i = 0; i < lists.size(); ++i)
    std::copy(lists[i].begin(), lists[i].end(), out.items.begin() + out.begin[i]);
  return out;
}
}  // namespace

std::array<double, 3> Octree::center(int b) const noexcept {
  const Box& bx = boxes_[b];
  const double s = side(bx.level);
  return {root_lo_[0] + (double(bx.ix) + 0.5) * s, root_lo_[1] + (double(bx.iy) + 0.5) * s,
          root_lo_[2] + (double(bx.iz) + 0.5) * s};
}

bool Octree::adjacent(int a, int b) const noexcept {
  const Box* A = &boxes_[a];
  const Box* B = &boxes_[b];
  if (A->level > B->level) std::swap(A, B);
  const int shift = B->level - A->level;
  const std::int64_t ca[3] = {A->ix, A->iy, A->iz};
  const std::int64_t cb[3] = {B->ix, B->iy, B->iz};
  for (int i = 0; i < 3; ++i) {
    const std::int64_t lo = ca[i] << shift;
    const std::int64_t hi = ((ca[i] + 1) << shift) - 1;
    if (cb[i] < lo - 1 || cb[i] > hi + 1) return false;
  }
  return true;
}

void Octree::build(std::span<const double> sources, std::span<const double> targets, const OctreeParams& params) {
  build_boxes(sources, targets, params);
  finish_build(sources, targets);
}

void Octree::build_boxes(std::span<const double> sources, std::span<const double> targets, const OctreeParams& params) {
  same_ = targets.empty();
  const std::size_t n = sources.size() / 3, m = same_ ? 0 : targets.size() / 3;
  double lo[3], hi[3];
  for (int i = 0; i < 3; ++i) {
    lo[i] = std::numeric_limits<double>::infinity();
    hi[i] = -std::numeric_limits<double>::infinity();
  }
  auto extend = [&](std::span<const double> pts) {
    for (std::size_t j = 0; j < pts.size() / 3; ++j)
      for (int i = 0; i < 3; ++i) {
        lo[i] = std::min(lo[i], pts[3 * j + i]);
        hi[i] = std::max(hi[i], pts[3 * j + i]);
      }
  };
  extend(sources);
  extend(targets);
  double side = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  if (!(side > 0.0)) side = std::max(1.0, std::abs(lo[0]) + std::abs(lo[1]) + std::abs(lo[2])) * 1e-3;
  if (params.root_scale > 1.0) {
    // Root enlarged and anchored at the low corner: at the level where its side is split into 2^L
    // boxes, exactly root_scale^-1 2^L of them span the points' extent (FmmOptions::root_scale).
    const double pad = 0.5e-10 * side;
    root_side_ = params.root_scale * side * (1.0 + 1e-10);
    for (int i = 0; i < 3; ++i) root_lo_[i] = lo[i] - pad;
  } else {
    root_side_ = side * (1.0 + 1e-10);
    for (int i = 0; i < 3; ++i) root_lo_[i] = 0.5 * (lo[i] + hi[i]) - 0.5 * root_side_;
  }

  src_perm_.resize(n);
  for (std::size_t j = 0; j < n; ++j) src_perm_[j] = j;
  tgt_perm_.resize(m);
  for (std::size_t j = 0; j < m; ++j) tgt_perm_[j] = j;
  boxes_.assign(1, Box{});
  boxes_[0].src_end = n;
  boxes_[0].tgt_end = same_ ? n : m;
  level_begin_ = {0, 1};
  for (int l = 0; l < params.max_level; ++l) {
    split_level(l, params, sources, same_ ? sources : targets);
    if (int(boxes_.size()) == level_begin_[l + 1]) break;
    level_begin_.push_back(int(boxes_.size()));
  }
  leaves_.clear();
  for (int b = 0; b < int(boxes_.size()); ++b)
    if (boxes_[b].leaf) leaves_.push_back(b);
}

void Octree::finish_build(std::span<const double> sources, std::span<const double> targets) {
  const std::size_t n = sources.size() / 3, m = same_ ? 0 : targets.size() / 3;
  src_xyz_.resize(3 * n);
  for (std::size_t j = 0; j < n; ++j)
    for (int i = 0; i < 3; ++i) src_xyz_[3 * j + i] = sources[3 * src_perm_[j] + i];
  tgt_xyz_.resize(3 * m);
  for (std::size_t j = 0; j < m; ++j)
    for (int i = 0; i < 3; ++i) tgt_xyz_[3 * j + i] = targets[3 * tgt_perm_[j] + i];
  build_lists();
}

namespace {

// Whether the points of a box (sources [sb, se) and targets [tb, te) of the permutations) all
// coincide: such a box is never split (duplicated points).
bool all_coincide(std::span<const double> src, const std::vector<std::size_t>& sperm, std::size_t sb, std::size_t se,
                  std::span<const double> tgt, const std::vector<std::size_t>& tperm, std::size_t tb, std::size_t te) {
  double mn[3], mx[3];
  for (int i = 0; i < 3; ++i) {
    mn[i] = std::numeric_limits<double>::infinity();
    mx[i] = -mn[i];
  }
  for (std::size_t j = sb; j < se; ++j)
    for (int i = 0; i < 3; ++i) {
      mn[i] = std::min(mn[i], src[3 * sperm[j] + i]);
      mx[i] = std::max(mx[i], src[3 * sperm[j] + i]);
    }
  for (std::size_t j = tb; j < te; ++j)
    for (int i = 0; i < 3; ++i) {
      mn[i] = std::min(mn[i], tgt[3 * tperm[j] + i]);
      mx[i] = std::max(mx[i], tgt[3 * tperm[j] + i]);
    }
  return mx[0] == mn[0] && mx[1] == mn[1] && mx[2] == mn[2];
}

// Stable partition of perm[begin, end) by the octant of each point about the centre c; cnt: the
// count per octant. oct, tmp: scratch.
void partition_octants(std::span<const double> pts, std::vector<std::size_t>& perm, std::size_t begin, std::size_t end,
                       const std::array<double, 3>& c, std::size_t* cnt, std::vector<unsigned char>& oct,
                       std::vector<std::size_t>& tmp) {
  const std::size_t len = end - begin;
  oct.resize(len);
  tmp.resize(len);
  for (int o = 0; o < 8; ++o) cnt[o] = 0;
  for (std::size_t j = 0; j < len; ++j) {
    oct[j] = static_cast<unsigned char>(octant_of(&pts[3 * perm[begin + j]], c.data()));
    ++cnt[oct[j]];
  }
  std::size_t pos[8];
  pos[0] = 0;
  for (int o = 1; o < 8; ++o) pos[o] = pos[o - 1] + cnt[o - 1];
  for (std::size_t j = 0; j < len; ++j) tmp[pos[oct[j]]++] = perm[begin + j];  // stable
  std::copy(tmp.begin(), tmp.end(), perm.begin() + begin);
}

}  // namespace

// Splits the boxes of a level that hold more than leaf_capacity points (and are not below
// min_leaf_side, nor of coincident points) into their non-empty children, in parallel over the
// boxes (each partitions only its own range of the permutations); children are appended in box order.
void Octree::split_level(int level, const OctreeParams& params, std::span<const double> src,
                         std::span<const double> tgt) {
  const int lb = level_begin_[level], le = level_begin_[level + 1];
  const double child_side = side(level + 1);
  std::vector<std::array<std::size_t, 16>> counts(le - lb);
  std::vector<char> split(le - lb, 0);
  std::vector<std::size_t>& tperm = same_ ? src_perm_ : tgt_perm_;
#pragma omp parallel if (le - lb >= 16)
  {
    std::vector<std::size_t> tmp;
    std::vector<unsigned char> oct;
#pragma omp for schedule(dynamic, 4)
    for (int b = lb; b < le; ++b) {
      Box& bx = boxes_[b];
      const std::size_t count = bx.nsrc() + (same_ ? 0 : bx.ntgt());
      if (count <= params.leaf_capacity || child_side < params.min_leaf_side) continue;
      if (all_coincide(src, src_perm_, bx.src_begin, bx.src_end, tgt, tperm, bx.tgt_begin,
                       same_ ? bx.tgt_begin : bx.tgt_end))
        continue;
      split[b - lb] = 1;
      const auto c = center(b);
      partition_octants(src, src_perm_, bx.src_begin, bx.src_end, c, counts[b - lb].data(), oct, tmp);
      if (same_) {
        for (int o = 0; o < 8; ++o) counts[b - lb][8 + o] = counts[b - lb][o];
      } else {
        partition_octants(tgt, tgt_perm_, bx.tgt_begin, bx.tgt_end, c, counts[b - lb].data() + 8, oct, tmp);
      }
    }
  }
  for (int b = lb; b < le; ++b)
    if (split[b - lb]) add_children(b, counts[b - lb]);
}

// Appends the non-empty children of box b, whose points are partitioned by octant with the counts
// of sources (counts[0..7]) and targets (counts[8..15]).
void Octree::add_children(int b, const std::array<std::size_t, 16>& counts) {
  std::size_t s0 = boxes_[b].src_begin, t0 = boxes_[b].tgt_begin;
  boxes_[b].leaf = false;
  for (int o = 0; o < 8; ++o) {
    const std::size_t ns = counts[o], nt = counts[8 + o];
    if (ns + nt == 0) continue;  // empty boxes are skipped
    Box ch;
    ch.level = boxes_[b].level + 1;
    ch.ix = 2 * boxes_[b].ix + (o & 1);
    ch.iy = 2 * boxes_[b].iy + ((o >> 1) & 1);
    ch.iz = 2 * boxes_[b].iz + ((o >> 2) & 1);
    ch.parent = b;
    ch.src_begin = s0;
    ch.src_end = s0 + ns;
    ch.tgt_begin = t0;
    ch.tgt_end = t0 + nt;
    s0 += ns;
    t0 += nt;
    boxes_[b].child[o] = int(boxes_.size());
    boxes_.push_back(ch);
  }
}

void Octree::build_lists() {
  const int nb = int(boxes_.size());
  std::vector<std::vector<int>> coll(nb), u(nb), w(nb), x(nb);
  coll[0] = {0};
  for (int l = 1; l < nlevels(); ++l) {
#pragma omp parallel for if (level_end(l) - level_begin(l) >= 64) schedule(dynamic, 16)
    for (int b = level_begin(l); b < level_end(l); ++b) {
      const Box& bx = boxes_[b];
      for (int c : coll[bx.parent])
        for (int ch : boxes_[c].child)
          if (ch >= 0 && std::abs(boxes_[ch].ix - bx.ix) <= 1 && std::abs(boxes_[ch].iy - bx.iy) <= 1 &&
              std::abs(boxes_[ch].iz - bx.iz) <= 1)
            coll[b].push_back(ch);
      std::sort(coll[b].begin(), coll[b].end());
    }
  }
#pragma omp parallel for if (leaves_.size() >= 64) schedule(dynamic, 16)
  for (std::size_t i = 0; i < leaves_.size(); ++i) {
    const int b = leaves_[i];
    u[b].push_back(b);
    std::vector<int> stack;
    for (int c : coll[b]) {
      if (c == b) continue;
      if (boxes_[c].leaf) {
        u[b].push_back(c);
      } else {
        stack.push_back(c);
      }
    }
    while (!stack.empty()) {
      const int d = stack.back();
      stack.pop_back();
      for (int ch : boxes_[d].child) {
        if (ch < 0) continue;
        if (adjacent(ch, b)) {
          if (boxes_[ch].leaf)
            u[b].push_back(ch);
          else
            stack.push_back(ch);
        } else {
          w[b].push_back(ch);
        }
      }
    }
  }
  // Coarser adjacent leaves: symmetrize U; X is the transpose of W.
  for (int b : leaves_)
    for (std::size_t k = 0; k < u[b].size(); ++k) {
      const int c = u[b][k];
      if (boxes_[c].level > boxes_[b].level) u[c].push_back(b);
    }
  for (int b : leaves_)
    for (int c : w[b]) x[c].push_back(b);
  for (int b = 0; b < nb; ++b) {
    std::sort(u[b].begin(), u[b].end());
    std::sort(w[b].begin(), w[b].end());
    std::sort(x[b].begin(), x[b].end());
  }
  coll_ = flatten(coll);
  u_ = flatten(u);
  w_ = flatten(w);
  x_ = flatten(x);
}

std::size_t Octree::memory_bytes() const noexcept {
  auto lists = [](const BoxLists& l) { return l.begin.size() * sizeof(std::size_t) + l.items.size() * sizeof(int); };
  return boxes_.size() * sizeof(Box) + (src_perm_.size() + tgt_perm_.size()) * sizeof(std::size_t) +
         (src_xyz_.size() + tgt_xyz_.size()) * sizeof(double) + lists(coll_) + lists(u_) + lists(w_) + lists(x_);
}

}  // namespace rpyfmm::fmm::detail
