// The stages of one LaplaceFmm::evaluate call (docs/theory/fmm.md; W. Guan, "Fast Algorithms for
// Brownian Dynamics with Hydrodynamic Interactions", PhD dissertation, University of North Carolina
// at Chapel Hill, Algorithm 1; Cheng, Greengard & Rokhlin, J. Comput. Phys. 155 (1999) §4):
//
//   sort the charges into tree order
//   upward pass:    P2M at the leaves, M2M towards the root
//   downward pass, level by level: L2L from the parent, X-list P2L, plane-wave M2L (V list)
//   leaves:         L2P, W-list M2P and the W/X pairs summed directly, U-list P2P
//   curl_grad_div and grad_div groups folded (docs/theory/fmm.md, section 2)
//   results back into the caller's order
//
// Each stage is one parallel loop over the boxes of a level or over the leaves; every output of a
// box is written by one thread, so results do not depend on the number of threads.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/fmm/detail/expansions.hpp"
#include "rpyfmm/fmm/detail/octree.hpp"
#include "rpyfmm/fmm/detail/planewave.hpp"
#include "rpyfmm/fmm/laplace_fmm.hpp"

namespace rpyfmm::fmm {

/// The plan of LaplaceFmm::set_points: the tree, the expansion order and the order-p tables.
struct LaplaceFmm::Plan {
  detail::Octree tree;
  int p = 0, planewave_nodes = 0, leaf_capacity = 0;
  double root_scale = 1.0;
  // W/X boxes with at most this many sources/targets are summed directly instead of by M2P/P2L;
  // with export_direct those direct sums are left to the caller (near_field() pairs).
  std::size_t direct_limit = 0;
  SimdLevel simd_level = SimdLevel::scalar;  // the level the parameters were chosen for
  bool export_direct = false;
  const detail::Harmonics* H = nullptr;
  const detail::ChildTranslations* ct = nullptr;
  const detail::PlaneWave* pw = nullptr;
  std::size_t n = 0, m = 0;
  std::vector<double> sx, sy, sz, tx, ty, tz;  // sorted coordinates, structure of arrays
};

namespace detail {

// Loops over fewer boxes than this run on one thread: the fork/join (and, on a loaded machine, the
// barrier spin) costs more than the work. Results do not depend on it (each item is one thread's).
inline constexpr std::size_t kMinParallel = 32;

/// The working state of one evaluate call: the densities and results in tree order and the
/// multipole (mp) and local (lp) expansions of every box, nd densities of ncoef(p) scaled
/// coefficients each, box b at b * stride.
struct Evaluation {
  Evaluation(const LaplaceFmm::Plan& plan, std::size_t nd, std::span<const unsigned> outputs);

  const LaplaceFmm::Plan& plan;
  const Octree& tree;
  const std::vector<Box>& boxes;
  int p = 0, nc = 0;  // order, coefficients per density
  std::size_t nd = 0, N = 0, M = 0, stride = 0;
  std::span<const unsigned> requested;  // per density: the caller's flags
  // Per density: potential | gradient | hessian, what every stage but L2P evaluates; a
  // curl_grad_div group asks for gradient | hessian, a grad_div group for hessian and its own
  // potential | gradient (folded by fold_combined_groups).
  std::vector<unsigned> outputs;
  std::vector<std::size_t> groups;    // first density of every curl_grad_div and grad_div group
  std::size_t combined_per_coef = 0;  // the groups' combined coefficients per ncoef(p)
  unsigned any_flags = 0;             // union of outputs
  bool uniform_flags = false;         // every density asks for the same outputs
  std::vector<double> qs;             // charges in tree order, nd x N
  std::vector<double> res;            // results in tree order, nd x M x result_width
  std::vector<cplx> mp, lp;
  std::vector<char> has_local;       // the box's local expansion has received a contribution
  std::vector<double> leaf_seconds;  // per leaf (tree.leaves() order): the leaf passes' wall time
};

/// Adds the wall time of its scope to ev.leaf_seconds[leaf]: the measured per-leaf cost
/// (LaplaceFmm::last_target_costs). Each leaf is one thread's within a pass.
class LeafTimer {
 public:
  LeafTimer(Evaluation& ev, std::size_t leaf) : slot_(&ev.leaf_seconds[leaf]) {}
  LeafTimer(const LeafTimer&) = delete;
  LeafTimer& operator=(const LeafTimer&) = delete;
  ~LeafTimer() { *slot_ += watch_.seconds(); }

 private:
  double* slot_;
  StopWatch watch_;
};

/// Charges into tree order (qs); results (res) zeroed.
void sort_charges(Evaluation& ev, std::span<const double> charges);
/// Upward pass, P2M: multipoles of the leaves from their sources.
void form_leaf_multipoles(Evaluation& ev);
/// Upward pass, M2M: multipoles of the parents from their children, deepest level first.
void merge_child_multipoles(Evaluation& ev);
/// Downward pass, L2L: the parent's local expansion shifted to the boxes of level l.
void shift_parent_locals(Evaluation& ev, int level);
/// Downward pass, X list: P2L of the sources of X-list boxes into the boxes of level l.
void x_list_to_locals(Evaluation& ev, int level);
/// Downward pass, V list: plane-wave M2L with merge-and-shift into the boxes of level l >= 2
/// (plane_wave_m2l.cpp).
void plane_wave_m2l(Evaluation& ev, int level);
/// Leaves, L2P: the local expansions evaluated at the targets.
void evaluate_leaf_locals(Evaluation& ev);
/// Leaves, W list: M2P, and the W/X interactions summed directly (few sources or targets).
void w_list_and_direct_far(Evaluation& ev);
/// Leaves, U list: P2P with the adjacent leaves.
void u_list_direct(Evaluation& ev);
/// curl_grad_div groups: curl and grad div (laplace_fmm.hpp) from their gradient and Hessian
/// columns into the group's first row, the rest of its rows zeroed; grad_div groups: grad div from
/// their Hessian columns into the first row's columns 4..6, the other Hessian columns zeroed.
void fold_combined_groups(Evaluation& ev);
/// Results back into the caller's order.
void unsort_results(const Evaluation& ev, std::span<double> results);
/// Each target's share of its leaf's measured seconds (leaf_seconds), in the caller's order.
[[nodiscard]] std::vector<double> target_costs(const Evaluation& ev);

}  // namespace detail
}  // namespace rpyfmm::fmm
