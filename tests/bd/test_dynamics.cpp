// BD integrator: statistics against closed forms (fixed seeds, stated standard
// errors), RPY pair motion, reproducibility across threads and restarts.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <vector>

#include "dense_rpy.hpp"
#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/block_preconditioner.hpp"
#include "rpyfmm/rpy/free_draining.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

using namespace rpyfmm::bd;
using rpyfmm::Error;
using rpyfmm::ErrorCode;
using rpyfmm::rpy::compute_device_from_string;
using rpyfmm::rpy::ComputeDevice;
using rpyfmm::rpy::default_fmm_crossover;
using rpyfmm::rpy::FreeDrainingMobility;
using rpyfmm::rpy::make_mobility;
using rpyfmm::rpy::MobilityMethod;
using rpyfmm::rpy::MobilitySpec;
constexpr double pi = std::numbers::pi;

namespace {
std::unique_ptr<rpyfmm::rpy::MobilityOperator> free_draining() {
  return std::make_unique<FreeDrainingMobility>();
}

std::vector<double> line_of_particles(std::size_t n, double spacing) {
  std::vector<double> x(3 * n, 0.0);
  for (std::size_t i = 0; i < n; ++i) x[3 * i] = spacing * static_cast<double>(i);
  return x;
}

// Harmonic traps F_i = -k (x_i - x0_i) as a user callback.
ForceField trapped(const std::vector<double>& centres, double k) {
  ForceField ff;
  ff.add_callback([centres, k](std::span<const double> x, std::uint64_t, std::span<double> f) {
    for (std::size_t i = 0; i < x.size(); ++i) f[i] += -k * (x[i] - centres[i]);
  });
  return ff;
}
}  // namespace

// MSD of free particles = 6 D0 t (Stokes-Einstein D0 = kT/(6 pi eta a)).
// N = 4000 independent particles (free draining: exact Gaussian steps), 10 steps:
// |dx|^2 / (2 D0 t) ~ chi^2_3, so the mean MSD has relative standard error
// sqrt(2/3)/sqrt(N) = 1.3%; tolerance 5% (~4 sigma).
TEST(BdStatistics, FreeParticleMsdIsSixD0t) {
  const std::size_t n = 4000;
  IntegratorOptions o{.dt = 0.1, .kT = 1.5, .seed = 11};
  auto x0 = line_of_particles(n, 10.0);
  Integrator bd(free_draining(), ForceField(), o, x0, std::vector<std::uint32_t>(n, 0));
  bd.run(10);
  double msd = 0;
  for (std::size_t k = 0; k < 3 * n; ++k) msd += std::pow(bd.positions()[k] - x0[k], 2);
  msd /= static_cast<double>(n);
  const double d0 = 1.5 / (6 * pi);
  EXPECT_NEAR(msd / (6 * d0 * bd.time()), 1.0, 0.05);
  EXPECT_EQ(bd.step_count(), 10u);
  EXPECT_EQ(bd.totals().mobility_products, 0u);  // M F skipped (F = 0); the exact diagonal sqrt needs no product
}

// Euler-Maruyama in a harmonic trap: x' = (1 - h) x + sqrt(2 kT mu dt) xi with
// h = mu k dt has the exact stationary variance (kT/k) * 2/(2 - h), which -> kT/k
// as dt -> 0. N = 500 particles x 3 axes, 50 steps of equilibration ((1-h)^100 ~ 1e-10),
// then 200 steps sampled: correlation time (1+(1-h)^2)/(1-(1-h)^2) = 4.6 steps gives
// ~65000 effective samples, relative standard error 0.55%; tolerance 3%.
TEST(BdStatistics, HarmonicTrapVarianceWithoutHi) {
  const std::size_t n = 500;
  const double k = 2.0, kT = 0.7, mu = 1.0 / (6 * pi), h = 0.2, dt = h / (mu * k);
  auto centres = line_of_particles(n, 10.0);
  Integrator bd(free_draining(), trapped(centres, k), {.dt = dt, .kT = kT, .seed = 5, .max_displacement = 100.0},
                centres, std::vector<std::uint32_t>(n, 0));
  bd.run(50);
  double sum2 = 0;
  std::size_t samples = 0;
  for (int s = 0; s < 200; ++s) {
    bd.step();
    for (std::size_t q = 0; q < 3 * n; ++q) sum2 += std::pow(bd.positions()[q] - centres[q], 2);
    samples += 3 * n;
  }
  const double expected = kT / k * 2.0 / (2.0 - h);
  EXPECT_NEAR(sum2 / static_cast<double>(samples) / expected, 1.0, 0.03);
}

