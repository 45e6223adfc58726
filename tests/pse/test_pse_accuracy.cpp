// PSE accuracy: Hasimoto self-mobility, xi independence, tolerance sweep against a
// direct Ewald sum without FFTs (ewald_reference.hpp), rectangular boxes, large-box limit.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>
#include <utility>

#include "ewald_reference.hpp"
#include "rpyfmm/fmm/direct_simd.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/real_space.hpp"
#include "simd_levels.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;
using pse_test::kPi;

namespace {

std::vector<double> product(const PseRpy& op, const std::vector<double>& f) {
  std::vector<double> u(f.size());
  op.apply(f, u);
  return u;
}

std::vector<double> random_forces(std::size_t n, unsigned seed) {
  auto f = pse_test::random_points(n, {2.0, 2.0, 2.0}, seed);
  for (auto& v : f) v -= 1.0;
  return f;
}

/// Particles i and j at x = xi and xj with equal y and z: a pair across the periodic x boundary.
void straddle_x_boundary(std::vector<double>& x, std::size_t i, std::size_t j, double xi, double xj) {
  x[3 * i] = xi;
  x[3 * j] = xj;
  x[3 * j + 1] = x[3 * i + 1];
  x[3 * j + 2] = x[3 * i + 2];
}

/// Relative differences of M F and of a split sample (seed 3, step 4) between two operators
/// that differ only in their options, on the same n random particles in box L.
struct Difference {
  double product;
  double sample;
};
Difference difference_between(const PseOptions& a, const PseOptions& b, const std::array<double, 3>& L, std::size_t n,
                              unsigned seed) {
  const auto x = pse_test::random_points(n, L, seed);
  const auto f = random_forces(n, seed + 1);
  PseRpy op_a(Geometry::periodic(L[0], L[1], L[2]), 1.0, a);
  PseRpy op_b(Geometry::periodic(L[0], L[1], L[2]), 1.0, b);
  op_a.set_positions(x, 1.0);
  op_b.set_positions(x, 1.0);
  std::vector<double> w_a(f.size()), w_b(f.size());
  op_a.sample(3, 4, w_a);
  op_b.sample(3, 4, w_b);
  return {pse_test::rel_l2(product(op_a, f), product(op_b, f)), pse_test::rel_l2(w_a, w_b)};
}

}  // namespace

TEST(PseAccuracy, HasimotoSelfMobility) {
  // One sphere in a cube: 6 pi mu a M_11 = 1 - 2.837297 a/L + (4 pi/3)(a/L)^3, exact for RPY.
  const double a = 1.0, mu = 1.0;
  for (double aL : {0.01, 0.05, 0.1, 0.2}) {
    for (double eps : {1e-3, 1e-6}) {
      PseOptions o;
      o.tolerance = eps;  // xi automatic (small boxes need a large xi)
      PseRpy op(Geometry::periodic(a / aL), mu, o);
      const std::vector<double> x = {0.3, 0.7, 0.1};
      op.set_positions(x, a);
      const auto ux = product(op, {1.0, 0.0, 0.0});
      const auto uz = product(op, {0.0, 0.0, 1.0});
      const double m0 = 1.0 / (6 * kPi * mu * a);
      EXPECT_NEAR(ux[0] / m0, pse_test::hasimoto(aL), eps) << "a/L = " << aL << " " << op.parameters().summary();
      EXPECT_NEAR(uz[2] / m0, pse_test::hasimoto(aL), eps) << "a/L = " << aL;
      EXPECT_NEAR(ux[1] / m0, 0.0, eps);
    }
  }
}

TEST(PseAccuracy, SelfMobilityIndependentOfXi) {
  const double a = 1.0, L = 10.0;
  for (double xa : {1.0, 2.0, 3.0}) {
    PseOptions o;
    o.tolerance = 1e-6;
    o.xi = xa;
    PseRpy op(Geometry::periodic(L), 1.0, o);
    op.set_positions(std::vector<double>{9.9, 0.05, 5.0}, a);
    const auto u = product(op, {0.0, 1.0, 0.0});
    EXPECT_NEAR(u[1] * 6 * kPi, pse_test::hasimoto(a / L), 1e-6) << "xi a = " << xa;
  }
}

