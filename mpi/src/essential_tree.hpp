// rpyfmm — what one rank sends to another of its cells (docs/mpi.md, "Distributed Laplace FMM"):
// the walk of the cell tree against the other rank's region with the acceptance criterion, and
// the Chebyshev order each compressed cell needs at its distance.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "cell_tree.hpp"

namespace rpyfmm::mpi::detail {

/// A cell sent as the equivalent charges of `order`^3 tensor Chebyshev nodes.
struct Compressed {
  std::uint32_t cell = 0;
  int order = 2;
  friend auto operator<=>(const Compressed&, const Compressed&) = default;
};

/// The cells sent to one rank: as their particles (halo) or as equivalent charges (compressed).
struct EssentialCells {
  std::vector<std::uint32_t> halo;
  std::vector<Compressed> compressed;
};

/// The acceptance test and order rule of the walk.
struct Acceptance {
  double tolerance = 1e-6;  // the serial FMM's tolerance
  double separation = 2.0;  // smallest distance / half-side of a compressed cell (eta)
  int max_order = 32;
  int fixed_order = 0;  // > 0: this order for every compressed cell instead of order_at
  // Smallest distance of a compressed cell from the region (the serial FMM's min_leaf_side): pairs
  // closer than it are never in a compressed cell (DistributedFmmRpy: no overlapping pair).
  double min_distance = 0.0;
};

/// The smallest Chebyshev order p >= 2 with rho^-p <= tolerance / 10, rho = eta + sqrt(1 + eta^2)
/// for a cube at distance eta × its half-side (capped at max_order; docs/mpi.md, "Error rule").
[[nodiscard]] int order_at(double tolerance, double eta, int max_order);

/// The order at which a cell (its cube and number of particles) is compressed for a rank with
/// particles in `region`: the order its distance needs where the cube lies at a distance of at
/// least separation × its half-side, and at least min_distance, from every box of the region and
/// that order's p^3 nodes are fewer than its particles; 0 where it is not (opened or halo).
[[nodiscard]] int compressed_order(const Cube& cube, std::size_t particles, std::span<const Box> region,
                                   const Acceptance& acceptance);

/// Not collective. The cells of `tree` that a rank with particles in `region` needs, top down: a
/// cell whose cube lies at a distance of at least separation × its half-side, and at least
/// min_distance, from every box of the region is compressed with the order its distance needs when
/// that order's p^3 nodes are fewer than its particles (compressed_order); any other cell is
/// opened, and a leaf that is not compressed is sent as its particles (halo). Every particle of the
/// tree is in exactly one cell sent. Empty for an empty region.
[[nodiscard]] EssentialCells essential_cells(const CellTree& tree, std::span<const Box> region,
                                             const Acceptance& acceptance);

}  // namespace rpyfmm::mpi::detail