// Two spheres sedimenting under equal forces F (kT = 0), side by side (F perpendicular
// to the line of centres) and one above the other (F along it). Closed-form RPY
// (Guan eq. 3.1): U = F [1/(6 pi eta a) + (1 + 2a^2/(3r^2))/(8 pi eta r)] perpendicular,
//                U = F [1/(6 pi eta a) + (2 - 4a^2/(3r^2))/(8 pi eta r)] parallel.
TEST(BdDynamics, TwoSedimentingSpheresMatchClosedFormRpy) {
  const double a = 1.0, eta = 2.0, r = 3.0, F = 1.0, dt = 1e-3;
  for (bool parallel : {false, true}) {
    ForceField ff({ParticleType{"A", a, {0, 0, -F}, 0.0}});
    std::vector<double> x{0, 0, 0, parallel ? 0.0 : r, 0, parallel ? r : 0.0};
    Integrator bd(std::make_unique<bdtest::DenseRpy>(eta), ff, {.dt = dt, .kT = 0.0, .keep_split_displacements = true},
                  x, {0, 0});
    bd.step();
    const double u_self = F / (6 * pi * eta * a);
    const double u_pair = parallel ? F * (2 - 4 * a * a / (3 * r * r)) / (8 * pi * eta * r)
                                   : F * (1 + 2 * a * a / (3 * r * r)) / (8 * pi * eta * r);
    for (int i = 0; i < 2; ++i) {
      EXPECT_NEAR(bd.positions()[3 * i + 2] - x[3 * i + 2], -(u_self + u_pair) * dt, 1e-15) << "particle " << i;
      EXPECT_NEAR(bd.positions()[3 * i] - x[3 * i], 0.0, 1e-15);
      EXPECT_NEAR(bd.deterministic_displacement()[3 * i + 2], -(u_self + u_pair) * dt, 1e-15);
      EXPECT_EQ(bd.brownian_displacement()[3 * i + 2], 0.0);
    }
  }
}

// Far apart (r = 1e5 a), HI corrections are O(a/r) = 1e-5: with the same noise the
// HI and free-draining paths must agree to that order (tolerance 1e-4 relative).
TEST(BdDynamics, FreeDrainingAndHiAgreeWhenFarApart) {
  const std::size_t n = 4;
  auto x = line_of_particles(n, 1e5);
  ForceField ff({ParticleType{"A", 1.0, {0.3, 0, -1.0}, 0.0}});
  IntegratorOptions o{.dt = 0.05, .kT = 1.0, .seed = 21};
  Integrator hi(std::make_unique<bdtest::DenseRpy>(), ff, o, x, std::vector<std::uint32_t>(n, 0));
  Integrator fd(free_draining(), ff, o, x, std::vector<std::uint32_t>(n, 0));
  hi.run(3);
  fd.run(3);
  for (std::size_t k = 0; k < 3 * n; ++k) {
    const double dfd = fd.positions()[k] - x[k];
    EXPECT_NEAR(hi.positions()[k] - x[k], dfd, 1e-4 * std::max(0.1, std::abs(dfd))) << "entry " << k;
  }
}

