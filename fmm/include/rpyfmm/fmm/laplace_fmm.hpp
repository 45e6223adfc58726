// rpyfmm::fmm — adaptive plane-wave fast multipole method for the 3-D Laplace kernel 1/r.
//
// Cheng, Greengard & Rokhlin, J. Comput. Phys. 155 (1999) 468-498; W. Guan, "Fast Algorithms for
// Brownian Dynamics with Hydrodynamic Interactions", PhD dissertation, University of North Carolina
// at Chapel Hill, ch. 2; docs/theory/fmm.md. Adaptive octree with U/V/W/X lists, scaled spherical-harmonic
// expansions, point-and-shoot M2M/L2L, plane-wave M2L with merge-and-shift in six directions,
// M2P/P2L for the W/X lists, potential/gradient/Hessian at sources and at separate targets.
//
//   phi(x) = sum_j q_j / |x - y_j|   (pairs at distance 0, e.g. the self pair, are skipped)
//
// Usage (plan once, apply many):
//   LaplaceFmm fmm({.tolerance = 1e-6});
//   fmm.set_points(sources);                       // builds tree and lists
//   fmm.evaluate(charges, nd, outputs, results);   // any number of times, const, thread-safe
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <utility>
#include <vector>

#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/fmm/leaf_grid.hpp"