TEST(PseAccuracy, ReferenceIsIndependentOfXi) {
  // Validates the reference itself (closed forms + k-sum jointly): different splittings agree.
  const std::array<double, 3> L = {12.0, 15.0, 10.0};
  const auto x = pse_test::random_points(12, L, 3);
  const auto f = random_forces(12, 4);
  const auto u05 = pse_test::ewald_reference(x, 1.0, 1.0, L, f, 0.5);
  for (double xi : {0.8, 1.5}) {
    const auto u = pse_test::ewald_reference(x, 1.0, 1.0, L, f, xi);
    EXPECT_LT(pse_test::rel_l2(u, u05), 1e-11) << xi;
  }
}

TEST(PseAccuracy, ErrorFollowsTolerance) {
  // Relative l2 error of U for random forces against the direct Ewald sum, eps = 1e-2 .. 1e-8,
  // cubic and rectangular boxes, several xi, the window shape chosen automatically. Bound eps:
  // the real-space, aliasing and window-truncation terms are each budgeted at eps / 2 with
  // measured constants (docs/theory/pse.md), and they do not add up in phase.
  struct Case {
    std::array<double, 3> L;
    double xa;       // the operator's xi a (0: automatic); the reference uses 1 then
    double min_eps;  // below it r_cut(xi) exceeds L/2 for this box (rejected, see PseBadInput)
    double eta;      // PseOptions::window_eta (0: automatic)
  };
  const Case cases[] = {{{20.0, 20.0, 20.0}, 0.5, 1e-6, 0.0}, {{14.0, 14.0, 14.0}, 1.0, 1e-8, 0.0},
                        {{12.0, 15.0, 10.0}, 1.5, 1e-8, 0.0}, {{13.0, 11.0, 16.5}, 2.0, 1e-8, 0.0},
                        {{14.0, 14.0, 14.0}, 1.0, 1e-8, 0.8},   // a fixed shape (the former default)
                        {{18.0, 16.0, 17.0}, 0.0, 1e-5, 0.0}};  // automatic xi and shape
  const std::size_t n = 30;
  for (const auto& c : cases) {
    const auto x = pse_test::random_points(n, c.L, 11);
    const auto f = random_forces(n, 12);
    const auto ref = pse_test::ewald_reference(x, 1.0, 1.0, c.L, f, c.xa > 0.0 ? c.xa : 1.0);
    for (double eps : {1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8}) {
      if (eps < c.min_eps) continue;
      PseOptions o;
      o.tolerance = eps;
      o.xi = c.xa;
      o.window_eta = c.eta;
      PseRpy op(Geometry::periodic(c.L[0], c.L[1], c.L[2]), 1.0, o);
      op.set_positions(x, 1.0);
      const double err = pse_test::rel_l2(product(op, f), ref);
      EXPECT_LE(err, eps) << "eps " << eps << ", " << op.parameters().summary();
      // and the tolerance is not met by accident of far too fine parameters: error within 1000x of eps
      if (eps >= 1e-7) {
        EXPECT_GE(err, 1e-3 * eps) << "eps " << eps;
      }
    }
  }
}

TEST(PseAccuracy, TableAndDirectRealSpaceAgree) {
  PseOptions table;
  table.tolerance = 1e-6;
  table.xi = 1.0;
  PseOptions direct = table;
  direct.real_space_table = false;
  EXPECT_LT(difference_between(table, direct, {14.0, 14.0, 14.0}, 40, 5).product, 1e-6);
}