namespace {
// A small polymer + colloid system touching every force kind and the cell list.
struct PolymerSystem {
  ForceField ff;
  std::vector<double> x;
  std::vector<std::uint32_t> types;
};
PolymerSystem polymer_system() {
  PolymerSystem s{
      ForceField({ParticleType{"bead", 0.5, {0, 0, -0.2}, 0.0}, ParticleType{"colloid", 1.0, {}, 0.0}}), {}, {}};
  s.ff.set_pair(0, 0, {.kind = PairKind::wca, .epsilon = 1.0});
  s.ff.set_pair(0, 1, {.kind = PairKind::wca, .epsilon = 1.0});
  s.ff.set_pair(1, 1, {.kind = PairKind::lj36_18, .epsilon = 14.0});
  const auto fene = s.ff.add_bond_potential({BondKind::fene, 30.0, 1.5});
  std::vector<Bond> bonds;
  for (std::size_t i = 0; i < 300; ++i) {  // 10 chains of 30 beads (bond 1.05, grid spacing 3)
    const std::size_t c = i / 30, b = i % 30;
    s.x.insert(s.x.end(),
               {1.05 * static_cast<double>(b), 3.0 * static_cast<double>(c % 5), 3.0 * static_cast<double>(c / 5)});
    s.types.push_back(0);
    if (b > 0) bonds.push_back({static_cast<std::uint32_t>(i - 1), static_cast<std::uint32_t>(i), fene});
  }
  for (std::size_t i = 0; i < 100; ++i) {  // colloids on a lattice above the chains
    s.x.insert(s.x.end(), {2.5 * static_cast<double>(i % 10), 2.5 * static_cast<double>(i / 10), 10.0});
    s.types.push_back(1);
  }
  s.ff.add_bonds(bonds);
  return s;
}
}  // namespace

TEST(BdReproducibility, OneTwoAndThreeThreadsGiveIdenticalTrajectories) {
  const int saved = omp_get_max_threads();
  std::vector<std::vector<double>> results;
  for (int threads : {1, 2, 3}) {
    omp_set_num_threads(threads);
    PolymerSystem s = polymer_system();
    Integrator bd(free_draining(), s.ff, {.dt = 1e-3, .kT = 1.0, .seed = 77}, s.x, s.types, {.skin = 0.3});
    bd.run(200);
    EXPECT_GT(bd.neighbour_rebuilds(), 1u);
    results.emplace_back(bd.positions().begin(), bd.positions().end());
  }
  omp_set_num_threads(saved);
  EXPECT_EQ(results[0], results[1]);  // bitwise
  EXPECT_EQ(results[0], results[2]);
}

TEST(BdReproducibility, RestartFromCheckpointContinuesBitwise) {
  const auto path = std::filesystem::temp_directory_path() / "rpyfmm_bd_restart_test.chk";
  IntegratorOptions o{.dt = 1e-3, .kT = 1.0, .seed = 1234};
  PolymerSystem s = polymer_system();
  Integrator full(free_draining(), s.ff, o, s.x, s.types, {.skin = 0.3});
  full.run(60);
  // Interrupted run: 25 steps, checkpoint, a fresh integrator from the file, 35 more.
  Integrator first(free_draining(), s.ff, o, s.x, s.types, {.skin = 0.3});
  first.run(25);
  Checkpoint c;
  c.step = first.step_count();
  c.seed = o.seed;
  c.dt = o.dt;
  c.positions.assign(first.positions().begin(), first.positions().end());
  c.reference_positions = s.x;
  c.types = s.types;
  c.config = "# test";
  write_checkpoint(path, c);
  const Checkpoint back = read_checkpoint(path);
  std::filesystem::remove(path);
  EXPECT_EQ(back.positions, c.positions);
  EXPECT_EQ(back.config, c.config);
  Integrator second(free_draining(), s.ff, {.dt = back.dt, .kT = 1.0, .seed = back.seed}, back.positions, back.types,
                    {.skin = 0.3}, back.step);
  second.run(35);
  EXPECT_EQ(second.step_count(), 60u);
  EXPECT_EQ(std::vector<double>(second.positions().begin(), second.positions().end()),
            std::vector<double>(full.positions().begin(), full.positions().end()));
}

TEST(BdSafety, BlowUpStopsWithTheLastGoodState) {
  ForceField ff({ParticleType{"A", 1.0, {0, 0, 0}, 0.0}});
  std::vector<double> x{0, 0, 0, 5, 0, 0};
  ff.add_callback([](std::span<const double>, std::uint64_t step, std::span<double> f) {
    if (step == 3) f[4] = 1e9;  // a sudden huge force on particle 1
  });
  Integrator bd(free_draining(), ff, {.dt = 1e-3, .kT = 1.0, .seed = 1}, x, {0, 0});
  bd.run(3);
  const std::vector<double> good(bd.positions().begin(), bd.positions().end());
  try {
    bd.step();
    FAIL() << "blow-up not detected";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::numerical_failure);
    EXPECT_NE(std::string(e.what()).find("blow-up at step 3: particle 1"), std::string::npos) << e.what();
  }
  EXPECT_EQ(std::vector<double>(bd.positions().begin(), bd.positions().end()), good);
  EXPECT_EQ(bd.step_count(), 3u);
}

