// Potentials, force field and neighbour lists against plain references:
// finite differences of the energies, brute-force pair sums, O(N^2) pair searches.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <tuple>
#include <utility>
#include <vector>

#include "rpyfmm/bd/force_field.hpp"
#include "rpyfmm/bd/neighbour_list.hpp"
#include "rpyfmm/bd/potentials.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"

using namespace rpyfmm::bd;
using rpyfmm::Error;
using rpyfmm::ErrorCode;
using rpyfmm::rpy::make_mobility;
using rpyfmm::rpy::mobility_method_from_string;
using rpyfmm::rpy::MobilityMethod;

namespace {
// Central difference of V: -V'(r)/r must equal s. O(h^2) error; h = 1e-6 r gives
// ~1e-8 relative accuracy for these smooth functions (tolerance 1e-6).
void expect_consistent(const EnergyForce& at, double r, auto&& energy) {
  const double h = 1e-6 * r;
  const double dv = (energy(r + h) - energy(r - h)) / (2 * h);
  EXPECT_NEAR(at.s, -dv / r, 1e-6 * std::max(1.0, std::abs(at.s))) << "r = " << r;
}

std::vector<double> random_points(std::size_t n, double box, unsigned seed) {
  std::mt19937_64 gen(seed);
  std::uniform_real_distribution<double> u(0.0, box);
  std::vector<double> x(3 * n);
  for (double& v : x) v = u(gen);
  return x;
}
}  // namespace

TEST(Potentials, ForcesAreMinusEnergyGradient) {
  for (PairKind kind : {PairKind::lj36_18, PairKind::wca, PairKind::soft}) {
    PairPotential p;
    p.kind = kind;
    p.epsilon = 14.0;
    const PairTerm t = resolve_pair(p, 1.0, 1.0, 0.0, 0.0);
    for (double r : {1.7, 1.9, 2.0, 2.05, 2.2}) {
      if (r >= t.cutoff) continue;
      expect_consistent(evaluate_pair(t, r), r, [&](double q) { return evaluate_pair(t, q).energy; });
    }
  }
  // DLVO, Tran et al. (2015), Annex 2 in SI units (alumina-silica, radii 200 nm / 50 nm), energies in joules scaled to
  // kT.
  PairPotential d;
  d.kind = PairKind::dlvo;
  d.hamaker = 1.48e-20 / 4.05e-21;
  d.permittivity = 80 * 8.854e-12 / 4.05e-21 * 1e-9;  // lengths in nm, potentials in V
  d.kappa = 0.1;                                      // 1/nm
  const PairTerm t = resolve_pair(d, 200.0, 50.0, 0.045, -0.020);
  for (double h : {0.5, 2.0, 10.0, 40.0}) {
    const double r = 250.0 + h;
    expect_consistent(evaluate_pair(t, r), r, [&](double q) { return evaluate_pair(t, q).energy; });
  }
  for (BondKind kind : {BondKind::harmonic, BondKind::fene}) {
    BondPotential b{kind, 30.0, 1.5};
    for (double r : {0.5, 1.0, 1.4})
      expect_consistent(evaluate_bond(b, r), r, [&](double q) { return evaluate_bond(b, q).energy; });
  }
}

TEST(Potentials, ClosedFormValues) {
  PairPotential p;
  p.kind = PairKind::lj36_18;
  p.epsilon = 14.0;
  const PairTerm t = resolve_pair(p, 1.0, 1.0, 0, 0);
  EXPECT_DOUBLE_EQ(t.sigma, 2.0);                                              // s = d_A, Tran et al. (2015) eq. 8
  EXPECT_NEAR(evaluate_pair(t, 2.0).energy, 0.0, 1e-12);                       // V(s) = 0
  EXPECT_NEAR(evaluate_pair(t, 2.0 * std::pow(2.0, 1.0 / 18)).s, 0.0, 1e-10);  // minimum at 2^(1/18) s
  PairPotential w;
  w.kind = PairKind::wca;
  const PairTerm tw = resolve_pair(w, 1.0, 1.0, 0, 0);
  EXPECT_NEAR(tw.cutoff, 2.0 * std::pow(2.0, 1.0 / 6), 1e-14);
  EXPECT_NEAR(evaluate_pair(tw, tw.cutoff * (1 - 1e-12)).energy, 0.0, 1e-9);  // continuous at the cutoff
  EXPECT_THROW(pair_kind_from_string("lj"), Error);
  PairPotential bad;
  bad.epsilon = -1;
  EXPECT_THROW(resolve_pair(bad, 1, 1, 0, 0), Error);
}

