// rpyfmm — the one definition of each user-facing parameter's valid range.
//
// Help texts (CLI), validation (library, CLI, TOML configs) and the Python binding all read the
// bounds from here, so that a range stated in --help is the range the library enforces.
// docs/safety-limits.md lists them with the reasons.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>

#include "rpyfmm/core/validate.hpp"

namespace rpyfmm::ranges {

/// "[lo, hi]" (built by appending: GCC 12 warns falsely on "literal" + std::string chains).
inline std::string bracket(const std::string& lo, const std::string& hi) {
  std::string s = "[";
  s.append(lo).append(", ").append(hi).append("]");
  return s;
}

/// A range of a real parameter: [lo, hi], or open at an end where a bound itself is invalid
/// (a solver tolerance of 0 or 1).
struct RealRange {
  double lo;
  double hi;
  bool open_lo = false;
  bool open_hi = false;
  /// False for NaN, for infinities (the bounds are finite) and for subnormal numbers, which no
  /// parameter needs and whose reciprocals overflow.
  [[nodiscard]] bool contains(double v) const noexcept {
    return (v == 0.0 || std::isnormal(v)) && (open_lo ? v > lo : v >= lo) && (open_hi ? v < hi : v <= hi);
  }
  /// "[1e-12, 0.1]" or "(0, 1)": the form used in --help and in error messages.
  [[nodiscard]] std::string str() const {
    std::string s = open_lo ? "(" : "[";
    s.append(format_number(lo)).append(", ").append(format_number(hi)).append(open_hi ? ")" : "]");
    return s;
  }
};

/// A closed range [lo, hi] of an integer parameter.
struct IntRange {
  std::int64_t lo;
  std::uint64_t hi;
  [[nodiscard]] std::string str() const { return bracket(std::to_string(lo), bound(hi)); }

 private:
  static std::string bound(std::uint64_t v) {
    if (v == std::numeric_limits<std::uint64_t>::max()) return "2^64-1";
    if (v == static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) return "2^63-1";
    return std::to_string(v);
  }
};

// ---- real parameters ----------------------------------------------------------------------
// Positive physical scales: finite and normal (no subnormals, whose reciprocals overflow), and
// at most 1e30 so that the powers the kernels form (a^3, 1 / (eta a)) stay finite in double.
inline constexpr RealRange kRadius{1e-30, 1e30};     ///< sphere / bead radius a
inline constexpr RealRange kViscosity{1e-30, 1e30};  ///< solvent viscosity eta
/// Relative tolerance of an approximate mobility product (fmm, pse): CLI --eps, the
/// [mobility] tolerance of a BD config, rpy::make_mobility and rpy::FmmRpy.
inline constexpr RealRange kMobilityTolerance{1e-12, 0.1};
/// Relative tolerance of a Krylov solve or square root (Lanczos, Chebyshev, GMRES): sample --tol,
/// rigid --tol, rigid-bd --tol / --sqrt-tol, the [mobility] sqrt_tolerance of a BD config.
inline constexpr RealRange kSolverTolerance{0.0, 1.0, true, true};
/// Relative tolerance of the Laplace FMM (laplace --eps; fmm::LaplaceFmm checks it too).
inline constexpr RealRange kLaplaceTolerance{1e-15, 0.1};

// ---- integer parameters -------------------------------------------------------------------
inline constexpr std::uint64_t kU64Max = std::numeric_limits<std::uint64_t>::max();
inline constexpr std::uint64_t kI64Max = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
/// Keys of the counter-based generator (sample --seed / --step, rigid-bd --seed / --first-step).
inline constexpr IntRange kSeed{0, kU64Max};
/// Steps of a run (bd --steps, integrator.steps; rigid-bd --steps from 1).
inline constexpr IntRange kSteps{0, kI64Max};
/// Lanczos iterations / Chebyshev degree (0 = automatic): the Lanczos basis grows with them.
inline constexpr IntRange kSqrtIterations{0, 100000};
/// Particles per block of the block preconditioner (0 = automatic): blocks are factorized
/// densely, so at most the dense square roots' size (rpy::kDenseSqrtMaxRows / 3).
inline constexpr IntRange kPreconditionerBlock{0, 2000};
/// GMRES iterations of the rigid-body solve.
inline constexpr IntRange kGmresIterations{1, 10000000};
/// Particles a BD config may ask to generate (count, chains x beads, clusters x cluster_size).
inline constexpr IntRange kParticleCount{1, 1000000000};

/// Throws rpyfmm::Error (invalid_argument) naming `where` unless `value` lies in `range`
/// (NaN, infinities and subnormals never do).
inline void require_in(const RealRange& range, double value, std::string_view where, std::string_view name) {
  if (!range.contains(value)) {
    std::string what(name);
    what.append(" must lie in ").append(range.str()).append(", got ");
    if (std::isfinite(value) && value != 0.0 && !std::isnormal(value)) what.append("the subnormal ");
    what.append(format_number(value));
    fail(ErrorCode::invalid_argument, where, what);
  }
}

}  // namespace rpyfmm::ranges