TEST(BdSafety, BadInputsNameTheProblem) {
  auto make = [](IntegratorOptions o, std::vector<double> x, std::vector<std::uint32_t> t) {
    return Integrator(std::make_unique<FreeDrainingMobility>(), ForceField(), o, std::move(x), std::move(t));
  };
  EXPECT_THROW(make({.dt = -1.0}, {0, 0, 0}, {0}), Error);
  EXPECT_THROW(make({.dt = 0.1, .kT = -1.0}, {0, 0, 0}, {0}), Error);
  EXPECT_THROW(make({.dt = 0.1}, {}, {}), Error);
  EXPECT_THROW(make({.dt = 0.1}, {0, 0}, {0}), Error);
  EXPECT_THROW(make({.dt = 0.1}, {0, 0, 0}, {1}), Error);  // unknown type
  try {
    make({.dt = 0.1}, {0, 0, 0, 1, NAN, 0}, {0, 0});
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("(1, 1) is NaN"), std::string::npos) << e.what();
  }
}

// Sharing M F with the first Krylov product: the count (iterations + 1 products) and the
// result against the unshared path, without and with the block preconditioner (then the block
// pass is M [F, G^T z] and the sample G^{-1} (G M G^T)^{1/2} z).
TEST(BdSampling, DriftAndFirstKrylovProductShareOnePass) {
  bdtest::DenseRpy op;
  op.set_positions(line_of_particles(6, 2.5), 1.0);
  std::vector<double> f(18), z(18), u(18), w(18), w_ref(18), u_ref(18);
  for (std::size_t k = 0; k < 18; ++k) {
    f[k] = std::sin(1.0 + static_cast<double>(k));
    z[k] = std::cos(2.0 * static_cast<double>(k));
  }
  for (auto preconditioner : {rpyfmm::rpy::SqrtPreconditioner::none, rpyfmm::rpy::SqrtPreconditioner::block}) {
    SCOPED_TRACE(to_string(preconditioner));
    const SqrtOptions lanczos{.method = SqrtMethod::lanczos,
                              .tolerance = 1e-10,
                              .preconditioner = preconditioner,
                              .preconditioner_block = 2};  // blocks of 1-2 particles: 6 -> 3 + 3 -> 1 + 2 ...
    const DriftNoiseReport rep = drift_and_noise(op, f, z, u, w, lanczos);
    EXPECT_TRUE(rep.shared_first_product);
    // Issue #8 target: at most (Lanczos iterations + 1) products per step.
    EXPECT_LE(rep.mobility_products, rep.sqrt.iterations + 1);
    EXPECT_GE(rep.sqrt.iterations, 2);
    op.apply(f, u_ref);
    // Reference: the same Lanczos on plain products (DenseRpy's own sqrt is Cholesky).
    if (preconditioner == rpyfmm::rpy::SqrtPreconditioner::none) {
      rpyfmm::rpy::sqrt_apply(op.as_linear_operator(), z, w_ref, 1, lanczos);
    } else {
      EXPECT_EQ(rep.sqrt.preconditioner_blocks, 4u);
      rpyfmm::rpy::BlockPreconditioner(op, 2).sample(op.as_linear_operator(), z, w_ref, 1, lanczos);
    }
    for (std::size_t k = 0; k < 18; ++k) {
      EXPECT_NEAR(u[k], u_ref[k], 1e-14);
      EXPECT_NEAR(w[k], w_ref[k], 1e-8);
    }
  }
}

// The library's direct RPY operator through the factory: the same closed form as
// above (side by side, F perpendicular to the line of centres).
TEST(BdDynamics, FactoryDirectOperatorSedimentsLikeClosedForm) {
  const double a = 1.0, r = 4.0, F = 2.0, dt = 1e-3;
  ForceField ff({ParticleType{"A", a, {0, 0, -F}, 0.0}});
  std::vector<double> x{0, 0, 0, r, 0, 0};
  Integrator bd(make_mobility({.method = MobilityMethod::direct}, 2), ff, {.dt = dt, .kT = 0.0}, x, {0, 0});
  bd.step();
  const double u = F / (6 * pi * a) + F * (1 + 2 * a * a / (3 * r * r)) / (8 * pi * r);
  EXPECT_NEAR(bd.positions()[2], -u * dt, 1e-15);
  EXPECT_NEAR(bd.positions()[5], -u * dt, 1e-15);
}

