// The SAC scheme (Algorithm 2 of Tran et al. (2015), Sec. 4.2; docs/theory/bd.md Sec. 9): complex
// membership against a brute-force search (ties included), a complex of k adsorbed particles
// diffusing as one body with the carrier's friction (and the naive scheme's caging drop beside it),
// runs without complexes equal to naive runs bit for bit, results independent of the thread count,
// restarts bit for bit, touching complexes whose adsorbed particles repel, Boltzmann's distribution
// of a trapped complex, and the config errors naming their key. Fixed seeds.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "config_helpers.hpp"
#include "one_thread.hpp"
#include "restart_pair.hpp"
#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/bd/output.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/bd/sac.hpp"
#include "rpyfmm/core/error.hpp"
#include "run_files_fixture.hpp"
#include "text_edit.hpp"

using namespace rpyfmm::bd;
using rpyfmm::Error;

namespace {

using bdtest::expect_refused;
using bdtest::make_integrator;
using bdtest::replace;

// Carriers "L" (Langevin, radius 1) and adsorbers "S" (Brownian, radius 0.25), free draining. The
// L-S well (lj36_18, eps = 14 kT, minimum at 2^(1/18) 1.25 = 1.30) lies well inside
// R_A = 1.2 x 1.25 = 1.5 (13 thermal widths sqrt(kT / V'') = 0.014): adsorbed particles stay.
const std::string kComplex = R"(
[system]
kT = 1.0
[[types]]
name = "L"
radius = 1.0
dynamics = "langevin"
mass = 0.000377
[[types]]
name = "S"
radius = 0.25
[particles]
source = "random"
count = 60
volume_fraction = 0.2
types = ["L", "S", "S", "S", "S"]
[[pair]]
types = ["L", "S"]
kind = "soft"
epsilon = 5.0
[[pair]]
types = ["S", "S"]
kind = "soft"
epsilon = 5.0
[mobility]
method = "none"
[integrator]
dt = 0.0001
steps = 40
seed = 11
scheme = "sac"
adsorption_factor = 1.5
[output]
trajectory_every = 5
log_every = 5
checkpoint_every = 10
)";

/// Brute-force membership: every adsorber against every carrier in index order, minimum image
/// computed here (box 0: open); the nearest strictly, so ties stay with the lower index.
std::vector<std::uint32_t> brute_force_owner(const std::vector<double>& x, const std::vector<std::uint32_t>& types,
                                             const std::vector<bool>& carrier_type, const std::vector<double>& radius,
                                             double factor, double box) {
  const std::size_t n = types.size();
  std::vector<std::uint32_t> owner(n, Complexes::kFree);
  for (std::size_t s = 0; s < n; ++s) {
    if (carrier_type[types[s]]) continue;
    double best2 = 0.0;
    for (std::size_t c = 0; c < n; ++c) {
      if (!carrier_type[types[c]]) continue;
      double r2 = 0.0;
      for (int k = 0; k < 3; ++k) {
        double d = x[3 * c + k] - x[3 * s + k];
        if (box > 0.0) d -= box * std::nearbyint(d / box);
        r2 += d * d;
      }
      const double ra = factor * (radius[types[c]] + radius[types[s]]);
      if (r2 < ra * ra && (owner[s] == Complexes::kFree || r2 < best2)) {
        owner[s] = static_cast<std::uint32_t>(c);
        best2 = r2;
      }
    }
  }
  for (std::size_t s = 0; s < n; ++s)
    if (owner[s] != Complexes::kFree) owner[owner[s]] = owner[s];
  return owner;
}

/// Uniform numbers in [0, 1) from a fixed seed (mt19937_64's raw output: the same on every platform).
std::vector<double> uniform(std::size_t count, std::uint64_t seed) {
  std::mt19937_64 gen(seed);
  std::vector<double> u(count);
  for (double& v : u) v = static_cast<double>(gen() >> 11) * 0x1.0p-53;
  return u;
}

class SacRun : public bdtest::RunFiles {};

}  // namespace