namespace {
// Gauss-Legendre nodes and weights on [-1, 1] by Newton's iteration on P_n (Abramowitz & Stegun
// 25.4.29): exact for polynomials of degree 2n - 1.
std::vector<std::array<double, 2>> gauss_legendre(int n) {
  std::vector<std::array<double, 2>> rule;
  for (int i = 1; i <= n; ++i) {
    double x = std::cos(std::numbers::pi * (i - 0.25) / (n + 0.5)), dp = 0.0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = x;
      for (int k = 2; k <= n; ++k) std::tie(p0, p1) = std::pair{p1, ((2 * k - 1) * x * p1 - (k - 1) * p0) / k};
      dp = n * (x * p1 - p0) / (x * x - 1.0);
      const double dx = p1 / dp;
      x -= dx;
      if (std::abs(dx) < 1e-16) break;
    }
    rule.push_back({x, 2.0 / ((1.0 - x * x) * dp * dp)});
  }
  return rule;
}

// Nodes and weights on [0, a], panels halving towards a (where the integrand below peaks).
std::vector<std::array<double, 2>> graded_rule(double a) {
  static const auto gl = gauss_legendre(8);
  std::vector<std::array<double, 2>> rule;
  double lo = 0.0;
  for (int k = 1; k <= 40; ++k) {
    const double hi = k < 40 ? a * (1.0 - std::ldexp(1.0, -k)) : a;
    for (const auto& [x, w] : gl) rule.push_back({lo + 0.5 * (hi - lo) * (x + 1.0), 0.5 * (hi - lo) * w});
    lo = hi;
  }
  return rule;
}

// Born energy as Hamaker's double volume integral of the r^-12 part of the Lennard-Jones pair
// energy, C6 sigma^6 / r^12 with A = pi^2 rho_i rho_j C6, over two spheres: shells of radii t1,
// t2 at centre distance R interact with 4 pi^2 t1 t2 / (90 R) [(R-t1-t2)^-9 - (R-t1+t2)^-9
// - (R+t1-t2)^-9 + (R+t1+t2)^-9] per unit densities (integrating 1/u^12 over each shell in
// turn), so V = A sigma^6 / pi^2 times its integral over t1 in [0, ai], t2 in [0, aj].
double born_by_quadrature(double hamaker, double sigma_b, double ai, double aj, double r) {
  double sum = 0.0;
  for (const auto& [t1, w1] : graded_rule(ai))
    for (const auto& [t2, w2] : graded_rule(aj)) {
      const double shells =
          std::pow(r - t1 - t2, -9) - std::pow(r - t1 + t2, -9) - std::pow(r + t1 - t2, -9) + std::pow(r + t1 + t2, -9);
      sum += w1 * w2 * 4.0 * std::numbers::pi * std::numbers::pi * t1 * t2 / (90.0 * r) * shells;
    }
  return hamaker * std::pow(sigma_b, 6) / (std::numbers::pi * std::numbers::pi) * sum;
}

PairTerm dlvo_born(double hamaker, double ai, double aj, double psi_i, double psi_j, double sigma_b) {
  PairPotential d;
  d.kind = PairKind::dlvo;
  d.hamaker = hamaker;
  d.permittivity = 175.0;  // water, kT / (V^2 nm) at 293 K (examples/bd/alumina_silica)
  d.kappa = 0.1;           // 1/nm
  d.core = DlvoCore::born;
  d.born_sigma = sigma_b;
  return resolve_pair(d, ai, aj, psi_i, psi_j);
}
}  // namespace

// The closed form of Feke et al. (1984) against the sphere-sphere volume integral done by
// quadrature (8-point Gauss-Legendre on 40 graded panels per radius: ~1e-12 relative at these
// separations; tolerance 1e-9), from near contact to far apart and for unequal radii; and its
// two limits: Derjaguin's A sigma^6 a_eff / (1260 h^7) near contact (relative error O(h / a):
// tolerance 2e-3 at h = 1e-4 a) and point particles 16 A sigma^6 ai^3 aj^3 / (9 r^12) far apart
// (relative error O((a / r)^2), 6.6e-3 at r = 50 ai for aj = ai / 2 by exact arithmetic:
// tolerance 1e-2; farther out the four poles cancel to below double precision).
TEST(Potentials, BornRepulsionMatchesTheVolumeIntegral) {
  const double hamaker = 3.0, sigma_b = 0.4;
  const double k = hamaker * std::pow(sigma_b, 6) / 37800.0;
  for (const auto& [ai, aj, h] : {std::array{1.0, 1.0, 0.5},
                                  {2.0, 0.5, 0.3},
                                  {3.0, 1.0, 0.1},
                                  {1.0, 0.25, 0.05},
                                  {200.0, 12.5, 2.0},
                                  {1.0, 1.0, 5.0}}) {
    const double r = ai + aj + h;
    const double exact = born_by_quadrature(hamaker, sigma_b, ai, aj, r);
    EXPECT_NEAR(born_repulsion(k, ai, aj, r).energy, exact, 1e-9 * exact) << ai << " " << aj << " h " << h;
  }
  const double ai = 200.0, aj = 12.5, h = 0.02;
  const double derjaguin = hamaker * std::pow(sigma_b, 6) * (ai * aj / (ai + aj)) / (1260.0 * std::pow(h, 7));
  EXPECT_NEAR(born_repulsion(k, ai, aj, ai + aj + h).energy, derjaguin, 2e-3 * derjaguin);
  const double far = 50.0,
               points = 16.0 * hamaker * std::pow(sigma_b, 6) * std::pow(0.5, 3) / (9.0 * std::pow(far, 12));
  EXPECT_NEAR(born_repulsion(k, 1.0, 0.5, far).energy, points, 1e-2 * points);
}