TEST(PseAccuracy, RealSpaceHalfListsMatchFullRows) {
  // Where the AVX-512 kernels run on a cell grid, M_r F sums each pair once for both rows, block
  // by block in up to four colours (rpy/src/pse/half_blocks.hpp). Against the portable full rows: cell grids
  // of 3 ... 10 layers (axes left whole, even and odd block counts, widths 2 and 3), coincident
  // and periodic-boundary pairs, 3 right-hand sides; the same result with 1 and 2 threads, bit
  // for bit (each sum is added in a fixed order). Without the pair cache, which rounds the blocks
  // it keeps (tests/pse/test_pse_pair_cache.cpp), so that every product evaluates the pairs.
  if (!(rpyfmm::simd_level() == rpyfmm::SimdLevel::avx512)) GTEST_SKIP() << "no AVX-512F on this CPU";
  const double rc = 4.0;
  for (const std::array<int, 3>& cells :
       {std::array<int, 3>{4, 4, 3}, std::array<int, 3>{5, 6, 4}, std::array<int, 3>{9, 10, 3},
        std::array<int, 3>{7, 4, 5}, std::array<int, 3>{3, 3, 3}, std::array<int, 3>{3, 8, 6}}) {
    const std::array<double, 3> L = {rc * cells[0] + 0.5, rc * cells[1] + 0.5, rc * cells[2] + 0.5};
    auto x = pse_test::random_points(static_cast<std::size_t>(cells[0] * cells[1] * cells[2] * 6), L, 43);
    for (int d = 0; d < 3; ++d) x[3 * 5 + d] = x[3 * 40 + d];  // coincident pair
    straddle_x_boundary(x, 6, 7, 0.1, L[0] - 0.2);
    const std::size_t n = x.size() / 3, nrhs = 3;
    const auto f = random_forces(n * nrhs, 44);
    PseOptions o;
    o.xi = 0.8;
    o.r_cut = rc;
    o.real_space_cache = false;
    PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
    op.set_positions(x, 1.0);
    std::vector<double> half(3 * n * nrhs), half2(3 * n * nrhs), full(3 * n * nrhs);
    const int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    op.real_space_operator().apply(f, half, nrhs);
    omp_set_num_threads(std::max(2, saved));
    op.real_space_operator().apply(f, half2, nrhs);
    omp_set_num_threads(saved);
    {
      const rpyfmm::ScopedSimdLevel portable(rpyfmm::SimdLevel::scalar);
      op.set_positions(x, 1.0);
      op.real_space_operator().apply(f, full, nrhs);
    }
    EXPECT_LT(pse_test::rel_l2(half, full), 1e-13) << cells[0] << " x " << cells[1] << " cells";
    EXPECT_EQ(half, half2) << cells[0] << " x " << cells[1] << " cells";
  }
}

TEST(PseAccuracy, RealSpaceProductMatchesPairSum) {
  // M_r F by the operator (cell lists, particles renumbered in cell order, the vectorized
  // table row) against an O(N^2) sum over minimum images with the closed forms of [PSE]
  // App. A, written here. 1500 particles in a rectangular box (8 x 7 x 9 cells), with
  // coincident and overlapping pairs, and a block of 3 right-hand sides. The table is built
  // to tolerance / 10 at every midpoint, so the products agree to ~tolerance.
  const std::array<double, 3> L = {40.0, 35.0, 45.0};
  auto x = pse_test::random_points(1500, L, 41);
  for (int d = 0; d < 3; ++d) {
    x[3 * 7 + d] = x[3 * 1200 + d];                        // coincident pair
    x[3 * 8 + d] = x[3 * 900 + d] + (d == 0 ? 0.3 : 0.0);  // deep overlap, r = 0.3 a
  }
  straddle_x_boundary(x, 9, 10, 0.2, L[0] - 0.4);
  const std::size_t n = x.size() / 3, nrhs = 3;
  const auto f = random_forces(n * nrhs, 42);
  PseOptions o;
  o.tolerance = 1e-6;
  o.xi = 0.9;
  PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
  op.set_positions(x, 1.0);
  std::vector<double> u(3 * n * nrhs);
  op.real_space_operator().apply(f, u, nrhs);
  const double rc = op.parameters().r_cut, xi = op.parameters().xi;
  ASSERT_GE(std::floor(std::min({L[0], L[1], L[2]}) / rc), 3.0) << "the cell-list path must be used";
  const double m0 = 1.0 / (6.0 * kPi);
  std::vector<double> ref(u.size(), 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t r = 0; r < nrhs; ++r)
      for (int c = 0; c < 3; ++c) ref[r * 3 * n + 3 * i + c] = m0 * real_space_self(xi, 1.0) * f[r * 3 * n + 3 * i + c];
    for (std::size_t j = 0; j < n; ++j) {
      if (j == i) continue;
      double d[3];
      for (int c = 0; c < 3; ++c) {
        d[c] = x[3 * i + c] - x[3 * j + c];
        d[c] -= L[c] * std::round(d[c] / L[c]);
      }
      const double dist = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (dist >= rc) continue;
      const FG v = dist > 0.0 ? real_space_fg(dist, xi, 1.0) : FG{real_space_self(xi, 1.0), real_space_self(xi, 1.0)};
      for (std::size_t r = 0; r < nrhs; ++r) {
        const double* fj = &f[r * 3 * n + 3 * j];
        const double proj = dist > 0.0 ? (d[0] * fj[0] + d[1] * fj[1] + d[2] * fj[2]) / (dist * dist) : 0.0;
        for (int c = 0; c < 3; ++c) ref[r * 3 * n + 3 * i + c] += m0 * (v.f * fj[c] + (v.g - v.f) * proj * d[c]);
      }
    }
  }
  EXPECT_LT(pse_test::rel_l2(u, ref), 1e-6);
  // Single right-hand side (the vectorized single-rhs path) equals the block's first column.
  std::vector<double> u1(3 * n);
  op.real_space_operator().apply(std::span<const double>(f.data(), 3 * n), u1, 1);
  EXPECT_LT(pse_test::rel_l2(u1, std::vector<double>(u.begin(), u.begin() + 3 * static_cast<long>(n))), 1e-14);
}