TEST(SacMembership, MatchesBruteForceWithTiesOpenAndPeriodic) {
  // Two carrier types (radii 2 and 1) and two adsorber types (0.5, 0.25) on a grid of spacing
  // 0.25 in a box of side 16: coordinates, their differences and squared distances are exact in
  // binary, so many adsorbers lie at exactly equal distances from two carriers (ties) and both
  // searches see the same numbers. Periodic runs add multiples of the box to half the positions
  // (unwrapped positions, minimum image). Sizes 40 (all-pairs list) and 1500 (cell list).
  const std::vector<ParticleType> table{{"L", 2.0}, {"S", 0.5}, {"M", 1.0}, {"T", 0.25}};
  std::vector<std::optional<LangevinParticle>> inertia(4);
  inertia[0] = LangevinParticle{1.0, 1.0};
  inertia[2] = LangevinParticle{1.0, 1.0};
  const std::vector<bool> carrier_type{true, false, true, false};
  const std::vector<double> radius{2.0, 0.5, 1.0, 0.25};
  const double box = 16.0, factor = 1.05;
  std::size_t ties = 0, adsorbed = 0;
  for (const std::size_t n : {std::size_t{40}, std::size_t{1500}}) {
    for (const bool periodic : {false, true}) {
      for (std::uint64_t seed = 1; seed <= 3; ++seed) {
        const std::vector<double> u = uniform(3 * n, seed);
        std::vector<double> x(3 * n);
        std::vector<std::uint32_t> types(n);
        for (std::size_t i = 0; i < n; ++i) {
          types[i] = i % 7 == 0 ? 0 : i % 7 == 3 ? 2 : i % 2 == 0 ? 1 : 3;
          for (int k = 0; k < 3; ++k) {
            x[3 * i + k] = 0.25 * std::floor(u[3 * i + k] * 64.0 * (n < 100 ? 0.5 : 1.0));
            if (periodic && i % 2 == 1) x[3 * i + k] += box * static_cast<double>(int(i % 5) - 2);
          }
        }
        const auto geometry = periodic ? rpyfmm::rpy::Geometry::periodic(box, box, box) : rpyfmm::rpy::Geometry::open();
        Complexes complexes(geometry, table, inertia, types, factor);
        complexes.update(x);
        const auto expected = brute_force_owner(x, types, carrier_type, radius, factor, periodic ? box : 0.0);
        const auto owner = complexes.owner();
        ASSERT_EQ(owner.size(), n);
        std::size_t count = 0, members = 0;
        for (std::size_t i = 0; i < n; ++i) {
          EXPECT_EQ(owner[i], expected[i]) << "particle " << i << " n " << n << " periodic " << periodic;
          if (owner[i] == i) ++count;
          if (owner[i] != Complexes::kFree && owner[i] != i) ++members;
        }
        EXPECT_EQ(complexes.count(), count);
        EXPECT_EQ(complexes.adsorbed_total(), members);
        adsorbed += members;
        for (std::size_t c = 0; c < n; ++c) {  // the groups list exactly the owners, ascending
          const auto group = complexes.adsorbed(c);
          for (std::size_t k = 0; k < group.size(); ++k) {
            EXPECT_EQ(owner[group[k]], c);
            if (k > 0) {
              EXPECT_LT(group[k - 1], group[k]);
            }
          }
        }
        // Count the ties the rule decided: an adsorber at the same distance from its carrier and a
        // carrier of higher index, both within R_A.
        for (std::size_t s = 0; s < n; ++s) {
          if (carrier_type[types[s]] || owner[s] == Complexes::kFree) continue;
          const auto dist2 = [&](std::size_t c) {
            double r2 = 0.0;
            for (int k = 0; k < 3; ++k) {
              double d = x[3 * c + k] - x[3 * s + k];
              if (periodic) d -= box * std::nearbyint(d / box);
              r2 += d * d;
            }
            return r2;
          };
          for (std::size_t c = owner[s] + 1; c < n; ++c) {
            const double ra = factor * (radius[types[c]] + radius[types[s]]);
            if (carrier_type[types[c]] && dist2(c) == dist2(owner[s]) && dist2(c) < ra * ra) ++ties;
          }
        }
      }
    }
  }
  EXPECT_GT(ties, 20u) << "the configurations must exercise the tie rule";
  EXPECT_GT(adsorbed, 1000u);
}

