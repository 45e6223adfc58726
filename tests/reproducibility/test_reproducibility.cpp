// Every operator is a function of its configuration alone (docs/reproducibility.md):
//  - the k-th product equals the first bit for bit, whatever was called in between (square
//    roots, samples, block products, set_positions to the same positions);
//  - the thread count does not change results: bit for bit for direct sums, the FMM, the
//    samplers and rigid bodies with 1, 2 and 3 threads; paths through FFTW's threaded
//    transforms (PSE) agree to 1e-14 relative (double grids; float grids to float round-off).
// These run at every instruction-set level the machine has (SimdLevelTest), and CI runs the
// whole suite again with RPYFMM_SIMD=avx2 and =scalar.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <vector>

#include "rpyfmm/fmm/laplace_fmm.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/free_draining.hpp"
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"
#include "simd_levels.hpp"

namespace {

using rpyfmm::rpy::Geometry;
using rpyfmm::rpy::MobilityOperator;

std::vector<double> uniform(std::size_t n, double lo, double hi, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<double> v(n);
  for (auto& x : v) x = u(rng);
  return v;
}

/// Non-overlapping-ish random spheres in a box of edge L (overlaps allowed: every operator
/// handles them).
std::vector<double> suspension(std::size_t n, double L, unsigned seed) {
  return uniform(3 * n, 0.0, L, seed);
}

/// Runs f with `threads` OpenMP threads and restores the previous count.
template <class F>
auto with_threads(int threads, F&& f) {
  const int saved = omp_get_max_threads();
  omp_set_num_threads(threads);
  auto result = f();
  omp_set_num_threads(saved);
  return result;
}

double rel_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0.0, r = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    d += (a[i] - b[i]) * (a[i] - b[i]);
    r += b[i] * b[i];
  }
  return std::sqrt(d / r);
}

struct OperatorCase {
  const char* name;
  std::function<std::unique_ptr<MobilityOperator>()> make;
  std::size_t n;
  double box;                 // positions in [0, box)^3
  double thread_bound = 0.0;  // 0: bit for bit across thread counts
};

std::vector<OperatorCase> operator_cases() {
  using rpyfmm::rpy::pse::PseOptions;
  using rpyfmm::rpy::pse::PseRpy;
  using rpyfmm::rpy::pse::WavePrecision;
  auto pse = [](double tolerance, WavePrecision precision) {
    return [=]() -> std::unique_ptr<MobilityOperator> {
      PseOptions o;
      o.tolerance = tolerance;
      o.wave_precision = precision;
      return std::make_unique<PseRpy>(Geometry::periodic(32.0, 30.0, 34.0), 1.0, o);
    };
  };
  return {
      {"direct", [] { return std::make_unique<rpyfmm::rpy::DirectRpy>(); }, 400, 35.0},
      {"fmm_1e-3",
       [] { return std::make_unique<rpyfmm::rpy::FmmRpy>(Geometry::open(), 1.0, rpyfmm::rpy::FmmRpyOptions{1e-3}); },
       2000, 50.0},
      {"fmm_1e-6",
       [] { return std::make_unique<rpyfmm::rpy::FmmRpy>(Geometry::open(), 1.0, rpyfmm::rpy::FmmRpyOptions{1e-6}); },
       2000, 50.0},
      {"free_draining", [] { return std::make_unique<rpyfmm::rpy::FreeDrainingMobility>(); }, 500, 20.0},
      // Float grids and a float pair cache (the default at tolerance >= 1e-5): FFTW's threaded
      // float transforms are bound by float round-off of the wave part (~1e-7 of |M F|).
      {"pse_1e-3_float", pse(1e-3, WavePrecision::automatic), 1200, 30.0, 1e-6},
      // Double grids: FFTW's threaded transforms round differently, to double round-off.
      {"pse_1e-6_double", pse(1e-6, WavePrecision::double_precision), 1200, 30.0, 1e-14},
      // PSE with open boundaries: the same wave space on a box that follows the particles.
      {"pse_open_1e-3_float", [] { return std::make_unique<rpyfmm::rpy::pse::OpenPseRpy>(1.0); }, 1200, 30.0, 1e-6},
  };
}

class Reproducible : public rpyfmm::test::SimdLevelTest {};
INSTANTIATE_TEST_SUITE_P(Levels, Reproducible, ::testing::ValuesIn(rpyfmm::test::all_simd_levels()),
                         rpyfmm::test::simd_level_param_name);

