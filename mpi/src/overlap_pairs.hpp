// rpyfmm — the overlap correction of DistributedFmmRpy (docs/mpi.md, "Distributed FmmRpy"): for
// every pair of particles closer than the sum of their radii, on any ranks, the exact RPY block
// minus the far form that the Laplace far field sums for it (docs/theory/rpy.md; Zuk, Wajnryb,
// Mizerski & Szymczak, J. Fluid Mech. 741, R5 (2014), eqs. (10)-(12)).
//
// The particles move to the owners of a space-filling-curve partition (SfcPartition). Every owner
// publishes a cover of its particles by tight boxes (the region of the distributed Laplace FMM,
// gather_regions) and sends every other owner the particles within a_j + a_max of its region (the
// halo: an overlapping partner of particle i lies within a_i + a_j <= a_max + a_j of it). Each
// owner finds its particles' overlapping partners among its own and the halo particles in a grid
// of cells of side >= 2 a_max and stores each pair's scalar corrections. Each product sends the
// forces of the halo once (one MPI_Alltoallv) and the corrections back to the input ranks. The
// wall time and received bytes of these exchanges are kept (OverlapTraffic) for
// DistributedFmmRpy::communication().
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/mpi/partition.hpp"

namespace rpyfmm::mpi::detail {

/// The correction of one overlapping pair (i owned, j owned or halo): M_exact - M_far =
/// (df I + dgr d d^T) / eta with d = x_i - x_j (df, dgr times eta). Coincident points (d = 0)
/// carry the whole exact block: the Laplace sums skip them.
struct OverlapPair {
  std::size_t j = 0;
  double df = 0.0, dgr = 0.0;
};

/// The far form of the RPY pair scalars (times eta) at 0 < r: what combine_far_field evaluates for
/// a pair at any distance (Zuk et al. 2014, eq. (10) continued to r <= ai + aj):
///   f = (1 + (ai^2 + aj^2) / (3 r^2)) / (8 pi r),  g = (1 - (ai^2 + aj^2) / r^2) / (8 pi r).
void far_form_scalars(double r, double ai, double aj, double& f, double& g);

/// The rotational correction of the ordered pair (i, j) at distance r < ai + aj, times eta: the
/// coefficients of rpy::rpy_rotation_scalars minus their far form rpy::rpy_rotation_far (what the
/// curl and grad div sums of the far field give every pair at r > 0; docs/theory/rpy.md, section 7),
/// in the form applied to d = x_i - x_j:
///   U_i += ut (T_j x d),   W_i += wf (F_j x d) + h T_j + k d (d . T_j),
/// i.e. the couplings divided by r and k by r^2. Coincident points (r = 0, skipped by the Laplace
/// sums) carry the exact block: h = 1 / (8 pi max(ai, aj)^3), the rest 0.
struct RotationCorrection {
  double ut = 0.0, wf = 0.0, h = 0.0, k = 0.0;
};
[[nodiscard]] RotationCorrection rotation_correction(double r, double ai, double aj);

/// What bounds the rounding the correction leaves: the requested tolerance and the largest |x_c| of
/// all ranks' positions in the far field's frame (about half the extent of the whole set).
struct RoundingLimits {
  double tolerance = 1e-6;
  double reach = 0.0;
};

/// The rounding left of a pair's far form after the correction takes it back, relative to its
/// exact block: the Laplace sums carry the dipole term (ai^2 + aj^2) / r^3 and, through
/// x_m E(F^m) - E(x.F), terms of |x| / r^2, each rounded to 2^-53 of itself, against an exact
/// block of order 1 / max(ai, aj):
///   2^-52 max(ai, aj) ((ai^2 + aj^2) / r^3 + reach / r^2)   (0 for coincident points).
/// Measured: 1.8e-7 for 150 pairs at r = 1e-3 a among 300 particles, where this gives 4.4e-7.
/// It bounds the rotational blocks' rounding too: their far forms are harmonic fields of the
/// forces and torques themselves (no x-weighted densities), which exceed the exact blocks (of
/// order 1 / max(ai, aj)^2 and 1 / max(ai, aj)^3) by at most (max(ai, aj) / r)^2 and
/// (max(ai, aj) / r)^3, within the dipole term 2^-52 max(ai, aj) (ai^2 + aj^2) / r^3 above.
[[nodiscard]] double cancellation_error(const double* d, double ai, double aj, double reach);

/// This rank's exchanges of the overlap correction: wall time (packing, MPI calls and waits) in
/// the construction (the partition, the positions to the owners, the regions, the halo and the
/// count of pairs) and in the last add; bytes received in the last add (forces to the owners, this
/// rank's own share included as SfcPartition moves it; halo loads; corrections back), of which
/// halo_bytes_received are the halo loads, all from other ranks. All 0 in an add when no rank has
/// an overlapping pair (nothing is exchanged).
struct OverlapTraffic {
  double setup_seconds = 0.0;
  double add_seconds = 0.0;
  std::uint64_t add_bytes_received = 0;
  std::uint64_t halo_bytes_received = 0;
};

class OverlapCorrection {
 public:
  /// Collective. This rank's positions (3n) and radii (n) in the operator's units; a_max: the
  /// largest radius on all ranks. Builds the partition, exchanges the halo and finds the pairs.
  /// Throws rpyfmm::Error (not_supported) on every rank when a pair's cancellation_error exceeds
  /// limits.tolerance, naming the lowest failing rank's worst pair by global indices.
  OverlapCorrection(const Communicator& comm, std::span<const double> x, std::span<const double> a, double a_max,
                    const RoundingLimits& limits);