TEST(SacMembership, RefusesRunsWithoutBothKinds) {
  const std::vector<ParticleType> table{{"L", 2.0}, {"S", 0.5}};
  std::vector<std::optional<LangevinParticle>> inertia(2);
  inertia[0] = LangevinParticle{1.0, 1.0};
  const auto geometry = rpyfmm::rpy::Geometry::open();
  EXPECT_THROW(Complexes(geometry, table, inertia, std::vector<std::uint32_t>{1, 1}, 1.05), Error);
  EXPECT_THROW(Complexes(geometry, table, inertia, std::vector<std::uint32_t>{0, 0}, 1.05), Error);
  EXPECT_THROW(Complexes(geometry, table, inertia, std::vector<std::uint32_t>{0, 1}, 0.0), Error);
  EXPECT_NO_THROW(Complexes(geometry, table, inertia, std::vector<std::uint32_t>{0, 1}, 1.05));
}

TEST(SacDynamics, AComplexDiffusesAsOneBodyWithTheCarriersFriction) {
  // 27 carriers (gamma_L = 6 pi), each with k = 8 adsorbed particles (gamma_S = 6 pi / 4) held in
  // the L-S well, 12 apart (no forces between complexes). D is estimated from the squared
  // displacements over windows of T = 100 steps: 300 windows per carrier, 3 components each, so
  // the relative standard error of the estimate is sqrt(2 / (3 x 8100)) = 0.9%. The velocity
  // relaxation time m / gamma = 0.2 dt biases <dx^2> by tau / T = 0.2% (the GJF step keeps the
  // long-time D = kT / gamma exactly). Bound: 5 standard errors + the bias, 5% of the expected D.
  //   SAC: the complex moves with the carrier's friction, D = kT / gamma_L, and every adsorbed
  //   particle stays (8 per complex).
  //   Naive: the frictions add (the caging of the paper's Sec. 4.1). The internal forces cancel in
  //   the sum of gamma_i dx_i, so the friction-weighted centre of a complex diffuses with
  //   kT / (gamma_L + k gamma_S) = D0 / 3 at every time scale longer than m / gamma (the carrier
  //   alone only at times beyond the adsorbed particles' sliding around it, R^2 / D_S ~ 8).
  const bdtest::OneThread one;
  const std::string text =
      replace(replace(replace(kComplex, "kind = \"soft\"\nepsilon = 5.0", "kind = \"lj36_18\"\nepsilon = 14.0"),
                      "[[pair]]\ntypes = [\"S\", \"S\"]\nkind = \"soft\"\nepsilon = 5.0\n", ""),
              "adsorption_factor = 1.5", "adsorption_factor = 1.2");
  const RunConfig sac = parse_config(text, "sac");
  const RunConfig naive =
      parse_config(replace(replace(text, "scheme = \"sac\"\n", ""), "adsorption_factor = 1.2\n", ""), "naive");
  const std::size_t carriers = 27, k = 8, n = carriers * (k + 1);
  const double r_min = std::pow(2.0, 1.0 / 18.0) * 1.25;
  std::vector<double> x(3 * n);
  std::vector<std::uint32_t> types(n, 1);
  const double corner = r_min / std::sqrt(3.0);
  for (std::size_t c = 0; c < carriers; ++c) {
    const double centre[3] = {12.0 * double(c % 3), 12.0 * double(c / 3 % 3), 12.0 * double(c / 9)};
    types[c * (k + 1)] = 0;
    for (int d = 0; d < 3; ++d) x[3 * c * (k + 1) + d] = centre[d];
    for (std::size_t s = 0; s < k; ++s) {  // the cube's corners at r_min
      const std::size_t i = c * (k + 1) + 1 + s;
      for (int d = 0; d < 3; ++d) x[3 * i + d] = centre[d] + ((s >> d) & 1 ? corner : -corner);
    }
  }
  const double kT = 1.0, dt = sac.integrator.dt, gamma_l = 6.0 * std::numbers::pi, gamma_s = gamma_l / 4.0;
  const int window = 100, windows = 300;
  const auto diffusion = [&](const RunConfig& config, bool check_membership) {
    Integrator bd = make_integrator(config, x, types);
    bd.run(200);  // velocities and the particles in the wells settle
    double sum_l = 0.0, sum_centre = 0.0;
    std::vector<double> start(bd.positions().begin(), bd.positions().end());
    for (int w = 0; w < windows; ++w) {
      bd.run(window);
      const auto now = bd.positions();
      for (std::size_t c = 0; c < carriers; ++c) {
        for (int d = 0; d < 3; ++d) {
          const std::size_t l = 3 * c * (k + 1) + d;
          double centre = gamma_l * (now[l] - start[l]);
          for (std::size_t s = 1; s <= k; ++s) centre += gamma_s * (now[l + 3 * s] - start[l + 3 * s]);
          centre /= gamma_l + k * gamma_s;
          sum_l += std::pow(now[l] - start[l], 2);
          sum_centre += centre * centre;
        }
      }
      start.assign(now.begin(), now.end());
      if (check_membership) {
        EXPECT_EQ(bd.complexes().count(), carriers);
        EXPECT_EQ(bd.complexes().mean_adsorbed(), double(k));
      }
    }
    const double t = window * dt * windows;
    return std::pair{sum_l / (2.0 * t * carriers * 3), sum_centre / (2.0 * t * carriers * 3)};
  };
  const double d0 = kT / gamma_l;
  const auto sac_l = diffusion(sac, true).first;
  EXPECT_NEAR(sac_l / d0, 1.0, 0.05);
  const auto naive_centre = diffusion(naive, false).second;
  const double caged = gamma_l / (gamma_l + k * gamma_s);
  EXPECT_NEAR(naive_centre / d0, caged, 0.05 * caged);
  std::printf("SAC D/D0 %.4f naive centre D/D0 %.4f expected %.4f\n", sac_l / d0, naive_centre / d0, caged);
}