namespace rpyfmm::fmm {

/// Output flag of LaplaceFmm::evaluate for three consecutive densities phi_1..3 (all three carry
/// it, alone): only (curl Phi)_c = d_(c+1) phi_(c+2) - d_(c+2) phi_(c+1) (indices mod 3) and
/// (grad div Phi)_c = sum_m d_c d_m phi_m of the vector field Phi = (phi_1, phi_2, phi_3), in
/// the first density's row, columns 1..3 (curl) and 4..6 (grad div); the rest of the three rows 0.
/// L2P evaluates these six sums from combined local coefficients (docs/theory/fmm.md,
/// section 2, "Combined outputs") instead of the 27 gradient and Hessian columns.
inline constexpr unsigned curl_grad_div = 8u;

/// Output flag of LaplaceFmm::evaluate for three consecutive densities phi_1..3 (all three carry
/// it, each optionally with potential and/or gradient of its own): (grad div Phi)_c =
/// sum_m d_c d_m phi_m of the vector field Phi = (phi_1, phi_2, phi_3) in the first density's row,
/// columns 4..6 (c = x, y, z); the other Hessian columns of the three rows 0; each density's
/// potential and gradient columns as it asks. L2P evaluates the three sums from combined local
/// coefficients (docs/theory/fmm.md, section 2, "Combined outputs") instead of the 18 Hessian
/// columns. FmmRpy's far field takes the Hessians of its force densities only in this form.
inline constexpr unsigned grad_div = 16u;

/// Throws rpyfmm::Error (invalid_argument, naming `where`) unless every entry of `outputs` is a
/// non-empty subset of potential|gradient|hessian or belongs to a group of three consecutive
/// densities flagged curl_grad_div, or grad_div (with potential|gradient only): the flags
/// LaplaceFmm::evaluate accepts.
void require_valid_outputs(std::span<const unsigned> outputs, const char* where);

/// The result columns (0..9 of a row, fmm::Column) LaplaceFmm::evaluate can fill for each density
/// of valid `outputs` (require_valid_outputs), in increasing order: potential 0, gradient 1..3,
/// Hessian 4..9 as each density asks; a grad_div group each density's own potential and gradient
/// columns and the first density's 4..6; a curl_grad_div group the first density's 1..6 and none
/// of the other two. evaluate sets every other column to 0, so a caller that moves results (e.g.
/// between MPI ranks) can move these columns alone.
std::vector<std::vector<std::size_t>> filled_result_columns(std::span<const unsigned> outputs);

/// Options of the FMM plan. The contract (docs/theory/fmm.md, Sec. 7): for each density and output
/// k, the l2 error over the targets is at most tolerance times the l2 norm of the absolute field
/// sum_j |q_j| c_k / r^(k+1), the relative l2 error where the field does not cancel.
struct FmmOptions {
  /// Requested accuracy of each output (see above), in [1e-15, 1e-1]. The plane-wave table is the
  /// one of the next tighter of 1e-3, 1e-6, 1e-9, 1e-12; below 1e-12 the accuracy saturates near 1e-13.
  double tolerance = 1e-6;
  /// Points per leaf before a box is split; 0 = automatic: fmm_default_leaf_capacity (chosen per
  /// tolerance and P2P kernel by benchmark), and for 1e4 to 1e6 points, where that tree's leaves hold
  /// well above the best occupancy (or where a near-uniform cloud's tree is partly split between
  /// two levels: TreeStats::leaf_level_share), leaves fitted to the cloud instead (fit_leaf_grid,
  /// leaf_grid.hpp). stats() reports the capacity and root scale used.
  int leaf_capacity = 0;
  /// Boxes are never split below this side: every pair of points closer than this is in the
  /// near field (U list). 0 = no limit.
  double min_leaf_side = 0.0;
  /// Evaluate the near field (U-list P2P). false = far field only: the caller evaluates the
  /// pairs of near_field() with its own kernel. (W/X interactions of small boxes are still summed
  /// directly with the Laplace kernel: they are far-field pairs, separated by >= the leaf side.)
  bool near_field = true;
  /// With near_field = false only: the W/X interactions that would be summed directly with the
  /// Laplace kernel (boxes with few sources or targets, and in this mode every W/X leaf of at most
  /// leaf_capacity points) are skipped too and listed in near_field().pairs instead, for a caller
  /// whose own pair kernel is cheaper than nd Laplace densities (FmmRpy). Those pairs are well
  /// separated (not adjacent); U-list pairs come first.
  bool export_direct_far = false;
  /// Side of the root box as a multiple of the points' bounding cube, in [1, 8]. 1 (default): the
  /// bounding cube, centred. Above 1 the root is anchored at the points' low corner, so that with
  /// root_scale = 2^L / k the points span exactly k boxes per side at level L: leaves of a chosen
  /// occupancy instead of the octree's factor-8 steps (fit_leaf_grid; the automatic leaves use
  /// this). With root_scale != 1 and leaf_capacity = 0 the automatic capacity is used as it is.
  double root_scale = 1.0;
  /// Expansion order; 0 = from eps (FMM3D's rule, fmm_order_for).
  int order = 0;
  /// Lambda nodes of the plane-wave quadrature, kMinPlaneWaveNodes to kMaxPlaneWaveNodes; 0 = from
  /// the tolerance (fmm_planewave_nodes_for: 12, 20, 29 or 37, near the steps 14, 23, 32 or 39).
  /// More nodes lower the M2L's own error between the four tables' steps (docs/theory/fmm.md,
  /// Sec. 7), for callers that combine outputs with cancellation (FmmRpy); together with `order`.
  int planewave_nodes = 0;
  /// With leaf_capacity > 0 and root_scale = 1: a fitted grid (fit_leaf_grid) replaces the tree of
  /// that capacity where this rule says it pays, e.g. a caller's measured rule (FmmRpy). The
  /// decision takes the bounding-cube tree's boxes only; the lists are built once. Default
  /// (occupancy 0): never. Automatic leaves (leaf_capacity = 0) follow the built-in rule instead.
  FittedGridRule fitted_grid{};
};

/// Shape and cost of a plan.
struct TreeStats {
  int levels = 0;
  std::size_t boxes = 0, leaves = 0;
  std::size_t memory_bytes = 0;  // tree + lists + plan tables (per-apply buffers not included)
  int order = 0;                 // expansion order p
  int nlams = 0;                 // plane-wave quadrature nodes
  int leaf_capacity = 0;         // split threshold of the tree built (the automatic one if chosen)
  double root_scale = 1.0;       // root side / bounding-cube side of the tree built
  std::size_t u_pairs = 0, w_pairs = 0, x_pairs = 0;
  // Fraction of the points (sources and separate targets) in the leaves of the most populated leaf
  // level: 1 where all leaves are on one level; in a near-uniform cloud, well below 1 means a
  // partly split tree (leaves on two levels, W/X lists between them).
  double leaf_level_share = 1.0;
  // The instruction-set level the plan was built for (docs/reproducibility.md: the automatic
  // leaf capacity, fitted grid and direct limit are chosen per level) and the W/X-list direct
  // limit: W/X pairs whose leaf holds at most this many points are summed directly.
  SimdLevel simd_level = SimdLevel::scalar;
  std::size_t direct_limit = 0;
};

/// Near-field structure in the caller's numbering: for every leaf, the source and target indices
/// it holds; and the U-list pairs (target leaf, source leaf), the leaf itself included, followed
/// (FmmOptions::export_direct_far) by the W/X leaf pairs left to the caller.
struct NearField {
  std::vector<std::size_t> source_begin;  // leaf l holds sources source_index[source_begin[l] .. source_begin[l+1])
  std::vector<std::size_t> source_index;
  std::vector<std::size_t> target_begin;  // same for targets (== sources when evaluating at the sources)
  std::vector<std::size_t> target_index;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;  // (target leaf, source leaf)
  [[nodiscard]] std::size_t num_leaves() const noexcept { return source_begin.empty() ? 0 : source_begin.size() - 1; }
  [[nodiscard]] std::span<const std::size_t> sources(std::size_t leaf) const noexcept {
    return {source_index.data() + source_begin[leaf], source_index.data() + source_begin[leaf + 1]};
  }
  [[nodiscard]] std::span<const std::size_t> targets(std::size_t leaf) const noexcept {
    return {target_index.data() + target_begin[leaf], target_index.data() + target_begin[leaf + 1]};
  }
};

class LaplaceFmm {
 public:
  explicit LaplaceFmm(const FmmOptions& options = {});
  ~LaplaceFmm();
  LaplaceFmm(LaplaceFmm&&) noexcept;
  LaplaceFmm& operator=(LaplaceFmm&&) noexcept;

