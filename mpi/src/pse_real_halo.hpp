// rpyfmm — the real-space part M_r of DistributedPseRpy ([PSE] eq. 10 with App. A; docs/mpi.md
// "Distributed PSE"): the serial real-space sum on a rank's particles and its halo.
// [PSE]: Fiore, Balboa Usabiaga, Donev & Swan, J. Chem. Phys. 146, 124116 (2017).
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "index_exchange.hpp"
#include "pse/real_space_sum.hpp"
#include "pse/rotation_real_space_sum.hpp"
#include "rpyfmm/mpi/communicator.hpp"
#include "rpyfmm/rpy/geometry.hpp"

namespace rpyfmm::mpi::detail {

class RealSpaceHalo {
 public:
  /// The serial operator's real-space sum for these parameters (PseRpy's table and cache choices).
  RealSpaceHalo(const rpy::pse::PseParameters& p, const std::array<double, 3>& box, double viscosity, bool use_table,
                rpy::pse::detail::PairCache cache, std::size_t cache_limit_bytes);

  /// Collective: this rank's positions (wrapped into the box, 3 n), the halo of the other ranks'
  /// particles within r_cut of their box, and the pair lists on both.
  void set_positions(const Communicator& comm, const rpy::Geometry& geometry, std::span<const double> x);
  /// Collective: out += M_r F for this rank's particles (3 n each; the self term included), the
  /// halo's forces from their ranks.
  void apply(const Communicator& comm, const double* forces, double* out) const;
  /// Collective: U += M_r^{UF} F + M_r^{UT} T and W += M_r^{WF} F + M_r^{WT} T (with the rotational
  /// self term) for this rank's particles (3 n each), the halo's forces and torques from their
  /// ranks: the serial RealSpaceSum and RotationRealSpaceSum over the same neighbour lists, as
  /// PseRpy's product with rotation adds them. The rotational table is built by the first call.
  void apply_rotation(const Communicator& comm, const double* forces, const double* torques, double* velocities,
                      double* angular) const;

  [[nodiscard]] std::size_t halo_size() const { return exchange_.received(); }
  /// The halo's exchanges since set_positions (its positions', then every product's loads).
  [[nodiscard]] IndexExchange::Traffic traffic() const { return exchange_.traffic; }

 private:
  rpy::pse::detail::RealSpaceSum sum_;
  rpy::pse::PseParameters params_;
  std::array<double, 3> box_;
  double viscosity_;
  double r_cut_;
  mutable std::unique_ptr<rpy::pse::detail::RotationRealSpaceSum> rotation_;
  std::vector<double> x_;  // this rank's positions, then the halo's (the sums' input order)

  // This rank's 3 n values followed by the halo's, received from their ranks (collective).
  [[nodiscard]] std::vector<double> with_halo(const Communicator& comm, const double* values, const char* what) const;
  mutable IndexExchange exchange_;
  std::size_t n_ = 0;  // this rank's particles; the halo's follow them in the sum's input order
};

}  // namespace rpyfmm::mpi::detail