TEST(SacDynamics, WithoutAdsorptionItIsTheNaiveSchemeBitForBit) {
  // R_A below every distance (factor 0.01): no complexes, so each particle feels the same forces
  // and noise as in the naive scheme, summed in the same order.
  const RunConfig sac = parse_config(replace(kComplex, "adsorption_factor = 1.5", "adsorption_factor = 0.01"), "sac");
  const RunConfig naive =
      parse_config(replace(replace(kComplex, "scheme = \"sac\"\n", ""), "adsorption_factor = 1.5\n", ""), "naive");
  std::vector<double> x(3 * 80);
  for (std::size_t i = 0; i < 80; ++i)
    for (int d = 0; d < 3; ++d)
      x[3 * i + d] = 0.9 * double((i >> (2 * d)) % 4) + (d == 0 ? 0.9 * 4 * double(i / 64) : 0.0);
  std::vector<std::uint32_t> types(80);
  for (std::size_t i = 0; i < 80; ++i) types[i] = i % 5 == 0 ? 0 : 1;
  Integrator a = make_integrator(sac, x, types), b = make_integrator(naive, x, types);
  a.run(30);
  b.run(30);
  EXPECT_EQ(a.complexes().count(), 0u);
  for (std::size_t k = 0; k < x.size(); ++k) {
    EXPECT_EQ(a.positions()[k], b.positions()[k]) << k;
    EXPECT_EQ(a.inertial().velocities()[k], b.inertial().velocities()[k]) << k;
  }
  EXPECT_NE(a.positions()[0], x[0]);
}

TEST(SacDynamics, AdsorbedParticlesDoNotPushTheirCarrier) {
  // One carrier, one adsorbed particle pressed into the soft repulsion, kT = 0: in the SAC scheme
  // the carrier does not move (no force from outside its complex), the adsorbed particle is pushed
  // away by the carrier; in the naive scheme both move.
  const std::string text = replace(kComplex, "kT = 1.0", "kT = 0.0");
  const RunConfig sac = parse_config(text, "sac");
  const RunConfig naive =
      parse_config(replace(replace(text, "scheme = \"sac\"\n", ""), "adsorption_factor = 1.5\n", ""), "naive");
  const std::vector<double> x{0, 0, 0, 1.0, 0, 0};
  for (const RunConfig* c : {&sac, &naive}) {
    Integrator bd = make_integrator(*c, x, {0, 1});
    bd.run(5);
    if (c == &sac) {
      EXPECT_EQ(bd.complexes().count(), 1u);
      EXPECT_EQ(bd.positions()[0], 0.0);
    } else {
      EXPECT_LT(bd.positions()[0], 0.0);
    }
    EXPECT_GT(bd.positions()[3], 1.0);
  }
}