// Full HI path (direct or FMM RPY + Lanczos with the shared first product) on 1, 2 and 3 threads.
TEST(BdReproducibility, HiPathIdenticalOnOneTwoAndThreeThreads) {
  for (MobilityMethod method : {MobilityMethod::direct, MobilityMethod::fmm}) {
    SCOPED_TRACE(to_string(method));
    const int saved = omp_get_max_threads();
    std::vector<std::vector<double>> results;
    for (int threads : {1, 2, 3}) {
      omp_set_num_threads(threads);
      PolymerSystem s = polymer_system();
      Integrator bd(make_mobility({.method = method}, s.types.size()), s.ff, {.dt = 1e-3, .kT = 1.0, .seed = 5}, s.x,
                    s.types, {.skin = 0.3});
      bd.run(3);
      EXPECT_TRUE(bd.last_report().shared_first_product);
      EXPECT_LE(bd.last_report().mobility_products, bd.last_report().sqrt_iterations + 1);
      results.emplace_back(bd.positions().begin(), bd.positions().end());
    }
    omp_set_num_threads(saved);
    EXPECT_EQ(results[0], results[1]);
    EXPECT_EQ(results[0], results[2]);
  }
}

// PSE steps (fused drift and noise through FFTW's threaded transforms) on 1, 2 and 3 threads: the
// transforms may sum in another order, so the displacements agree to the round-off of the wave
// grids (docs/reproducibility.md): double grids 1e-12 of the displacement over three steps (a
// product agrees to ~1e-15, and the neighbour forces pass it on), float grids 1e-5 (float
// round-off of the wave part, ~1e-7 of M F, likewise passed on).
TEST(BdReproducibility, PseStepsAgreeOnOneTwoAndThreeThreads) {
  const double L = 24.0;
  std::vector<double> x0;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j)
      for (int k = 0; k < 6; ++k)
        x0.insert(x0.end(), {4.0 * i + 0.3 * (j % 2), 4.0 * j + 0.2 * (k % 3), 4.0 * k + 0.1});
  const std::vector<std::uint32_t> types(x0.size() / 3, 0);
  for (const auto& [tolerance, bound] : {std::pair{1e-3, 1e-5}, std::pair{1e-6, 1e-12}}) {
    SCOPED_TRACE(tolerance);
    MobilitySpec spec;
    spec.method = MobilityMethod::pse;
    spec.tolerance = tolerance;
    spec.geometry = rpyfmm::rpy::Geometry::periodic(L);
    const int saved = omp_get_max_threads();
    std::vector<std::vector<double>> moves;
    for (int threads : {1, 2, 3}) {
      omp_set_num_threads(threads);
      Integrator bd(make_mobility(spec, types.size()), ForceField(), {.dt = 0.01, .kT = 1.0, .seed = 9}, x0, types);
      bd.run(3);
      std::vector<double> d(x0.size());
      for (std::size_t i = 0; i < d.size(); ++i) {
        d[i] = bd.positions()[i] - x0[i];
        d[i] -= L * std::round(d[i] / L);
      }
      moves.push_back(d);
    }
    omp_set_num_threads(saved);
    for (std::size_t t = 1; t < moves.size(); ++t) {
      double diff = 0.0, ref = 0.0;
      for (std::size_t i = 0; i < moves[0].size(); ++i) {
        diff += (moves[t][i] - moves[0][i]) * (moves[t][i] - moves[0][i]);
        ref += moves[0][i] * moves[0][i];
      }
      EXPECT_LE(std::sqrt(diff / ref), bound) << t + 1 << " threads";
    }
  }
}

