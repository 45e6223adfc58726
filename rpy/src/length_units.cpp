// rpyfmm — length units of the RPY operators (length_units.hpp).
#include "length_units.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::rpy::detail {
namespace {

constexpr double kPlainScaleMin = 0x1p-150, kPlainScaleMax = 0x1p199, kPlainRadiusMin = 0x1p-300;

// The largest ratio of the suspension's size S to a radius: 2^300 (~2e90). In units of S, radii
// and the distances of non-overlapping pairs are then >= 2^-300, their squares and cubes normal
// numbers; overlapping pairs closer than 2^-511 meet r^2 = 0, i.e. coincide, an error of
// r / a < 2^-211 in M. A particle 1e300 away from spheres of radius 1 is beyond it: no unit keeps
// both the outlier's squared distance finite and the spheres' squared distances normal (scaled to
// the outlier, they underflow; unscaled, the squared distance overflows).
constexpr int kMaxSizeRatioLog2 = 300;

std::string format_length(double v, int digits = 6) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.*g", digits, v);
  return buf;
}

// Half the widest extent (no overflow: halves before subtracting) and its axis.
double half_extent(const BoundingBox& box, int& widest) {
  double half = 0.0;
  widest = 0;
  for (int c = 0; c < 3; ++c)
    if (0.5 * box.hi[c] - 0.5 * box.lo[c] > half) half = 0.5 * box.hi[c] - 0.5 * box.lo[c], widest = c;
  return half;
}

void require_size_ratio(const BoundingBox& box, std::span<const double> a, double a_max, std::size_t first,
                        const char* where) {
  int widest = 0;
  const double half = half_extent(box, widest);
  const double size = std::max(half, a_max);
  const double least = std::ldexp(size, -kMaxSizeRatioLog2);
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i] >= least) continue;
    const char axis = char('x' + widest);
    const std::string span = size == a_max && a_max > half
                                 ? "the largest radius is " + format_length(a_max)
                                 : "particles " + std::to_string(box.ilo[widest]) + " (" + axis + " = " +
                                       format_length(box.lo[widest], 17) + ") and " + std::to_string(box.ihi[widest]) +
                                       " (" + axis + " = " + format_length(box.hi[widest], 17) + ") span " +
                                       format_length(2.0 * half) + " along " + axis;
    fail(ErrorCode::invalid_input, where,
         "radius of particle " + std::to_string(first + i) + " (" + format_length(a[i]) + ") is below 2^-" +
             std::to_string(kMaxSizeRatioLog2) + " of the size of the suspension: " + span +
             "; squared distances of its pairs would underflow where those of the suspension's extent do not " +
             "overflow (the RPY operators evaluate ratios of half the extent, or of the largest radius, to a radius " +
             "up to 2^" + std::to_string(kMaxSizeRatioLog2) + " = " +
             format_length(std::ldexp(1.0, kMaxSizeRatioLog2)) + ")");
  }
}

// Translation by the box centre c where it is exact: with lo >= c/2 and hi <= 2c (c > 0, or
// mirrored), every x in [lo, hi] has x/c in [1/2, 2] and x - c is exact (Sterbenz). Otherwise the
// box reaches within a third of its extent from the origin, |x| <= 1.5 extent, and the positions
// are only scaled. Either way pair distances are those of the input positions.
std::array<double, 3> exact_shift(const BoundingBox& box) {
  std::array<double, 3> shift{};
  for (int c = 0; c < 3; ++c) {
    const double mid = 0.5 * box.lo[c] + 0.5 * box.hi[c];
    const bool sterbenz = mid > 0.0 ? (box.lo[c] >= 0.5 * mid && box.hi[c] <= 2.0 * mid)
                                    : (box.hi[c] <= 0.5 * mid && box.lo[c] >= 2.0 * mid);
    shift[c] = sterbenz ? mid : 0.0;
  }
  return shift;
}

}  // namespace

BoundingBox bounding_box(std::span<const double> x) {
  BoundingBox box;
  box.lo = {x[0], x[1], x[2]};
  box.hi = box.lo;
  for (std::size_t i = 0; i < x.size() / 3; ++i)
    for (int c = 0; c < 3; ++c) {
      if (x[3 * i + c] < box.lo[c]) box.lo[c] = x[3 * i + c], box.ilo[c] = i;
      if (x[3 * i + c] > box.hi[c]) box.hi[c] = x[3 * i + c], box.ihi[c] = i;
    }
  return box;
}

LengthUnits choose_length_units(const BoundingBox& box, std::span<const double> radii, const char* where) {
  const auto [a_min, a_max] = std::minmax_element(radii.begin(), radii.end());
  return choose_length_units(box, radii, {*a_min, *a_max, 0}, where);
}

LengthUnits choose_length_units(const BoundingBox& box, std::span<const double> radii, const RadiiPiece& piece,
                                const char* where) {
  require_size_ratio(box, radii, piece.a_max, piece.first, where);
  int widest = 0;
  const double size = std::max(half_extent(box, widest), piece.a_max);
  if (size >= kPlainScaleMin && size <= kPlainScaleMax && piece.a_min >= kPlainRadiusMin) return {};
  return {std::ilogb(size), exact_shift(box)};
}

void to_units(const LengthUnits& units, std::span<const double> x, std::span<const double> a, std::vector<double>& xs,
              std::vector<double>& as) {
  const int e = units.exponent;
  // Scaling by 2^-e is exact unless a result is subnormal: positions lose only bits below 2^-1022
  // of the suspension's size there, and radii are at least 2^-300 of it (require_size_ratio).
  xs.resize(x.size());
  for (std::size_t i = 0; i < x.size() / 3; ++i)
    for (int c = 0; c < 3; ++c) xs[3 * i + c] = std::ldexp(x[3 * i + c] - units.shift[c], -e);
  as.resize(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) as[i] = std::ldexp(a[i], -e);
}

void to_fmm_frame(const LengthUnits& units, const BoundingBox& box, std::span<const double> x,
                  std::span<const double> a, std::vector<double>& xs, std::vector<double>& as) {
  if (units.exponent != 0) {
    to_units(units, x, a, xs, as);
    return;
  }
  xs.resize(x.size());
  for (std::size_t i = 0; i < x.size() / 3; ++i)
    for (int c = 0; c < 3; ++c) xs[3 * i + c] = x[3 * i + c] - 0.5 * (box.lo[c] + box.hi[c]);
  as.clear();
}

}  // namespace rpyfmm::rpy::detail