TEST(SacDynamics, SameResultWithOneTwoAndThreeThreads) {
  // 6000 particles (above the threshold of every parallel loop of the step), 1 carrier in 10,
  // soft pairs: positions, velocities and membership after 4 steps are identical.
  const RunConfig c = parse_config(kComplex, "sac");
  const std::size_t n = 6000;
  std::vector<double> x = uniform(3 * n, 5);
  for (double& v : x) v *= 30.0;
  std::vector<std::uint32_t> types(n);
  for (std::size_t i = 0; i < n; ++i) types[i] = i % 10 == 0 ? 0 : 1;
  std::vector<std::vector<double>> positions, velocities;
  std::vector<std::vector<std::uint32_t>> owners;
  const int saved = omp_get_max_threads();
  for (int threads = 1; threads <= 3; ++threads) {
    omp_set_num_threads(threads);
    Integrator bd = make_integrator(c, x, types);
    bd.run(4);
    positions.emplace_back(bd.positions().begin(), bd.positions().end());
    velocities.emplace_back(bd.inertial().velocities().begin(), bd.inertial().velocities().end());
    owners.emplace_back(bd.complexes().owner().begin(), bd.complexes().owner().end());
    EXPECT_GT(bd.complexes().count(), 100u);
  }
  omp_set_num_threads(saved);
  for (int t = 1; t < 3; ++t) {
    EXPECT_TRUE(positions[t] == positions[0]) << t + 1 << " threads";
    EXPECT_TRUE(velocities[t] == velocities[0]) << t + 1 << " threads";
    EXPECT_TRUE(owners[t] == owners[0]) << t + 1 << " threads";
  }
}

TEST_F(SacRun, RestartContinuesBitForBitWithComplexesInTheOutputs) {
  // Interrupted at step 20 and restarted to 40: positions, velocities, the trajectory (with its
  // complex column) and the log's complexes and mean_adsorbed columns equal those of the
  // uninterrupted run, bitwise. Membership is recomputed from the positions, so the checkpoint
  // stores none.
  const bdtest::OneThread one;
  const RunConfig c = parse_config(kComplex, "sac");
  EXPECT_EQ(bdtest::run_whole_and_restarted(c, dir_ / "whole", dir_ / "split", 20).last_step, 40u);
  const Checkpoint a = read_checkpoint(dir_ / "whole" / "checkpoint.bin");
  const Checkpoint b = read_checkpoint(dir_ / "split" / "checkpoint.bin");
  EXPECT_TRUE(a.positions == b.positions);
  EXPECT_TRUE(a.velocities == b.velocities);
  const std::string traj = slurp(dir_ / "whole" / "trajectory.xyz");
  EXPECT_TRUE(traj == slurp(dir_ / "split" / "trajectory.xyz"));
  EXPECT_NE(traj.find(":complex:I:1 "), std::string::npos);
  const auto last_two = [](const std::string& log) {
    std::vector<std::string> out;
    for (std::size_t start = 0, end; (end = log.find('\n', start)) != std::string::npos; start = end + 1) {
      const std::string line = log.substr(start, end - start);
      out.push_back(line.substr(line.rfind(',', line.rfind(',') - 1) + 1));
    }
    return out;
  };
  const auto cols = last_two(slurp(dir_ / "whole" / "log.csv"));
  EXPECT_EQ(cols, last_two(slurp(dir_ / "split" / "log.csv")));
  ASSERT_EQ(cols.size(), 10u);  // header + steps 0, 5, ..., 40
  EXPECT_EQ(cols.front(), "complexes,mean_adsorbed");
  EXPECT_NE(cols.back().substr(0, 2), "0,") << "the run must have complexes";
}