// The FMM operator through the factory: one deterministic step of a 600-sphere
// sedimenting cloud agrees with the direct operator to the requested tolerance
// (relative l2 error of M F, FmmRpy's contract; 1e-4 requested, 1e-4 allowed).
TEST(BdDynamics, FactoryFmmMatchesDirectStep) {
  const std::size_t n = 600;
  std::vector<double> x(3 * n);
  for (std::size_t i = 0; i < n; ++i) {  // jittered cubic lattice, spacing 3a
    x[3 * i] = 3.0 * static_cast<double>(i % 9) + 0.3 * std::sin(1.0 * static_cast<double>(i));
    x[3 * i + 1] = 3.0 * static_cast<double>((i / 9) % 9) + 0.3 * std::cos(2.0 * static_cast<double>(i));
    x[3 * i + 2] = 3.0 * static_cast<double>(i / 81) + 0.3 * std::sin(3.0 * static_cast<double>(i));
  }
  ForceField ff({ParticleType{"A", 1.0, {0.2, 0, -1.0}, 0.0}});
  IntegratorOptions o{.dt = 1e-2, .kT = 0.0};
  const std::vector<std::uint32_t> types(n, 0);
  Integrator fmm(make_mobility({.method = MobilityMethod::fmm, .tolerance = 1e-4}, n), ff, o, x, types);
  Integrator direct(make_mobility({.method = MobilityMethod::direct}, n), ff, o, x, types);
  fmm.step();
  direct.step();
  double err = 0, ref = 0;
  for (std::size_t k = 0; k < 3 * n; ++k) {
    err += std::pow(fmm.positions()[k] - direct.positions()[k], 2);
    ref += std::pow(direct.positions()[k] - x[k], 2);
  }
  EXPECT_LT(std::sqrt(err / ref), 1e-4);
  EXPECT_GT(std::sqrt(err / ref), 0.0);  // really a different (approximate) method
  EXPECT_EQ(make_mobility({.method = MobilityMethod::automatic}, 5000)->name(), "fmm");
  EXPECT_EQ(make_mobility({.method = MobilityMethod::automatic}, 500)->name(), "direct");
}

// "auto" switches exactly at the crossover: the machine default per tolerance (which grows with
// the digits asked for, as the FMM gets dearer and direct sums stay exact) or the caller's value.
TEST(BdMobility, AutoSwitchesToFmmAtTheCrossover) {
  std::size_t previous = 0;
  for (double tol : {1e-3, 1e-6, 1e-9, 1e-12}) {
    const std::size_t c = default_fmm_crossover(tol);
    EXPECT_GT(c, previous) << tol;
    EXPECT_GE(c, 1000u) << tol;  // below ~1000 particles direct sums win at every tolerance measured
    previous = c;
    EXPECT_EQ(make_mobility({.method = MobilityMethod::automatic, .tolerance = tol}, c - 1)->name(), "direct");
    EXPECT_EQ(make_mobility({.method = MobilityMethod::automatic, .tolerance = tol}, c)->name(), "fmm");
  }
  EXPECT_EQ(default_fmm_crossover(1e-4), default_fmm_crossover(1e-6));  // the 6-digit table serves 1e-4

  const MobilitySpec chosen{.method = MobilityMethod::automatic, .fmm_crossover = 100};
  EXPECT_EQ(make_mobility(chosen, 99)->name(), "direct");
  EXPECT_EQ(make_mobility(chosen, 100)->name(), "fmm");
  EXPECT_THROW(default_fmm_crossover(0.0), Error);
}