TEST(PseAccuracy, LargeBoxApproachesFreeSpaceWithHasimotoCorrection) {
  // Two spheres at distance r = 3a in a cube of side L: M_12(L) = M_12^RPY - (2.837297/(6 pi mu L)) I
  // + O(r^2/L^3). The O(1/L) term is checked exactly, the remainder must fall ~L^-3.
  const double a = 1.0, r = 3.0;
  double prev = 0.0;
  for (double L : {24.0, 48.0}) {
    PseOptions o;
    o.tolerance = 1e-8;
    PseRpy op(Geometry::periodic(L), 1.0, o);
    op.set_positions(std::vector<double>{1.0, 1.0, 1.0, 1.0 + r, 1.0, 1.0}, a);
    const auto ux = product(op, {1.0, 0.0, 0.0, 0.0, 0.0, 0.0});
    const auto uy = product(op, {0.0, 1.0, 0.0, 0.0, 0.0, 0.0});
    const double m0 = 1.0 / (6 * kPi * a);
    const double par = 1.0 / (8 * kPi * r) * (1 + 2 * a * a / (3 * r * r) + 1 - 2 * a * a / (r * r));
    const double perp = 1.0 / (8 * kPi * r) * (1 + 2 * a * a / (3 * r * r));
    const double corr = 2.83729747948061947666591710460773907 / (6 * kPi * L);
    const double rem_par = (ux[3] - (par - corr)) / m0;
    const double rem_perp = (uy[4] - (perp - corr)) / m0;
    const double rem = std::max(std::abs(rem_par), std::abs(rem_perp));
    // At L = 24 the remainder must be far below the 1/L term (2.837 a/L = 0.12 in units of M0).
    EXPECT_LT(rem, 0.05 * 2.837 * a / L) << "L = " << L;
    if (prev > 0.0) {
      EXPECT_NEAR(prev / rem, 8.0, 2.0) << "remainder should scale like L^-3";
    }
    prev = rem;
  }
}

TEST(PseAccuracy, WrappedPositionsGiveTheSameResult) {
  const std::array<double, 3> L = {12.0, 15.0, 10.0};
  auto x = pse_test::random_points(20, L, 8);
  const auto f = random_forces(20, 9);
  PseOptions o;
  o.xi = 1.0;
  PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
  op.set_positions(x, 1.0);
  const auto u0 = product(op, f);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] += (i % 2 ? 3.0 : -2.0) * L[i % 3];
  op.set_positions(x, 1.0);
  EXPECT_LT(pse_test::rel_l2(product(op, f), u0), 1e-12);
}

// The stored positions lie in [0, L) per axis: inside ones bitwise unchanged (also the largest
// double below L, whose x / L rounds to 1), outside ones moved by whole periods, including
// values a hair below a multiple of L, -0.0, tiny negatives (the smallest, whose quotient by L
// underflows, must not stay negative) and huge values.
TEST(PseAccuracy, StoredPositionsAreWrappedIntoTheBox) {
  const std::array<double, 3> L = {12.0, 15.0, 10.0};
  const double below_L = std::nextafter(L[0], 0.0);
  const double below_2L = std::nextafter(2.0 * L[1], 0.0);
  const double tiniest = std::numeric_limits<double>::denorm_min();  // -tiniest / L underflows to -0
  std::vector<double> x = {0.5,  1.0,         2.0,  below_L, -0.0,        7.25,  -1e-300,  below_2L, 3.0 * L[2] + 0.5,
                           -6.0, 1e6 + 0.125, -0.0, 11.0,    -4.0 * L[1], 9.999, -tiniest, 4.0,      5.0};
  const std::size_t n = x.size() / 3;
  PseOptions o;
  o.xi = 1.0;
  PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
  op.set_positions(x, 1.0);
  const auto stored = op.positions();
  ASSERT_EQ(stored.size(), x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double Ld = L[i % 3];
    EXPECT_GE(stored[i], 0.0) << i;
    EXPECT_LT(stored[i], Ld) << i;
    if (x[i] >= 0.0 && x[i] < Ld) {
      EXPECT_EQ(stored[i], x[i]) << i;
    } else {
      const double periods = (x[i] - stored[i]) / Ld;  // a whole number (or one off, at L - tiny)
      EXPECT_NEAR(periods, std::round(periods), 1e-9) << i;
    }
  }
  EXPECT_EQ(op.radii().size(), n);
}