TEST(SacOutput, XyzFramesCarryTheComplexColumn) {
  // A carrier (0) with one adsorbed particle (2) and a free particle (1): ids 0, -1, 0.
  const std::vector<ParticleType> table{{"L", 2.0}, {"S", 0.5}};
  const std::vector<double> x{0, 0, 0, 10, 0, 0, 2.5, 0, 0};
  const std::vector<std::uint32_t> ids{0, Complexes::kFree, 0};
  const std::string frame =
      xyz_frame(x, std::vector<std::uint32_t>{0, 1, 1}, table, rpyfmm::rpy::Geometry::open(), 3, 0.5, {}, ids);
  EXPECT_NE(frame.find("Properties=species:S:1:pos:R:3:radius:R:1:complex:I:1 Time=0.5 Step=3\n"), std::string::npos)
      << frame;
  EXPECT_NE(frame.find("\nL 0 0 0 2 0\nS 10 0 0 0.5 -1\nS 2.5 0 0 0.5 0\n"), std::string::npos) << frame;
  EXPECT_EQ(
      xyz_frame(x, std::vector<std::uint32_t>{0, 1, 1}, table, rpyfmm::rpy::Geometry::open(), 3, 0.5).find("complex"),
      std::string::npos);
}

TEST(SacConfig, BadCombinationsAreRefusedNamingTheKey) {
  const std::string k = kComplex;
  expect_refused(replace(k, "scheme = \"sac\"", "scheme = \"complex\""), "integrator.scheme",
                 "must be \"naive\" or \"sac\"");
  expect_refused(replace(k, "scheme = \"sac\"\n", ""), "integrator.adsorption_factor",
                 "only used with scheme = \"sac\"");
  expect_refused(replace(k, "adsorption_factor = 1.5", "adsorption_factor = 0.0"), "integrator.adsorption_factor",
                 "> 0");
  expect_refused(replace(replace(k, "dynamics = \"langevin\"\n", ""), "mass = 0.000377\n", ""), "integrator.scheme",
                 "needs a carrier type");
  expect_refused(replace(k, "radius = 0.25", "radius = 0.25\ndynamics = \"langevin\"\nmass = 1.0"), "integrator.scheme",
                 "needs an adsorbing type");
  expect_refused(replace(k, "method = \"none\"", "method = \"direct\""), "integrator.scheme", "method = \"none\"");
  expect_refused(replace(k, "kT = 1.0", "kT = 1.0\nrotation = true"), "integrator.scheme", "system.rotation");
  expect_refused(replace(k, "[mobility]", "[bonds]\nkind = \"harmonic\"\nk = 1.0\n[mobility]"), "integrator.scheme",
                 "bonds");
  const RunConfig c = parse_config(k, "good");
  EXPECT_TRUE(c.integrator.sac.enabled);
  EXPECT_EQ(c.integrator.sac.adsorption_factor, 1.5);
  EXPECT_EQ(parse_config(replace(k, "adsorption_factor = 1.5\n", ""), "default").integrator.sac.adsorption_factor,
            1.05);
}

TEST_F(SacRun, ARunWhoseParticlesHaveNoCarrierIsRefused) {
  // The types allow complexes but the generated particles are all adsorbers: refused before any
  // file is written.
  const RunConfig c =
      parse_config(replace(kComplex, "types = [\"L\", \"S\", \"S\", \"S\", \"S\"]", "types = [\"S\"]"), "no carriers");
  expect_error([&] { (void)run(c, dir_ / "out", 5); }, {"carrier"});
  EXPECT_FALSE(std::filesystem::exists(dir_ / "out"));
}