// PSE: a step is one fused pass, dx = dt (M F + (sqrt(2 kT dt) / dt) M^{1/2} z) with the operator's
// own noise keyed by (seed, step), so that the deterministic and Brownian wave-space parts share
// their FFTs; asking for the split displacements takes the separate drift + sampler path, whose
// drift is exactly dt M F.
TEST(BdDynamics, PseStepFusesDriftAndNoise) {
  MobilitySpec spec;
  spec.method = MobilityMethod::pse;
  spec.tolerance = 1e-4;
  spec.geometry = rpyfmm::rpy::Geometry::periodic(14.0);
  const std::vector<double> x0 = {1.0, 2.0, 3.0, 4.5, 2.0, 3.0, 9.0, 9.0, 1.0, 12.5, 7.0, 6.0};
  const std::vector<double> centres = {0.0, 0.0, 0.0, 7.0, 7.0, 7.0, 7.0, 7.0, 7.0, 7.0, 7.0, 7.0};
  const double k = 0.3, dt = 0.01, kT = 0.5;
  const std::vector<std::uint32_t> types(4, 0);
  IntegratorOptions o{.dt = dt, .kT = kT, .seed = 5};
  Integrator fused(make_mobility(spec, 4), trapped(centres, k), o, x0, types);
  fused.step();  // step 0
  fused.step();  // step 1: the one checked
  // Reference: the same state before step 1, and one apply_with_noise call.
  Integrator first(make_mobility(spec, 4), trapped(centres, k), o, x0, types);
  first.step();
  std::vector<double> x1(first.positions().begin(), first.positions().end()), f(12), v(12);
  for (std::size_t i = 0; i < 12; ++i) f[i] = -k * (x1[i] - centres[i]);
  auto pse = make_mobility(spec, 4);
  pse->set_positions(x1, 1.0);
  const auto& op = dynamic_cast<const rpyfmm::rpy::pse::PseRpy&>(*pse);
  op.apply_with_noise(f, std::sqrt(2.0 * kT * dt) / dt, 5, 1, v);
  for (std::size_t i = 0; i < 12; ++i) EXPECT_NEAR(fused.positions()[i], x1[i] + dt * v[i], 1e-14) << i;
  // Split displacements: the unfused path (drift = dt M F exactly, noise from the sampler).
  IntegratorOptions os = o;
  os.keep_split_displacements = true;
  Integrator split(make_mobility(spec, 4), trapped(centres, k), os, x1, types);
  split.step();
  std::vector<double> u(12);
  pse->apply(f, u);
  for (std::size_t i = 0; i < 12; ++i) EXPECT_NEAR(split.deterministic_displacement()[i], dt * u[i], 1e-15) << i;
  EXPECT_GT(std::abs(split.brownian_displacement()[0]), 0.0);
  // Only the PSE split sampler fuses: generic Lanczos on the PSE operator, or another operator,
  // takes the separate path, and asking such an operator for the fused pass is refused.
  EXPECT_TRUE(fuses_drift_and_noise(*pse, SqrtOptions{}));
  EXPECT_FALSE(fuses_drift_and_noise(*pse, SqrtOptions{.method = SqrtMethod::lanczos}));
  bdtest::DenseRpy dense;
  dense.set_positions(x1, 1.0);
  EXPECT_FALSE(fuses_drift_and_noise(dense, SqrtOptions{}));
  try {
    fused_drift_and_noise(dense, f, 1.0, 5, 1, v, SqrtOptions{});
    ADD_FAILURE() << "fused_drift_and_noise accepted an operator without a fused pass";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::not_supported);
    EXPECT_NE(std::string(e.what()).find("fused"), std::string::npos) << e.what();
  }
}

// Device "cuda" builds the PSE operator on a GPU and nothing else: other methods (and "auto" in
// open geometry) are refused by name, and without a usable device the PSE one is refused too,
// before anything is computed. (A BD step on the GPU against the CPU: tests/pse/test_pse_cuda.cpp.)
TEST(BdMobility, CudaDeviceIsForPseOnly) {
  EXPECT_EQ(compute_device_from_string("cuda"), ComputeDevice::cuda);
  EXPECT_EQ(compute_device_from_string("cpu"), ComputeDevice::cpu);
  EXPECT_THROW(compute_device_from_string("gpu"), Error);
  auto expect_refusal = [](const MobilitySpec& spec, const std::string& needle) {
    try {
      make_mobility(spec, 10);
      ADD_FAILURE() << "accepted device cuda for method " << to_string(spec.method);
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::not_supported);
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  for (MobilityMethod m :
       {MobilityMethod::direct, MobilityMethod::fmm, MobilityMethod::none, MobilityMethod::automatic})
    expect_refusal({.method = m, .device = ComputeDevice::cuda}, "no CUDA version");
  const MobilitySpec pse{
      .method = MobilityMethod::pse, .geometry = rpyfmm::rpy::Geometry::periodic(14.0), .device = ComputeDevice::cuda};
  if (rpyfmm::rpy::pse::PseRpyCuda::device_available()) {
    EXPECT_EQ(make_mobility(pse, 10)->name(), "pse-cuda");
    EXPECT_EQ(make_mobility({.method = MobilityMethod::automatic,
                             .geometry = rpyfmm::rpy::Geometry::periodic(14.0),
                             .device = ComputeDevice::cuda},
                            10)
                  ->name(),
              "pse-cuda");
  } else {
    expect_refusal(pse, "no usable CUDA device");
  }
}