TEST(PseAccuracy, FftMeasurePlansGiveTheSameProduct) {
  // FFTW_MEASURE picks another algorithm for the same transforms: equal to round-off, of double
  // (1e-12) or of single-precision wave grids (1e-6, test_pse_precision.cpp).
  for (const auto& [precision, bound] :
       {std::pair{WavePrecision::double_precision, 1e-12}, std::pair{WavePrecision::single_precision, 1e-6}}) {
    PseOptions estimate;
    estimate.tolerance = 1e-5;
    estimate.wave_precision = precision;
    PseOptions measure = estimate;
    measure.fft_measure = true;
    const Difference d = difference_between(estimate, measure, {16.0, 14.0, 18.0}, 200, 51);
    EXPECT_LT(d.product, bound);
    EXPECT_LT(d.sample, bound);
  }
}

TEST(PseAccuracy, SimdAndPortableKernelsAgree) {
  // Spreading and interpolation (support <= 8 points) run with AVX-512 or AVX2 intrinsics when the
  // CPU has them, the real-space rows and the wave-space noise with AVX-512, the portable loops
  // otherwise. Every path must give the same product and sample to round-off: windows that wrap
  // around the box (particles near each face), neighbour rows that cross the box, supports from
  // 4 to 9 (tolerances 1e-2 ... 1e-6; 9 takes the portable spreading everywhere), double- and
  // single-precision wave grids. RealSpaceProductMatchesPairSum checks the AVX-512 rows against
  // an independent pair sum with coincident and overlapping pairs.
  if (rpyfmm::detected_simd_level() == rpyfmm::SimdLevel::scalar) GTEST_SKIP() << "no AVX2 on this machine";
  const std::array<double, 3> L = {17.0, 15.0, 19.0};
  auto x = pse_test::random_points(300, L, 61);
  for (std::size_t i = 0; i < 30; ++i) x[3 * i + i % 3] = L[i % 3] * (i % 2 ? 0.999 : 0.001);
  const auto f = random_forces(300, 62);
  // Plans the positions, then runs M F and a sample, at one instruction-set level.
  auto run = [&](PseRpy& op, rpyfmm::SimdLevel level) {
    const rpyfmm::ScopedSimdLevel scope(level);
    op.set_positions(x, 1.0);
    std::vector<double> w(f.size());
    auto u = product(op, f);
    op.sample(3, 4, w);
    u.insert(u.end(), w.begin(), w.end());
    return u;
  };
  for (const auto& [eps, precision] :
       {std::pair{1e-2, WavePrecision::double_precision}, std::pair{1e-3, WavePrecision::double_precision},
        std::pair{1e-4, WavePrecision::double_precision}, std::pair{1e-6, WavePrecision::double_precision},
        std::pair{1e-3, WavePrecision::single_precision}, std::pair{1e-4, WavePrecision::single_precision}}) {
    PseOptions o;
    o.tolerance = eps;
    o.wave_precision = precision;
    // Float grids: the same sums in another order, rounded to float (test_pse_precision.cpp).
    const double bound = precision == WavePrecision::double_precision ? 1e-13 : 1e-6;
    PseRpy op(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
    const auto portable = run(op, rpyfmm::SimdLevel::scalar);
    SCOPED_TRACE(op.parameters().summary());
    for (const rpyfmm::SimdLevel level : rpyfmm::test::available_simd_levels())
      EXPECT_LT(pse_test::rel_l2(run(op, level), portable), bound) << rpyfmm::simd_level_name(level);
  }
}