TEST_P(Reproducible, ProductsDoNotDependOnCallHistory) {
  for (const auto& c : operator_cases()) {
    SCOPED_TRACE(c.name);
    const auto op = c.make();
    const auto x = suspension(c.n, c.box, 11);
    const auto f = uniform(3 * c.n, -1.0, 1.0, 12);
    const auto z = uniform(3 * c.n, -1.0, 1.0, 13);
    std::vector<double> first(3 * c.n), again(3 * c.n), w(3 * c.n), block(6 * c.n);
    op->set_positions(x, 1.0);
    op->apply(f, first);
    // Every other kind of call, then the product again.
    std::vector<std::function<void()>> calls = {
        [&] { op->apply_sqrt(z, w); },
        [&] {
          op->apply_sqrt(
              z, w,
              {.method = rpyfmm::rpy::SqrtMethod::lanczos, .preconditioner = rpyfmm::rpy::SqrtPreconditioner::block});
        },
        [&] {
          std::vector<double> two(f);
          two.insert(two.end(), z.begin(), z.end());
          op->apply_block(two, block, 2);
        },
        [&] { op->set_positions(x, 1.0); },
        [&] { op->apply(z, w); },
    };
    if (auto* pse = dynamic_cast<const rpyfmm::rpy::pse::PseOperator*>(op.get())) {
      calls.push_back([&, pse] { pse->sample(3, 4, w); });
      calls.push_back([&, pse] { pse->apply_with_noise(f, 1.0, 3, 5, w); });
    }
    for (std::size_t k = 0; k < calls.size(); ++k) {
      calls[k]();
      op->apply(f, again);
      EXPECT_EQ(again, first) << "after call " << k;
    }
  }
}

TEST_P(Reproducible, BlockColumnsDoNotDependOnTheOtherColumns) {
  // A right-hand side of a block is scaled by its own power of two, as apply() scales it alone
  // (rpy/src/mobility.cpp): loads near 1e-298 beside loads near 1e298 keep their digits. Columns
  // 2^-990 f, f and 2^990 f: each column's velocities are those of its block with ordinary
  // companions (2^-990 f beside f and f) times its power of two, bit for bit, on every operator
  // (the scaling is exact and every do_apply treats its columns alike).
  for (const auto& c : operator_cases()) {
    SCOPED_TRACE(c.name);
    const auto op = c.make();
    op->set_positions(suspension(c.n, c.box, 51), 1.0);
    const auto f = uniform(3 * c.n, -1.0, 1.0, 52);
    const std::size_t m = f.size();
    auto block_of = [&](std::initializer_list<int> exponents) {
      std::vector<double> forces, velocities(m * exponents.size());
      for (const int e : exponents)
        for (double v : f) forces.push_back(std::ldexp(v, e));
      op->apply_block(forces, velocities, exponents.size());
      return velocities;
    };
    const auto ordinary = block_of({0, 0, 0});
    const auto extreme = block_of({-990, 0, 990});
    for (std::size_t j = 0; j < 3; ++j) {
      const int e = j == 0 ? -990 : (j == 1 ? 0 : 990);
      std::size_t differing = 0;
      for (std::size_t i = 0; i < m; ++i) differing += extreme[j * m + i] != std::ldexp(ordinary[j * m + i], e) ? 1 : 0;
      EXPECT_EQ(differing, 0u) << "column " << j << " (2^" << e << " f)";
    }
  }
}

TEST_P(Reproducible, ProductsDoNotDependOnThreadCount) {
  for (const auto& c : operator_cases()) {
    SCOPED_TRACE(c.name);
    const auto x = suspension(c.n, c.box, 21);
    const auto f = uniform(3 * c.n, -1.0, 1.0, 22);
    auto product = [&](int threads) {
      return with_threads(threads, [&] {
        const auto op = c.make();
        op->set_positions(x, 1.0);
        std::vector<double> u(3 * c.n);
        op->apply(f, u);
        return u;
      });
    };
    const auto one = product(1);
    for (const int threads : {2, 3}) {
      const auto u = product(threads);
      if (c.thread_bound == 0.0) {
        EXPECT_EQ(u, one) << threads << " threads";
      } else {
        EXPECT_LE(rel_diff(u, one), c.thread_bound) << threads << " threads";
      }
    }
  }
}