// DLVO with the Born core (the alumina-silica and silica-silica pairs of Tran et al. (2015), Annex 2,
// Table 5 R = 1.1 %, in nm and kT): the force is -dV/dr, inside the core, at the primary minimum
// and up to the cut-off. Central differences with step 1e-5 h, where the h^-7 core varies:
// truncation ~1e-9 and rounding ~1e-8 relative (tolerance 1e-6).
TEST(Potentials, DlvoBornForcesAreMinusEnergyGradient) {
  for (const PairTerm& t :
       {dlvo_born(3.66, 200.0, 12.5, 0.030, -0.026, 0.0),  //
        dlvo_born(1.137, 12.5, 12.5, -0.026, -0.026, 0.0), dlvo_born(11.77, 200.0, 200.0, 0.030, 0.030, 0.5)}) {
    for (double h : {0.2, 0.6, 1.3, 3.0, 10.0, 60.0}) {
      const double r = t.ai + t.aj + h, step = 1e-5 * h;
      const double dv = (evaluate_pair(t, r + step).energy - evaluate_pair(t, r - step).energy) / (2.0 * step);
      const double s = evaluate_pair(t, r).s;
      EXPECT_NEAR(s, -dv / r, 1e-6 * std::abs(s)) << "a " << t.ai << " " << t.aj << " h " << h;
    }
  }
}

// Where the core puts the primary minimum. With van der Waals only (Psi = 0) and radii much
// larger than sigma_B, Derjaguin's forms -A a_eff / (6 h) + A sigma_B^6 a_eff / (1260 h^7) give the
// minimum at h = sigma_B / 30^(1/6) (tolerance 1e-3 relative: corrections O(h / a) = 1e-5). The
// default sigma_B is 0.8 / kappa, and without the core the force stays attractive to contact.
TEST(Potentials, DlvoBornMinimumLocation) {
  const double a = 1e5, sigma_b = 2.0;
  const PairTerm t = dlvo_born(3.0, a, a, 0.0, 0.0, sigma_b);
  double lo = 0.3 * sigma_b, hi = 2.0 * sigma_b;  // s = -V'/r > 0 (repulsive) at lo, < 0 at hi
  ASSERT_GT(evaluate_pair(t, 2 * a + lo).s, 0.0);
  ASSERT_LT(evaluate_pair(t, 2 * a + hi).s, 0.0);
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (evaluate_pair(t, 2 * a + mid).s > 0.0 ? lo : hi) = mid;
  }
  EXPECT_NEAR(lo, sigma_b * std::pow(30.0, -1.0 / 6.0), 1e-3 * sigma_b);

  const PairTerm by_default = dlvo_born(3.0, a, a, 0.0, 0.0, 0.0);
  const PairTerm explicit_sigma = dlvo_born(3.0, a, a, 0.0, 0.0, 0.8 / 0.1);
  EXPECT_EQ(by_default.born_prefactor, explicit_sigma.born_prefactor);
  PairTerm bare = by_default;
  bare.born_prefactor = 0.0;
  for (double h : {0.01, 0.1, 1.0}) EXPECT_LT(evaluate_pair(bare, 2 * a + h).s, 0.0) << h;
}

TEST(Potentials, DlvoCoreBadInputIsRefused) {
  EXPECT_EQ(dlvo_core_from_string("born"), DlvoCore::born);
  EXPECT_EQ(dlvo_core_from_string("none"), DlvoCore::none);
  EXPECT_THROW(dlvo_core_from_string("hard"), Error);
  PairPotential d;
  d.kind = PairKind::dlvo;
  d.kappa = 0.1;
  d.core = DlvoCore::born;
  d.born_sigma = -1.0;
  EXPECT_THROW(resolve_pair(d, 1.0, 1.0, 0.0, 0.0), Error);
  d.born_sigma = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(resolve_pair(d, 1.0, 1.0, 0.0, 0.0), Error);
}

