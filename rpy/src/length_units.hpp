// rpyfmm — the units of length in which an RPY operator evaluates a suspension.
//
// The pair kernels form r^2 and g / r^2 ~ 1/r^3, the FMM's far field 1/r^3 and a^2 T. Where the
// suspension's size S (half its extent, or the largest radius) lies in [2^-150, 2^199] and every
// radius is >= 2^-300, non-overlapping pairs have r >= 2^-299 and the FMM's far pairs r >= 2^-31 S
// (its octree's 30 levels), so all of these stay normal and finite for loads below ~1e100 (larger
// ones are scaled by MobilityOperator::apply), LaplaceFmm accepts the extent, and the operators
// evaluate the lengths as given. Other suspensions (extent 1e137 with radius 1e135: the a^2 T terms underflowed; extent
// 1e-130: NaN) are evaluated in units of 2^e with 2^-e S in [1, 2): exact, and
// M(x, a) = 2^-e M(2^-e x, 2^-e a) since the RPY tensor is homogeneous of degree -1 in its
// lengths (docs/theory/rpy.md). Used by DirectRpy and FmmRpy.
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <vector>

namespace rpyfmm::rpy::detail {

/// The axis-aligned bounding box of the centres, and the particles on its faces.
struct BoundingBox {
  std::array<double, 3> lo{}, hi{};
  std::array<std::size_t, 3> ilo{}, ihi{};
};

/// x: 3N coordinates, N >= 1.
[[nodiscard]] BoundingBox bounding_box(std::span<const double> x);

/// Length units 2^exponent; exponent 0 where the lengths are plain (above): results are then those
/// of the unscaled evaluation, bit for bit.
struct LengthUnits {
  int exponent = 0;
  std::array<double, 3> shift{};  // translation applied before scaling, only where it is exact
};

/// Chooses the units. Throws rpyfmm::Error (invalid_input) naming `where` and the particle when a
/// radius is below 2^-300 of the suspension's size: no unit keeps both the squared extent finite
/// and that particle's squared pair distances normal.
[[nodiscard]] LengthUnits choose_length_units(const BoundingBox& box, std::span<const double> radii, const char* where);

/// Where the radii are held in pieces (rpyfmm::mpi::DistributedDirectRpy): `radii` are those of
/// particles first, first + 1, ... of a suspension whose radii lie in [a_min, a_max] and whose
/// centres have the bounding box `box` (its particle indices those of the whole suspension). Every
/// piece gets the units choose_length_units gives for the whole suspension, and a piece holding a
/// radius it refuses throws the same error, naming the particle by its index in the suspension.
struct RadiiPiece {
  double a_min = 0.0, a_max = 0.0;
  std::size_t first = 0;
};
[[nodiscard]] LengthUnits choose_length_units(const BoundingBox& box, std::span<const double> radii,
                                              const RadiiPiece& piece, const char* where);

/// 2^-e (x - shift) and 2^-e a.
void to_units(const LengthUnits& units, std::span<const double> x, std::span<const double> a, std::vector<double>& xs,
              std::vector<double>& as);

/// The positions and radii an FMM far field evaluates (FmmRpy, rpyfmm::mpi::DistributedFmmRpy): in
/// plain units (exponent 0) the centres minus the midpoint of `box` (rounded: the far field's
/// errors scale with |x| through x_m E(F^m) - E(x.F), so centring keeps them at the scale of the
/// cloud) and `as` empty (the radii as given); otherwise to_units, exact.
void to_fmm_frame(const LengthUnits& units, const BoundingBox& box, std::span<const double> x,
                  std::span<const double> a, std::vector<double>& xs, std::vector<double>& as);

}  // namespace rpyfmm::rpy::detail