namespace {

// kComplex with the L-S well of the paper (lj36_18, eps = 14 kT, R_A = 1.2 (a_L + a_S) = 1.5),
// WCA between adsorbers (eps = 1 kT) and between carriers (eps = 14 kT, sigma = 2 (a_L + a_S), so
// that no adsorbed particle sits in both carriers' wells at once and pulls them into each other),
// and a harmonic trap k |x|^2 / 2 on every particle.
std::string touching_config(double trap, double dt) {
  std::string text = replace(replace(kComplex, "kind = \"soft\"\nepsilon = 5.0", "kind = \"lj36_18\"\nepsilon = 14.0"),
                             "kind = \"soft\"\nepsilon = 5.0", "kind = \"wca\"\nepsilon = 1.0");
  text = replace(
      text, "[mobility]",
      "[[pair]]\ntypes = [\"L\", \"L\"]\nkind = \"wca\"\nepsilon = 14.0\nsigma = 2.5\n[external]\ntrap_stiffness = " +
          std::to_string(trap) + "\n[mobility]");
  return replace(replace(text, "adsorption_factor = 1.5", "adsorption_factor = 1.2"), "dt = 0.0001",
                 "dt = " + std::to_string(dt));
}

/// The L-S well of touching_config: 4 eps [(s/r)^36 - (s/r)^18], eps = 14, s = a_L + a_S = 1.25.
double ls_well(double r) {
  const double q = std::pow(1.25 / r, 18);
  return 56.0 * (q * q - q);
}

}  // namespace

TEST(SacDynamics, TouchingComplexesKeepTheirAdsorbedParticlesApart) {
  // Two carriers, each with 12 adsorbed particles at the well's minimum (a Fibonacci lattice about
  // the axis joining them, mirrored), pressed together by the trap (k = 50: about 1000 kT / a_L on
  // each complex) so that adsorbed particles of the two complexes touch (WCA, sigma = 0.5) and those
  // of one complex also feel the other carrier. The forces from the other complex act on each
  // adsorbed particle's own step (docs/theory/bd.md Sec. 9), so the adsorbed particles of the two
  // complexes push each other aside: 4e4 steps (4 time units, 200 relaxation times gamma_L / 13k
  // of a complex in the trap) pass the overlap check (r >= 0.8 sigma on every hard pair), keep all
  // 24 adsorbed, and the complexes touch in most frames. When only the complexes as wholes feel
  // those forces, two adsorbed particles overlap within 100 steps.
  const bdtest::OneThread one;
  const RunConfig c = parse_config(touching_config(50.0, 1e-4), "touching");
  const std::size_t k = 12, n = 2 * (k + 1);
  const double r_min = std::pow(2.0, 1.0 / 18.0) * 1.25, golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
  std::vector<double> x(3 * n, 0.0);
  std::vector<std::uint32_t> types(n, 1);
  for (std::size_t body = 0; body < 2; ++body) {
    const double side = body == 0 ? 1.0 : -1.0;  // the lattice's pole points at the other carrier
    const std::size_t c0 = body * (k + 1);
    types[c0] = 0;
    x[3 * c0] = -side * 1.5;
    for (std::size_t s = 0; s < k; ++s) {
      const double u = 1.0 - (2.0 * double(s) + 1.0) / double(k), rho = std::sqrt(1.0 - u * u);
      const double phi = golden * double(s);
      double* p = &x[3 * (c0 + 1 + s)];
      p[0] = x[3 * c0] + side * r_min * u;
      p[1] = r_min * rho * std::cos(phi);
      p[2] = r_min * rho * std::sin(phi);
    }
  }
  Integrator bd = make_integrator(c, x, types);
  int touching = 0;
  const int frames = 400;
  for (int f = 0; f < frames; ++f) {
    ASSERT_NO_THROW(bd.run(100)) << "frame " << f;
    const auto p = bd.positions();
    const auto owner = bd.complexes().owner();
    double closest = 1e300;
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j)
        if (types[i] == 1 && types[j] == 1 && owner[i] != owner[j])
          closest = std::min(closest,
                             std::hypot(p[3 * i] - p[3 * j], p[3 * i + 1] - p[3 * j + 1], p[3 * i + 2] - p[3 * j + 2]));
    touching += closest < std::pow(2.0, 1.0 / 6.0) * 0.5 ? 1 : 0;  // within the WCA range
    EXPECT_EQ(bd.complexes().count(), 2u);
    EXPECT_EQ(bd.complexes().adsorbed_total(), 2 * k);
  }
  EXPECT_GT(touching, frames / 2) << "the complexes must touch through their adsorbed particles";
  std::printf("adsorbed particles of the two complexes within the WCA range in %d of %d frames\n", touching, frames);
}