// Also with positions outside the periodic box (BD trajectories are not wrapped): the list
// wraps its own copy and carries image shifts across the faces.
TEST(NeighbourList, MatchesAllPairsOpenAndPeriodic) {
  for (int variant = 0; variant < 3; ++variant) {
    const bool periodic = variant > 0;
    const double box = 20.0, rc = 2.5;
    auto g = periodic ? rpyfmm::rpy::Geometry::periodic(box) : rpyfmm::rpy::Geometry::open();
    NeighbourList list(g, rc, {.skin = 0.5});
    auto x = random_points(600, box, 3);
    if (variant == 2) {
      for (std::size_t i = 0; i < x.size(); ++i) x[i] += box * static_cast<double>(static_cast<int>(i % 5) - 2);
    }
    list.build(x);
    const double rl = rc + 0.5;
    std::size_t count = 0;
    for (std::size_t i = 0; i < 600; ++i) {
      std::vector<std::uint32_t> expected;
      for (std::size_t j = 0; j < 600; ++j) {
        if (i == j) continue;
        double r2 = 0;
        for (int c = 0; c < 3; ++c) {
          double d = x[3 * i + c] - x[3 * j + c];
          if (periodic) d -= box * std::round(d / box);
          r2 += d * d;
        }
        if (r2 < rl * rl) expected.push_back(static_cast<std::uint32_t>(j));
      }
      auto got = list.neighbours(i);
      ASSERT_EQ(std::vector<std::uint32_t>(got.begin(), got.end()), expected) << "particle " << i;
      count += expected.size();
    }
    EXPECT_GT(count, 600u);  // the test exercises real neighbours
  }
}

// Per pair of types its own list radius (set_pair_cutoffs): each row holds exactly the pairs
// within their pair's cut-off + skin (O(N^2) search), for both build paths (all pairs below 64
// particles, cells above), open and periodic; a pair that does not interact is never listed.
TEST(NeighbourList, PairCutoffsListEachKindWithinItsOwnRadius) {
  const double skin = 0.4;
  // Types 0 (large cut-off with itself), 1 (short with itself), 2 (interacts with nothing).
  const std::vector<double> cutoffs = {3.0, 1.2, 0.0,  //
                                       1.2, 0.8, 0.0,  //
                                       0.0, 0.0, 0.0};
  for (const std::size_t n : {50u, 700u}) {
    for (const bool periodic : {false, true}) {
      const double box = n < 64 ? 9.0 : 15.0;
      auto g = periodic ? rpyfmm::rpy::Geometry::periodic(box) : rpyfmm::rpy::Geometry::open();
      const auto x = random_points(n, box, 5);
      std::vector<std::uint32_t> types(n);
      for (std::size_t i = 0; i < n; ++i)
        types[i] = static_cast<std::uint32_t>((i * 7) % 10 < 2 ? 0 : (i % 9 == 4 ? 2 : 1));
      NeighbourList list(g, 3.0, {.skin = skin});
      list.set_pair_cutoffs(types, cutoffs, 3);
      list.build(x);
      std::size_t listed = 0;
      for (std::size_t i = 0; i < n; ++i) {
        std::vector<std::uint32_t> expected;
        for (std::size_t j = 0; j < n; ++j) {
          const double rc = cutoffs[types[i] * 3 + types[j]];
          if (i == j || rc == 0.0) continue;
          double r2 = 0;
          for (int c = 0; c < 3; ++c) {
            double d = x[3 * i + c] - x[3 * j + c];
            if (periodic) d -= box * std::round(d / box);
            r2 += d * d;
          }
          if (r2 < (rc + skin) * (rc + skin)) expected.push_back(static_cast<std::uint32_t>(j));
        }
        const auto got = list.neighbours(i);
        ASSERT_EQ(std::vector<std::uint32_t>(got.begin(), got.end()), expected) << "n " << n << " particle " << i;
        listed += expected.size();
      }
      EXPECT_GT(listed, n);  // real neighbours of every kind
    }
  }
  NeighbourList list(rpyfmm::rpy::Geometry::open(), 2.0, {});
  const std::vector<std::uint32_t> two_types = {0, 1};
  EXPECT_THROW(list.set_pair_cutoffs(two_types, std::vector<double>{2.0, 2.5, 2.5, 1.0}, 2), Error);  // above r_c
  EXPECT_THROW(list.set_pair_cutoffs(two_types, std::vector<double>{2.0, 1.0, 1.0}, 2), Error);       // not 2^2
  EXPECT_THROW(list.set_pair_cutoffs(std::vector<std::uint32_t>{0, 2}, std::vector<double>(4, 1.0), 2), Error);
  list.set_pair_cutoffs(two_types, std::vector<double>(4, 1.0), 2);
  EXPECT_THROW(list.build(random_points(3, 5.0, 1)), Error);  // types for 2 particles, 3 given
}