  /// Collective. u (3n, this rank's particles in input order) += sum over the overlapping partners j
  /// of particle i of (df f_j + dgr d (d . f_j)): the corrections times eta, for the forces f (3n)
  /// of this rank's particles; for nrhs such vectors one after another in f and u (3n nrhs each),
  /// with one halo exchange for all of them, each corrected as it would be alone. Nothing is
  /// exchanged when no rank has an overlapping pair.
  void add(std::span<const double> f, std::span<double> u, std::size_t nrhs) const;

  /// Collective. The same with rotation, for the torques t (3n) beside the forces: u += the
  /// corrections of add(f, u) plus sum_j ut (t_j x d), and w (3n) += sum_j wf (f_j x d) + h t_j +
  /// k d (d . t_j) with the rotation_correction of each pair (times eta). One halo exchange of
  /// forces and torques together.
  void add(std::span<const double> f, std::span<const double> t, std::span<double> u, std::span<double> w) const;

  /// Overlapping pairs (ordered: (i, j) and (j, i) count twice) of all ranks; halo particles received.
  [[nodiscard]] std::uint64_t global_pairs() const { return global_pairs_; }
  [[nodiscard]] std::size_t halo_size() const { return halo_n_; }
  [[nodiscard]] const OverlapTraffic& traffic() const { return traffic_; }

 private:
  void exchange_halo(std::span<const double> owned_x, std::span<const double> owned_a, double a_max);
  void find_pairs(std::span<const double> owned_a, double a_max);
  void require_resolvable(const RoundingLimits& limits) const;
  // The columns of the owned particles (to the owners), each followed by the halo particles' values.
  [[nodiscard]] std::vector<std::vector<double>> owned_and_halo(std::span<const Column> columns) const;
  // The owned particles' corrections back to the input ranks and order (SfcPartition::to_origin).
  [[nodiscard]] std::vector<std::vector<double>> to_origin(std::span<const Column> columns) const;
  // Owned particle i's translational corrections for the forces f (owned, then halo) into ui (3).
  void add_translation(std::size_t i, const double* f, double* ui) const;
  // Its rotational corrections for the forces f and torques t into ui and wi (3 each).
  void add_rotation(std::size_t i, const double* f, const double* t, double* ui, double* wi) const;

  Communicator comm_;
  std::unique_ptr<SfcPartition> partition_;
  std::size_t owned_n_ = 0, halo_n_ = 0;
  std::vector<double> points_, radii_;          // owned, then halo from each rank in rank order
  std::vector<std::uint64_t> index_;            // the global index of each of points_
  std::vector<std::vector<std::size_t>> sent_;  // owned particles sent to each rank
  std::vector<std::size_t> halo_counts_;        // halo particles from each rank
  std::vector<std::size_t> first_;              // pairs of owned i: [first_[i], first_[i + 1])
  std::vector<OverlapPair> pairs_;
  std::uint64_t global_pairs_ = 0;
  mutable OverlapTraffic traffic_;
};

}  // namespace rpyfmm::mpi::detail