TEST_P(Reproducible, SamplesDoNotDependOnThreadCount) {
  // Lanczos (plain and block-preconditioned) on the direct and FMM operators: the Krylov
  // recurrences' dot products are summed in a fixed order, so bit for bit.
  for (const auto& c : operator_cases()) {
    if (c.thread_bound != 0.0) continue;  // PSE: its sampler runs through FFTW (the product test)
    SCOPED_TRACE(c.name);
    const auto x = suspension(c.n, c.box, 31);
    const auto z = uniform(3 * c.n, -1.0, 1.0, 32);
    for (const auto preconditioner : {rpyfmm::rpy::SqrtPreconditioner::none, rpyfmm::rpy::SqrtPreconditioner::block}) {
      auto sample = [&](int threads) {
        return with_threads(threads, [&] {
          const auto op = c.make();
          op->set_positions(x, 1.0);
          std::vector<double> w(3 * c.n);
          op->apply_sqrt(z, w, {.preconditioner = preconditioner});
          return w;
        });
      };
      const auto one = sample(1);
      for (const int threads : {2, 3}) EXPECT_EQ(sample(threads), one) << threads << " threads";
    }
  }
}

TEST_P(Reproducible, LaplaceFmmDoesNotDependOnCallHistoryOrThreads) {
  const std::size_t n = 6000;
  const auto x = uniform(3 * n, -1.0, 1.0, 41);
  const auto q = uniform(2 * n, -1.0, 1.0, 42);
  for (const double eps : {1e-3, 1e-6, 1e-9}) {
    SCOPED_TRACE(eps);
    auto evaluate = [&](int threads, bool detour) {
      return with_threads(threads, [&] {
        rpyfmm::fmm::FmmOptions o;
        o.tolerance = eps;
        rpyfmm::fmm::LaplaceFmm fmm(o);
        fmm.set_points(x);
        std::vector<double> out(n * 10), other(2 * n * 10);
        if (detour) {  // another density count and other outputs first
          fmm.evaluate(q, 2, rpyfmm::fmm::all_outputs, other);
          fmm.evaluate(std::span<const double>(q.data() + n, n), 1, 1u, out);
          fmm.set_points(x);
        }
        fmm.evaluate(std::span<const double>(q.data(), n), 1, rpyfmm::fmm::all_outputs, out);
        return out;
      });
    };
    const auto one = evaluate(1, false);
    EXPECT_EQ(evaluate(1, true), one) << "after other evaluations";
    for (const int threads : {2, 3}) EXPECT_EQ(evaluate(threads, threads == 3), one) << threads << " threads";
  }
}

TEST_P(Reproducible, RigidBodiesDoNotDependOnCallHistoryOrThreads) {
  // 40 bodies of 12 beads (a ring of three squares), FMM beads at 1e-6; GMRES iterates are
  // computed in a fixed order, so bit for bit.
  const std::size_t bodies = 40, per = 12;
  std::vector<double> beads;
  std::vector<std::size_t> offsets = {0};
  const auto centres = uniform(3 * bodies, 0.0, 30.0, 51);
  for (std::size_t b = 0; b < bodies; ++b) {
    for (std::size_t k = 0; k < per; ++k) {
      const double phi = 2.0 * 3.141592653589793 * static_cast<double>(k) / per;
      beads.insert(beads.end(), {centres[3 * b] + 1.5 * std::cos(phi), centres[3 * b + 1] + 1.5 * std::sin(phi),
                                 centres[3 * b + 2] + 0.5 * static_cast<double>(k % 3)});
    }
    offsets.push_back(beads.size() / 3);
  }
  const auto ft = uniform(6 * bodies, -1.0, 1.0, 52);
  auto solve = [&](int threads, bool twice) {
    return with_threads(threads, [&] {
      rpyfmm::rpy::FmmRpy beads_op(Geometry::open(), 1.0, {.tolerance = 1e-6});
      rpyfmm::rpy::RigidBodies rigid(beads_op, {.tolerance = 1e-6});
      rigid.set_configuration(beads, 0.5, offsets);
      std::vector<double> v(6 * bodies);
      rigid.apply(ft, v);
      if (twice) {
        std::vector<double> other(6 * bodies);
        rigid.apply(std::vector<double>(ft.rbegin(), ft.rend()), other);
        rigid.apply(ft, v);
      }
      return v;
    });
  };
  const auto one = solve(1, false);
  EXPECT_EQ(solve(1, true), one) << "after another solve";
  for (const int threads : {2, 3}) EXPECT_EQ(solve(threads, false), one) << threads << " threads";
}

}  // namespace