// The forces and the energy of a mixture whose kinds interact over very different ranges are the
// same bit for bit from per-kind list radii as from one radius for all, after moves within half
// the skin (no rebuild): the pairs left out are beyond their cut-offs until the rebuild test fires.
TEST(ForceField, PerKindListRadiiGiveTheSameForces) {
  ForceField ff({ParticleType{"big", 2.0, {0, 0, 0}, 0.0}, ParticleType{"small", 0.25, {0, 0, 0}, 0.0}});
  // Soft repulsions (no hard core: random placement may overlap), cut off at contact: 4, 2.25, 0.5.
  ff.set_pair(0, 0, {.kind = PairKind::soft, .epsilon = 2.0});
  ff.set_pair(0, 1, {.kind = PairKind::soft, .epsilon = 1.0});
  ff.set_pair(1, 1, {.kind = PairKind::soft, .epsilon = 1.0});
  const std::size_t n = 1500;
  const double box = 40.0;
  auto x = random_points(n, box, 9);
  std::vector<std::uint32_t> types(n);
  for (std::size_t i = 0; i < n; ++i) types[i] = i % 25 == 0 ? 0 : 1;
  const auto geometry = rpyfmm::rpy::Geometry::periodic(box);
  NeighbourList one(geometry, ff.max_cutoff(), {}), per_kind(geometry, ff.max_cutoff(), {});
  per_kind.set_pair_cutoffs(types, ff.pair_cutoffs(), 2);
  one.build(x);
  per_kind.build(x);
  EXPECT_LT(per_kind.pair_entries() * 5, one.pair_entries());  // much shorter rows
  std::mt19937_64 gen(3);
  std::uniform_real_distribution<double> step(-1.0, 1.0);
  for (int move = 0; move < 4; ++move) {
    std::vector<double> f_one(3 * n), f_kind(3 * n);
    const double e_one = ff.compute(x, types, one, 0, f_one);
    const double e_kind = ff.compute(x, types, per_kind, 0, f_kind);
    EXPECT_EQ(f_kind, f_one) << "move " << move;
    EXPECT_EQ(e_kind, e_one);
    // The energy is summed in particle order: the same with 1 and 3 threads.
    const int threads = omp_get_max_threads();
    omp_set_num_threads(1);
    const double e_serial = ff.compute(x, types, per_kind, 0, f_kind);
    omp_set_num_threads(3);
    const double e_three = ff.compute(x, types, per_kind, 0, f_kind);
    omp_set_num_threads(threads);
    EXPECT_EQ(e_serial, e_kind);
    EXPECT_EQ(e_three, e_kind);
    // Moves of at most 0.05 per axis, 0.35 in all: below half the skin of the largest cut-off
    // (0.3 * 4 / 2 = 0.6), so neither list rebuilds.
    for (double& v : x) v += 0.05 * step(gen);
    EXPECT_FALSE(one.update(x));
    EXPECT_FALSE(per_kind.update(x));
  }
}

TEST(NeighbourList, RebuildsOnlyAfterHalfSkin) {
  NeighbourList list(rpyfmm::rpy::Geometry::open(), 2.0, {.skin = 1.0});
  auto x = random_points(100, 10.0, 5);
  EXPECT_TRUE(list.update(x));
  x[0] += 0.49;  // < skin / 2
  EXPECT_FALSE(list.update(x));
  x[0] += 0.02;  // now 0.51 > skin / 2 (Tran et al. (2015), Algorithm 1, line 15)
  EXPECT_TRUE(list.update(x));
  EXPECT_EQ(list.rebuilds(), 2u);
  NeighbourList fixed(rpyfmm::rpy::Geometry::open(), 2.0, {.skin = 1.0, .fixed_interval = 3});
  int rebuilds = 0;
  for (int s = 0; s < 9; ++s) rebuilds += fixed.update(x);
  EXPECT_EQ(rebuilds, 3);
  EXPECT_THROW(NeighbourList(rpyfmm::rpy::Geometry::periodic(5.0), 2.0, {.skin = 1.0}), Error);  // r_L > L/2
}