TEST(SacDynamics, OneComplexInATrapSamplesTheBoltzmannDistribution) {
  // One carrier and one adsorbed particle, both in the trap U_t = k (|x_L|^2 + |x_S|^2) / 2, held by
  // the L-S well V(r). In the coordinates of the SAC step, the complex's position X = x_L and the
  // relative one r = x_S - x_L, U_t = k |X + r/2|^2 + k |r|^2 / 4: Boltzmann's distribution of
  // r = |r| is r^2 exp(-(V(r) + k r^2 / 4) / kT), and <|X + r/2|^2> = 3 kT / (2 k). The SAC step
  // samples it because the adsorbed particle's relative step feels the whole force on it, the
  // trap's included (docs/theory/bd.md Sec. 9); with the forces inside its complex only, r would
  // follow r^2 exp(-V(r) / kT), whose mean lies 0.013 (over 50 standard errors) higher.
  // Expected <r> by the trapezoidal rule on [1.1, 1.5] (the density is < 1e-30 of its peak at
  // both ends) with 4e4 intervals (error < 1e-10). Measured: 1e6 steps of dt = 2e-5, in 40 blocks
  // of 2.5e4 steps, each 5 relaxation times of the trapped complex (gamma_L / 2k = 0.094) and
  // ~5000 of r (gamma_S / V''); standard errors from the blocks' spread. The adsorbed particle's
  // dt V'' / gamma_S = 0.02 biases <r> by about that fraction of <r> - r_min (Euler-Maruyama),
  // 5e-5 here, a quarter of a standard error. Bounds: 4 standard errors.
  const bdtest::OneThread one;
  const double trap = 100.0, kT = 1.0;
  const RunConfig c = parse_config(touching_config(trap, 2e-5), "trap");
  const double r_min = std::pow(2.0, 1.0 / 18.0) * 1.25;
  const auto mean_r = [&](double k) {
    const auto energy = [&](double r) { return ls_well(r) + k * r * r / 4.0; };
    double z = 0.0, m = 0.0;
    const int intervals = 40000;
    const double lo = 1.1, h = 0.4 / intervals;
    for (int i = 0; i <= intervals; ++i) {
      const double r = lo + h * i;
      const double w = (i == 0 || i == intervals ? 0.5 : 1.0) * r * r * std::exp(-(energy(r) - energy(r_min)) / kT);
      z += w;
      m += w * r;
    }
    return m / z;
  };
  const double expected = mean_r(trap), forces_inside_only = mean_r(0.0);
  Integrator bd = make_integrator(c, {0, 0, 0, r_min, 0, 0}, {0, 1});
  bd.run(25000);
  const int blocks = 40, per_block = 25000;
  std::vector<double> block_r, block_centre;
  for (int b = 0; b < blocks; ++b) {
    double sum_r = 0.0, sum_centre = 0.0;
    for (int s = 0; s < per_block; ++s) {
      bd.step();
      const auto p = bd.positions();
      const double d[3] = {p[3] - p[0], p[4] - p[1], p[5] - p[2]};
      sum_r += std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      for (int a = 0; a < 3; ++a) sum_centre += std::pow(p[a] + 0.5 * d[a], 2);
    }
    ASSERT_EQ(bd.complexes().count(), 1u);
    block_r.push_back(sum_r / per_block);
    block_centre.push_back(sum_centre / per_block);
  }
  const auto mean_and_error = [&](const std::vector<double>& v) {
    double m = 0.0, s2 = 0.0;
    for (double e : v) m += e / blocks;
    for (double e : v) s2 += (e - m) * (e - m) / (blocks - 1);
    return std::pair{m, std::sqrt(s2 / blocks)};
  };
  const auto [r, r_err] = mean_and_error(block_r);
  const auto [centre, centre_err] = mean_and_error(block_centre);
  std::printf("<r> %.6f +- %.6f expected %.6f (forces inside only: %.6f); <|X + r/2|^2> %.5f +- %.5f expected %.5f\n",
              r, r_err, expected, forces_inside_only, centre, centre_err, 1.5 * kT / trap);
  EXPECT_NEAR(r, expected, 4.0 * r_err);
  EXPECT_GT(std::abs(forces_inside_only - expected), 20.0 * r_err);
  EXPECT_NEAR(centre, 1.5 * kT / trap, 4.0 * centre_err);
}