  /// Builds the tree and lists. sources: 3N (x0,y0,z0,x1,...), N >= 1; targets: 3M, or empty to
  /// evaluate at the sources (self pair excluded). Throws rpyfmm::Error on bad input.
  void set_points(std::span<const double> sources, std::span<const double> targets = {});

  /// charges: nd x N (density d at charges[d*N + j]); outputs: nd flags (potential|gradient|hessian,
  /// at least one bit each, or curl_grad_div, or grad_div with any of potential|gradient, on consecutive
  /// groups of three densities); results: nd x M x 10 [pot, gx,
  /// gy, gz, hxx, hyy, hzz, hxy, hxz, hyz], overwritten (unrequested columns = 0). const and thread-safe; results do
  /// not depend on the number of OpenMP threads.
  void evaluate(std::span<const double> charges, std::size_t nd, std::span<const unsigned> outputs,
                std::span<double> results) const;
  /// Convenience: the same output flags for every density.
  void evaluate(std::span<const double> charges, std::size_t nd, unsigned outputs, std::span<double> results) const;

  [[nodiscard]] const FmmOptions& options() const noexcept { return options_; }
  [[nodiscard]] std::size_t num_sources() const noexcept;
  [[nodiscard]] std::size_t num_targets() const noexcept;
  /// Stage times (seconds) of set_points ("tree": tree + lists; "tables": order-p tables, built once
  /// per process) and of the last evaluate ("sort", "p2m", "m2m", "l2l", "x_p2l", "m2l" (plane waves),
  /// "l2p", "wx_far" (W-list M2P and the W/X boxes summed directly), "p2p" (U list), "total").
  [[nodiscard]] StageTimes last_timings() const;
  /// The measured cost of each target in the last evaluate (input order, seconds): the wall time
  /// of the leaf passes (L2P, W list and the far boxes summed directly, U-list P2P) on each target
  /// leaf, shared equally by the leaf's targets; empty before the first evaluate after set_points.
  /// A measurement, so it differs from run to run; results do not depend on it. The distributed
  /// FMM weights its partition by it (rpyfmm/mpi/laplace_fmm.hpp, measured_weights).
  [[nodiscard]] std::vector<double> last_target_costs() const;
  [[nodiscard]] TreeStats stats() const;
  /// Near-field structure (built on first call, then cached).
  [[nodiscard]] const NearField& near_field() const;

  struct Plan;  // implementation

 private:
  FmmOptions options_;
  std::unique_ptr<Plan> plan_;
  mutable std::mutex mutex_;
  mutable StageTimes timings_;
  mutable std::vector<double> target_costs_;
  mutable std::unique_ptr<NearField> near_;
};

/// Expansion order chosen for a tolerance: smallest p >= 2 with (sqrt(3)/2)^p / 1.5^(p+1) < eps,
/// capped at 9 / 18 / 32 / 42 for the 3 / 6 / 9 / 12-digit plane-wave tables (where the error
/// saturates); within a factor 10 above a table's step (eps < 1e-2, 1e-5, 1e-8, 1e-11 in the
/// respective table) 10 / 22 / 32 / 46 instead, for the Hessian (docs/theory/fmm.md, Sec. 7).
int fmm_order_for(double eps);
/// Digits of the plane-wave table used for a tolerance (3, 6, 9 or 12).
int fmm_table_digits_for(double eps);
/// Lambda nodes for a tolerance: the table's 12, 20, 29 or 37, and within a factor 10 above its
/// step 14, 23, 32 or 39 (with the orders of fmm_order_for).
int fmm_planewave_nodes_for(double eps);
/// The range of FmmOptions::planewave_nodes: the separation-1 tables of 12 to 39 lambda nodes.
inline constexpr int kMinPlaneWaveNodes = 12;
inline constexpr int kMaxPlaneWaveNodes = 39;
/// Automatic leaf capacity for a tolerance (measured per plane-wave table; larger where the
/// AVX-512 P2P kernels are active, see simd_level() == SimdLevel::avx512).
int fmm_default_leaf_capacity(double eps);

}  // namespace rpyfmm::fmm