TEST(ForceField, PairSumsMatchBruteForceWithTypesBondsAndExternal) {
  ParticleType a{"A", 1.0, {0, 0, -0.5}, 0.0};
  ParticleType b{"B", 0.5, {0.1, 0, 0}, 0.0};
  ForceField ff({a, b});
  ff.set_pair(0, 0, {.kind = PairKind::lj36_18, .epsilon = 2.0});
  ff.set_pair(0, 1, {.kind = PairKind::wca, .epsilon = 1.0});
  ff.set_pair(1, 1, {.kind = PairKind::soft, .epsilon = 3.0});
  const auto bt = ff.add_bond_potential({BondKind::fene, 10.0, 5.0});
  const std::vector<Bond> bonds{{0, 1, bt}, {1, 2, bt}};
  ff.add_bonds(bonds);
  // Particles on a jittered lattice with spacing 2.1 (no hard overlaps).
  const std::size_t n = 216;
  std::vector<double> x(3 * n);
  std::vector<std::uint32_t> types(n);
  std::mt19937_64 gen(7);
  std::uniform_real_distribution<double> jitter(-0.03, 0.03);
  for (std::size_t i = 0; i < n; ++i) {
    x[3 * i] = 2.1 * static_cast<double>(i % 6) + jitter(gen);
    x[3 * i + 1] = 2.1 * static_cast<double>((i / 6) % 6) + jitter(gen);
    x[3 * i + 2] = 2.1 * static_cast<double>(i / 36) + jitter(gen);
    types[i] = static_cast<std::uint32_t>(i % 3 == 0);
  }
  NeighbourList list(rpyfmm::rpy::Geometry::open(), ff.max_cutoff(), {});
  list.build(x);
  std::vector<double> f(3 * n);
  ff.compute(x, types, list, 0, f);
  // Reference: every pair, written plainly.
  std::vector<double> ref(3 * n, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) ref[3 * i + c] += (types[i] ? b : a).external_force[c];
    for (std::size_t j = 0; j < n; ++j) {
      if (i == j) continue;
      const PairTerm& t = ff.pair(types[i], types[j]);
      double d[3], r2 = 0;
      for (int c = 0; c < 3; ++c) {
        d[c] = x[3 * i + c] - x[3 * j + c];
        r2 += d[c] * d[c];
      }
      if (r2 >= t.cutoff * t.cutoff) continue;
      const double s = evaluate_pair(t, std::sqrt(r2)).s;
      for (int c = 0; c < 3; ++c) ref[3 * i + c] += s * d[c];
    }
  }
  for (const Bond& bd : bonds) {
    double d[3], r2 = 0;
    for (int c = 0; c < 3; ++c) {
      d[c] = x[3 * bd.i + c] - x[3 * bd.j + c];
      r2 += d[c] * d[c];
    }
    const double s = evaluate_bond(ff.bond_potentials()[0], std::sqrt(r2)).s;
    for (int c = 0; c < 3; ++c) {
      ref[3 * bd.i + c] += s * d[c];
      ref[3 * bd.j + c] -= s * d[c];
    }
  }
  double scale = 0;
  for (double v : ref) scale = std::max(scale, std::abs(v));
  EXPECT_GT(scale, 1.0);
  for (std::size_t k = 0; k < 3 * n; ++k) EXPECT_NEAR(f[k], ref[k], 1e-12 * scale) << "entry " << k;
}

// Groups (the beads of rigid bodies): pairs within a group are skipped, pairs across groups
// kept, a hard overlap inside a group is not an error; groups of the wrong size are refused.
TEST(ForceField, GroupsSkipPairsWithinAGroup) {
  ForceField ff;
  ff.set_pair(0, 0, {.kind = PairKind::wca, .epsilon = 1.0, .sigma = 2.0});
  // 0-1 overlap hard (r = 1 < 0.8 sigma) but share group 0; 1-2 at r = 2.1 < 2^(1/6) 2 interact.
  const std::vector<double> x{0, 0, 0, 1, 0, 0, 3.1, 0, 0, 9, 0, 0};
  const std::vector<std::uint32_t> types(4, 0), groups{0, 0, 1, 1};
  NeighbourList list(rpyfmm::rpy::Geometry::open(), ff.max_cutoff(), {});
  list.build(x);
  std::vector<double> f(12);
  EXPECT_THROW(ff.compute(x, types, list, 0, f), rpyfmm::Error);  // without groups: the overlap
  ff.compute(x, types, list, 0, f, groups);
  const double s = evaluate_pair(ff.pair(0, 0), 2.1).s;
  const std::vector<double> expected{0, 0, 0, -2.1 * s, 0, 0, 2.1 * s, 0, 0, 0, 0, 0};
  for (std::size_t k = 0; k < 12; ++k) EXPECT_NEAR(f[k], expected[k], 1e-12 * std::abs(2.1 * s)) << k;
  EXPECT_NE(s, 0.0);
  const std::vector<std::uint32_t> short_groups{0, 0, 1};
  EXPECT_THROW(ff.compute(x, types, list, 0, f, short_groups), rpyfmm::Error);
}

TEST(ForceField, OverlapAndOverstretchedBondNameTheParticles) {
  ForceField ff;
  ff.set_pair(0, 0, {.kind = PairKind::lj36_18, .epsilon = 14.0});
  std::vector<double> x{0, 0, 0, 5, 0, 0, 6.0, 0, 0};  // particles 1 and 2 at r = 1 < 0.8 * 2
  std::vector<std::uint32_t> types{0, 0, 0};
  NeighbourList list(rpyfmm::rpy::Geometry::open(), ff.max_cutoff(), {});
  list.build(x);
  std::vector<double> f(9);
  try {
    ff.compute(x, types, list, 12, f);
    FAIL() << "overlap not detected";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::invalid_input);
    EXPECT_NE(std::string(e.what()).find("particles 1 and 2 overlap at step 12"), std::string::npos) << e.what();
  }
  ForceField chain;
  const auto bt = chain.add_bond_potential({BondKind::fene, 30.0, 1.5});
  const std::vector<Bond> bonds{{0, 2, bt}};
  chain.add_bonds(bonds);
  NeighbourList empty(rpyfmm::rpy::Geometry::open(), 0.0, {});
  empty.build(x);
  try {
    chain.compute(x, types, empty, 0, f);
    FAIL() << "overstretched FENE bond not detected";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("between particles 0 and 2"), std::string::npos) << e.what();
  }
  EXPECT_THROW(chain.check(std::vector<std::uint32_t>{0, 0}), Error);  // bond refers to particle 2 >= N
  EXPECT_THROW(ForceField({ParticleType{"A", -1.0}}), Error);
}

// compute_rows on a part of a system (the particles of one MPI rank with its halo): the rows' forces
// and energy shares are compute()'s bit for bit, whatever subset of rows is asked for and in which
// order, with bonds indexing the part; errors name the particles by their ids; callbacks are refused.
TEST(ForceField, RowsOfAPartEqualTheWholeSystemsForcesBitForBit) {
  ForceField ff({ParticleType{"A", 0.5, {0.0, 0.1, 0.0}, 0.0}, ParticleType{"B", 0.7, {0, 0, 0}, 0.0}});
  ff.set_pair(0, 0, {.kind = PairKind::lj36_18, .epsilon = 1.0});
  ff.set_pair(0, 1, {.kind = PairKind::wca});
  ff.set_pair(1, 1, {.kind = PairKind::soft, .epsilon = 2.0});
  ff.set_trap(0.1);
  const std::size_t n = 125;
  std::vector<double> x(3 * n);
  std::vector<std::uint32_t> types(n);
  std::mt19937_64 gen(3);
  std::uniform_real_distribution<double> jitter(-0.1, 0.1);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t c = 0, k = i; c < 3; ++c, k /= 5) x[3 * i + c] = 1.5 * static_cast<double>(k % 5) + jitter(gen);
    types[i] = static_cast<std::uint32_t>(i % 2);
  }
  NeighbourList list(rpyfmm::rpy::Geometry::open(), ff.max_cutoff(), {});
  list.set_pair_cutoffs(types, ff.pair_cutoffs(), 2);
  list.build(x);
  std::vector<double> f(3 * n);
  const double energy = ff.compute(x, types, list, 0, f);
  std::vector<std::uint64_t> ids(n);
  for (std::size_t i = 0; i < n; ++i) ids[i] = 1000 + i;
  const std::vector<std::uint32_t> rows{77, 3, 124, 0, 50};
  std::vector<double> fr(3 * rows.size()), er(rows.size());
  ff.compute_rows(x, types, list, 0, rows, ids, fr, er);
  for (std::size_t k = 0; k < rows.size(); ++k)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(fr[3 * k + c], f[3 * rows[k] + c]) << "row " << rows[k];
  std::vector<std::uint32_t> all(n);
  for (std::size_t i = 0; i < n; ++i) all[i] = static_cast<std::uint32_t>(i);
  std::vector<double> fa(3 * n), ea(n);
  ff.compute_rows(x, types, list, 0, all, ids, fa, ea);
  double sum = 0.0;
  for (const double e : ea) sum += e;
  EXPECT_EQ(sum, energy);  // compute() sums the same shares in the same order
  EXPECT_EQ(fa, f);
  // An overlap is named by the ids.
  std::vector<double> y = x;
  for (int c = 0; c < 3; ++c) y[3 * 6 + c] = y[3 * 5 + c] + (c == 1 ? 0.2 : 0.0);
  list.build(y);
  try {
    ff.compute_rows(y, types, list, 4, all, ids, fa, ea);
    FAIL() << "overlap not detected";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("particles 1005 and 1006 overlap at step 4"), std::string::npos) << e.what();
  }
  const std::vector<std::uint32_t> beyond{0, 125};
  EXPECT_THROW(ff.compute_rows(x, types, list, 0, beyond, ids, fr, er), Error);
  // Bonds index the part: the rows with bonds are compute()'s bit for bit, and a FENE bond beyond
  // its maximum extension is named by the name with_bonds gives it and by the particles' ids.
  list.build(x);
  ForceField bonded = ff;
  const auto spring = bonded.add_bond_potential({.kind = BondKind::harmonic, .k = 3.0, .length = 1.2});
  const auto fene = bonded.add_bond_potential({.kind = BondKind::fene, .k = 2.0, .length = 2.5});
  bonded.add_bonds(std::vector<Bond>{{0, 1, spring}, {77, 78, fene}, {3, 4, fene}, {124, 0, spring}, {50, 51, fene}});
  bonded.compute(x, types, list, 0, f);
  bonded.compute_rows(x, types, list, 0, rows, ids, fr, er);
  for (std::size_t k = 0; k < rows.size(); ++k)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(fr[3 * k + c], f[3 * rows[k] + c]) << "bonded row " << rows[k];
  const std::vector<Bond> stretched{{0, 124, fene}};  // 8.5 apart
  try {
    bonded.with_bonds(stretched, std::vector<std::uint64_t>{4000}).compute_rows(x, types, list, 2, rows, ids, fr, er);
    FAIL() << "a FENE bond beyond its maximum extension not detected";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("bond 4000 between particles 1000 and 1124 at step 2"), std::string::npos)
        << e.what();
  }
  ForceField called = ff;
  called.add_callback([](auto, auto, auto) {});
  try {
    called.compute_rows(x, types, list, 0, rows, ids, fr, er);
    FAIL() << "callbacks not refused";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::not_supported);
  }
}

TEST(MobilityFactory, FreeDrainingAndUnavailableMethods) {
  auto m = make_mobility({.method = MobilityMethod::none}, 2);
  m->set_positions(std::vector<double>{0, 0, 0, 1, 0, 0}, std::vector<double>{1.0, 2.0});
  std::vector<double> f{1, 2, 3, 4, 5, 6}, u(6), w(6);
  m->apply(f, u);
  EXPECT_NEAR(u[1], 2.0 / (6 * M_PI), 1e-15);
  EXPECT_NEAR(u[4], 5.0 / (12 * M_PI), 1e-15);
  m->apply_sqrt(f, w);
  EXPECT_NEAR(w[4], 5.0 / std::sqrt(12 * M_PI), 1e-15);
  EXPECT_THROW(mobility_method_from_string("magic"), Error);
  EXPECT_EQ(mobility_method_from_string("auto"), MobilityMethod::automatic);
  // pse in open geometry: PSE with open boundaries; on a GPU not (yet) supported, by name.
  EXPECT_EQ(make_mobility({.method = MobilityMethod::pse}, 10)->name(), "pse-open");
  try {
    (void)make_mobility({.method = MobilityMethod::pse, .device = rpyfmm::rpy::ComputeDevice::cuda}, 10);
    FAIL();
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::not_supported);
    EXPECT_NE(std::string(e.what()).find("pse"), std::string::npos);
  }
  EXPECT_THROW((void)make_mobility({.method = MobilityMethod::none, .tolerance = 2.0}, 10), Error);
  // The PSE options reach the operator (MobilitySpec::wave_precision, fft_measure).
  for (const auto precision :
       {rpyfmm::rpy::pse::WavePrecision::double_precision, rpyfmm::rpy::pse::WavePrecision::single_precision}) {
    const auto pse = make_mobility({.method = MobilityMethod::pse,
                                    .geometry = rpyfmm::rpy::Geometry::periodic(12.0),
                                    .fft_measure = true,
                                    .wave_precision = precision},
                                   10);
    const auto* op = dynamic_cast<const rpyfmm::rpy::pse::PseRpy*>(pse.get());
    ASSERT_NE(op, nullptr);
    EXPECT_EQ(op->options().wave_precision, precision);
    EXPECT_TRUE(op->options().fft_measure);
  }
}
