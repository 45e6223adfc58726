// PSE: CPU and CUDA operators agree for the same positions, forces, seed and step.
// Skips cleanly without a usable device (any CUDA error counts as none), unless
// RPYFMM_EXPECT_CUDA is set (scripts/gpu-check.sh sets it on the GPU machine): then a missing or
// unusable device is a failure, so that a broken setup cannot pass by skipping.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <ostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cuda_test_device.hpp"
#include "ewald_reference.hpp"
#include "rpyfmm/bd/integrator.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

using pse_test::device_expected;
#ifdef RPYFMM_HAVE_CUDA_PSE
using pse_test::DeviceVector;
#endif

// Without a device the operator refuses at construction; with one it constructs (no skip on the
// GPU machine, where gpu-check.sh treats any skipped test as a failure).
TEST(PseCuda, NoDeviceMeansCleanRefusal) {
  if (PseRpyCuda::device_available()) {
    EXPECT_NO_THROW(PseRpyCuda(Geometry::periodic(20.0), 1.0));
    return;
  }
  if (device_expected()) FAIL() << "RPYFMM_EXPECT_CUDA is set, but no usable CUDA device";
  EXPECT_THROW(PseRpyCuda(Geometry::periodic(20.0), 1.0), rpyfmm::Error);
}

TEST(PseCuda, CpuAndGpuAgree) {
  REQUIRE_DEVICE();
  // A cube and a rectangular box with the grids chosen from the tolerance (odd Nz), and one with
  // an explicit even grid, so that the Nyquist planes of all three axes are exercised too.
  struct Box {
    std::array<double, 3> L;
    std::array<int, 3> grid;
  };
  for (const Box& box : {Box{{14.0, 14.0, 14.0}, {0, 0, 0}}, Box{{12.0, 15.0, 10.0}, {0, 0, 0}},
                         Box{{13.0, 13.0, 15.0}, {36, 36, 40}}}) {
    const auto& L = box.L;
    const auto x = pse_test::random_points(500, L, 51);
    auto f = pse_test::random_points(500, {2.0, 2.0, 2.0}, 52);
    for (auto& v : f) v -= 1.0;
    PseOptions o;
    o.tolerance = 1e-6;
    o.xi = 1.0;
    o.grid = box.grid;
    o.wave_precision = WavePrecision::double_precision;  // round-off agreement (float grids: SinglePrecisionGridsAgree)
    PseRpy cpu(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
    PseRpyCuda gpu(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
    cpu.set_positions(x, 1.0);
    gpu.set_positions(x, 1.0);
    EXPECT_EQ(cpu.parameters().grid, gpu.parameters().grid);
    std::vector<double> uc(f.size()), ug(f.size());
    cpu.apply(f, uc);
    gpu.apply(f, ug);
    EXPECT_LT(pse_test::rel_l2(ug, uc), 1e-12);
    // Lanczos on both sides: with the same number of iterations the results differ by
    // round-off; round-off can, rarely, stop one side an iteration earlier, and then they
    // differ by about the Lanczos tolerance (1e-6 here).
    auto sampler_bound = [&](const SqrtReport& c, const SqrtReport& g) {
      return c.iterations == g.iterations ? 1e-10 : 10.0 * o.tolerance;
    };
    const SqrtReport rc = cpu.apply_with_noise(f, 1.3, 17, 5, uc);
    const SqrtReport rg = gpu.apply_with_noise(f, 1.3, 17, 5, ug);
    EXPECT_LT(pse_test::rel_l2(ug, uc), sampler_bound(rc, rg)) << rc.iterations << " vs " << rg.iterations;
    const SqrtReport sc = cpu.sample(17, 6, uc);
    const SqrtReport sg = gpu.sample(17, 6, ug);
    EXPECT_LT(pse_test::rel_l2(ug, uc), sampler_bound(sc, sg)) << sc.iterations << " vs " << sg.iterations;
    // The split M^{1/2} z of a given z (wave noise keyed by the hash of z).
    const SqrtReport qc = cpu.apply_sqrt(f, uc);
    const SqrtReport qg = gpu.apply_sqrt(f, ug);
    EXPECT_LT(pse_test::rel_l2(ug, uc), sampler_bound(qc, qg)) << qc.iterations << " vs " << qg.iterations;
    // Two right-hand sides at once.
    std::vector<double> f2(2 * f.size()), uc2(f2.size()), ug2(f2.size());
    for (std::size_t i = 0; i < f.size(); ++i) {
      f2[i] = f[i];
      f2[f.size() + i] = 0.5 - f[i] * f[i];
    }
    cpu.apply_block(f2, uc2, 2);
    gpu.apply_block(f2, ug2, 2);
    EXPECT_LT(pse_test::rel_l2(ug2, uc2), 1e-12);
#ifdef RPYFMM_HAVE_CUDA_PSE
    // The device-array entry points: the same products without host transfers.
    {
      DeviceVector df(f), du(f.size());
      cpu.apply(f, uc);
      gpu.apply_device(df.get(), du.get());
      EXPECT_LT(pse_test::rel_l2(du.host(), uc), 1e-12) << "apply_device";
      const SqrtReport dc = cpu.sample(23, 2, uc);
      const SqrtReport dg = gpu.sample_device(23, 2, du.get());
      EXPECT_LT(pse_test::rel_l2(du.host(), uc), sampler_bound(dc, dg)) << "sample_device";
    }
    // Stage times from the device's events: every stage of a product and of a sample ran.
    const auto stages = gpu.stage_times();
    for (const char* stage :
         {"transfer", "real_space", "spread", "fft_forward", "scale", "fft_backward", "interpolate", "lanczos"}) {
      EXPECT_TRUE(stages.count(stage) == 1 && stages.at(stage) > 0.0) << stage;
    }
#endif
    // New positions in the same plan (moved particles, other neighbour counts), then fewer particles.
    auto moved = x;
    for (std::size_t i = 0; i < moved.size(); ++i) moved[i] += 0.7 * std::sin(1.3 * double(i));
    cpu.set_positions(moved, 1.0);
    gpu.set_positions(moved, 1.0);
    cpu.apply(f, uc);
    gpu.apply(f, ug);
    EXPECT_LT(pse_test::rel_l2(ug, uc), 1e-12) << "moved";
    const std::vector<double> fewer(x.begin(), x.begin() + 3 * 300), f300(f.begin(), f.begin() + 3 * 300);
    cpu.set_positions(fewer, 1.0);
    gpu.set_positions(fewer, 1.0);
    std::vector<double> uc3(f300.size()), ug3(f300.size());
    cpu.apply(f300, uc3);
    gpu.apply(f300, ug3);
    EXPECT_LT(pse_test::rel_l2(ug3, uc3), 1e-12) << "300 particles";
  }
}

// The device cell list (PseCudaOptions::device_cell_list): the real-space pairs found by a radix
// sort into cells on the GPU give the host lists' products (to round-off: the same pairs, summed
// in another order), in boxes with 3 (16^3, r_cut 4.96) and 5-6 cells per side, with coincident and overlapping
// particles, after moves and with fewer particles; a box side with < 3 cells falls back to the
// host lists.
TEST(PseCuda, DeviceCellListMatchesHostLists) {
  REQUIRE_DEVICE();
  struct Case {
    std::array<double, 3> L;
    std::size_t n;
  };
  for (const Case& c : {Case{{16.0, 16.0, 16.0}, 500}, Case{{30.0, 26.0, 34.0}, 3000}, Case{{12.0, 15.0, 10.0}, 400}}) {
    auto x = pse_test::random_points(c.n, c.L, 81);
    for (int d = 0; d < 3; ++d) x[3 * 7 + d] = x[3 * 3 + d];  // a coincident pair
    auto f = pse_test::random_points(c.n, {2.0, 2.0, 2.0}, 82);
    for (auto& v : f) v -= 1.0;
    PseOptions o;
    o.tolerance = 1e-6;
    o.xi = 1.0;
    o.wave_precision = WavePrecision::double_precision;
    const Geometry g = Geometry::periodic(c.L[0], c.L[1], c.L[2]);
    PseRpy cpu(g, 1.0, o);
    PseRpyCuda lists(g, 1.0, o, PseCudaOptions{.device_cell_list = false});
    PseRpyCuda cells(g, 1.0, o, PseCudaOptions{.device_cell_list = true});
    std::vector<double> uc(f.size()), ul(f.size()), ug(f.size());
    for (int round = 0; round < 2; ++round) {
      if (round == 1) {  // moved particles, then the same plan with fewer of them below
        for (std::size_t i = 0; i < x.size(); ++i) x[i] += 0.9 * std::cos(0.7 * double(i));
      }
      cpu.set_positions(x, 1.0);
      lists.set_positions(x, 1.0);
      cells.set_positions(x, 1.0);
      const double r_cut = cells.parameters().r_cut;
      const bool fits = std::min({c.L[0], c.L[1], c.L[2]}) >= 3.0 * r_cut;
      EXPECT_EQ(cells.device_cell_list_active(), fits) << "r_cut " << r_cut;
      EXPECT_FALSE(lists.device_cell_list_active());
      cpu.apply(f, uc);
      lists.apply(f, ul);
      cells.apply(f, ug);
      EXPECT_LT(pse_test::rel_l2(ug, ul), 1e-12) << c.n << " round " << round;
      EXPECT_LT(pse_test::rel_l2(ug, uc), 1e-12) << c.n << " round " << round;
      const SqrtReport sl = lists.sample(4, 2, ul);
      const SqrtReport sg = cells.sample(4, 2, ug);
      EXPECT_LT(pse_test::rel_l2(ug, ul), sl.iterations == sg.iterations ? 1e-10 : 10.0 * o.tolerance);
    }
    const std::vector<double> fewer(x.begin(), x.begin() + 3 * (c.n / 2)), fh(f.begin(), f.begin() + 3 * (c.n / 2));
    std::vector<double> a(fh.size()), b(fh.size());
    cpu.set_positions(fewer, 1.0);
    cells.set_positions(fewer, 1.0);
    cpu.apply(fh, a);
    cells.apply(fh, b);
    EXPECT_LT(pse_test::rel_l2(b, a), 1e-12) << "fewer particles";
  }
}

// Spreading and interpolation by bins through shared memory (PseCudaOptions::window_bin): the
// same products as one block per particle and as the CPU (double grids: to round-off, 1e-12;
// float grids: float round-off, 1e-5), for bin edges that divide the grid or not, a grid
// no larger than one bin along an axis (the subgrid wraps onto itself: edge 12 on the explicit
// 27x33x12 grid), a rectangular box with an explicit grid, particles piled into a few bins
// (many particles per block), the split sampler (interpolation alone), and with pageable
// instead of page-locked transfers. One instance per (box, precision, edge), so that
// compute-sanitizer can run a single one (scripts/gpu-check.sh).
struct BinBox {
  const char* name;
  std::array<double, 3> L;
  std::array<int, 3> grid;  // {0, 0, 0}: from the tolerance
  std::size_t n;
  bool clustered;
  int largest_edge;  // the largest edge whose 8-byte subgrids fit in an H100's or H200's 227 KiB
};
struct BinCase {
  BinBox box;
  WavePrecision precision;
  int edge;
};

// Test names and ctest's list show the case, not its bytes.
void PrintTo(const BinCase& c, std::ostream* os) {
  *os << c.box.name << (c.precision == WavePrecision::double_precision ? " double" : " float") << " edge " << c.edge;
}

class WindowBins : public testing::TestWithParam<BinCase> {};

TEST_P(WindowBins, MatchPerParticleKernelsAndCpu) {
  REQUIRE_DEVICE();
  const BinCase& p = GetParam();
  const BinBox& c = p.box;
  auto x = pse_test::random_points(c.n, c.L, 91);
  if (c.clustered) {  // most particles within a small cube: a few crowded bins
    for (std::size_t i = 0; i < x.size(); i += 3) {
      if (i % 9 == 0) continue;
      for (int d = 0; d < 3; ++d) x[i + d] = 3.0 + 0.2 * x[i + d];
    }
  }
  auto f = pse_test::random_points(c.n, {2.0, 2.0, 2.0}, 92);
  for (auto& v : f) v -= 1.0;
  PseOptions o;
  o.tolerance = 1e-5;
  o.xi = 1.0;
  o.grid = c.grid;
  o.wave_precision = p.precision;
  const double bound = p.precision == WavePrecision::double_precision ? 1e-12 : 1e-5;
  const Geometry g = Geometry::periodic(c.L[0], c.L[1], c.L[2]);
  PseRpy cpu(g, 1.0, o);
  cpu.set_positions(x, 1.0);
  std::vector<double> uc(f.size()), sc(f.size());
  cpu.apply(f, uc);
  const SqrtReport rc = cpu.sample(5, 1, sc);
  PseRpyCuda per_particle(g, 1.0, o, PseCudaOptions{.window_bin = -1});
  per_particle.set_positions(x, 1.0);
  EXPECT_EQ(per_particle.window_bin_edge(), 0);
  std::vector<double> up(f.size());
  per_particle.apply(f, up);
  EXPECT_LT(pse_test::rel_l2(up, uc), bound);
  for (const bool pinned : {true, false}) {
    PseRpyCuda bins(g, 1.0, o, PseCudaOptions{.window_bin = p.edge, .pinned_transfers = pinned});
    bins.set_positions(x, 1.0);
    ASSERT_EQ(bins.window_bin_edge(), p.edge);
    std::vector<double> ub(f.size()), sb(f.size());
    bins.apply(f, ub);
    EXPECT_LT(pse_test::rel_l2(ub, uc), bound) << "grid " << bins.parameters().grid[0];
    EXPECT_LT(pse_test::rel_l2(ub, up), bound);
    const SqrtReport rb = bins.sample(5, 1, sb);
    EXPECT_LT(pse_test::rel_l2(sb, sc), rb.iterations == rc.iterations ? std::max(bound, 1e-10) : 10.0 * o.tolerance);
  }
}

std::vector<BinCase> bin_cases() {
  std::vector<BinCase> cases;
  // Supports 11, 10 and 11 points: subgrids of (edge + 10)^3 or (edge + 9)^3 points, 8 bytes each.
  // Edge 12 on the rectangular box's 12-point axis: one bin whose subgrid wraps onto itself.
  for (const BinBox& b : {BinBox{"cube", {14.0, 14.0, 14.0}, {0, 0, 0}, 600, false, 10},
                          BinBox{"rectangular", {12.0, 15.0, 10.0}, {27, 33, 12}, 500, false, 12},
                          BinBox{"clustered", {16.0, 16.0, 16.0}, {0, 0, 0}, 800, true, 10}}) {
    for (const int edge : {4, 5, 8, b.largest_edge}) {
      cases.push_back({b, WavePrecision::double_precision, edge});
      cases.push_back({b, WavePrecision::single_precision, edge});
    }
  }
  return cases;
}

INSTANTIATE_TEST_SUITE_P(PseCuda, WindowBins, testing::ValuesIn(bin_cases()),
                         [](const testing::TestParamInfo<BinCase>& param) {
                           const BinCase& c = param.param;
                           return std::string(c.box.name) +
                                  (c.precision == WavePrecision::double_precision ? "_double" : "_float") + "_edge" +
                                  std::to_string(c.edge);
                         });

// Bin edges out of range, or whose subgrid exceeds the device's shared memory, are refused.
TEST(PseCuda, BadWindowBinsAreRefused) {
  REQUIRE_DEVICE();
  EXPECT_THROW(PseRpyCuda(Geometry::periodic(20.0), 1.0, {}, PseCudaOptions{.window_bin = 65}), rpyfmm::Error);
  EXPECT_THROW(PseRpyCuda(Geometry::periodic(20.0), 1.0, {}, PseCudaOptions{.window_bin = -2}), rpyfmm::Error);
  // An edge whose subgrid cannot fit in shared memory: refused at set_positions, with a message.
  PseOptions o;
  o.tolerance = 1e-6;
  o.wave_precision = WavePrecision::double_precision;
  PseRpyCuda too_big(Geometry::periodic(80.0), 1.0, o, PseCudaOptions{.window_bin = 64});
  const auto x = pse_test::random_points(50, {80.0, 80.0, 80.0}, 93);
  try {
    too_big.set_positions(x, 1.0);
    ADD_FAILURE() << "window_bin 64 was accepted";
  } catch (const rpyfmm::Error& e) {
    EXPECT_NE(std::string(e.what()).find("window_bin"), std::string::npos) << e.what();
  }
}

// Single-precision wave grids (the automatic choice for tolerances >= 1e-5, on both back ends):
// R2C / C2R transforms on the GPU. GPU and CPU then agree to float round-off
// (~1e-7 relative; bound 1e-5), and both stay within that of the double-precision product.
TEST(PseCuda, SinglePrecisionGridsAgree) {
  REQUIRE_DEVICE();
  const std::array<double, 3> L{12.0, 15.0, 10.0};
  const auto x = pse_test::random_points(400, L, 71);
  auto f = pse_test::random_points(400, {2.0, 2.0, 2.0}, 72);
  for (auto& v : f) v -= 1.0;
  PseOptions o;
  o.tolerance = 1e-4;
  PseRpy cpu(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
  PseRpyCuda gpu(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
  cpu.set_positions(x, 1.0);
  gpu.set_positions(x, 1.0);
  ASSERT_TRUE(cpu.parameters().wave_single);
  ASSERT_TRUE(gpu.parameters().wave_single);
  std::vector<double> uc(f.size()), ug(f.size()), ud(f.size());
  cpu.apply(f, uc);
  gpu.apply(f, ug);
  EXPECT_LT(pse_test::rel_l2(ug, uc), 1e-5);
  PseOptions od = o;
  od.wave_precision = WavePrecision::double_precision;
  PseRpyCuda gpu_double(Geometry::periodic(L[0], L[1], L[2]), 1.0, od);
  gpu_double.set_positions(x, 1.0);
  gpu_double.apply(f, ud);
  EXPECT_LT(pse_test::rel_l2(ug, ud), 1e-5);
  EXPECT_GT(pse_test::rel_l2(ug, ud), 0.0);  // the float path did run
  const SqrtReport rc = cpu.apply_with_noise(f, 1.1, 3, 4, uc);
  const SqrtReport rg = gpu.apply_with_noise(f, 1.1, 3, 4, ug);
  EXPECT_LT(pse_test::rel_l2(ug, uc), rc.iterations == rg.iterations ? 1e-5 : 10.0 * o.tolerance);
}

// The BD engine on the GPU (mobility device "cuda"): a few steps of sedimenting, diffusing
// particles give the CPU engine's trajectory (double-precision wave grids on both), to the
// round-off of the fixed-point spreading and the Lanczos tolerance (PSE tolerance 1e-7: the sampler's Lanczos
// stops at the same iteration or one apart, ~1e-7 of a displacement).
TEST(PseCuda, BdStepsOnTheGpuMatchTheCpu) {
  REQUIRE_DEVICE();
  using namespace rpyfmm::bd;
  const std::array<double, 3> L{14.0, 15.0, 13.0};
  const std::size_t n = 300;
  const auto x0 = pse_test::random_points(n, L, 61);
  MobilitySpec spec{.method = MobilityMethod::pse,
                    .tolerance = 1e-7,
                    .geometry = Geometry::periodic(L[0], L[1], L[2]),
                    .wave_precision = WavePrecision::double_precision};
  auto engine = [&](ComputeDevice device) {
    spec.device = device;
    ForceField ff;
    ff.add_callback([](std::span<const double>, std::uint64_t, std::span<double> f) {
      for (std::size_t i = 2; i < f.size(); i += 3) f[i] -= 1.0;  // gravity along -z
    });
    auto bd = std::make_unique<Integrator>(make_mobility(spec, n), std::move(ff),
                                           IntegratorOptions{.dt = 0.01, .kT = 1.0, .seed = 9}, x0,
                                           std::vector<std::uint32_t>(n, 0));
    return bd;
  };
  auto cpu = engine(ComputeDevice::cpu);
  auto gpu = engine(ComputeDevice::cuda);
  cpu->run(3);
  gpu->run(3);
  std::vector<double> dc(3 * n), dg(3 * n);
  for (std::size_t i = 0; i < 3 * n; ++i) {
    dc[i] = cpu->positions()[i] - x0[i];
    dg[i] = gpu->positions()[i] - x0[i];
  }
  EXPECT_LT(pse_test::rel_l2(dg, dc), 1e-6);
}

// One configuration, one answer (docs/reproducibility.md): on the device the k-th product equals
// the first bit for bit, whatever was called in between, for float and double grids, by bins and
// per particle. Bit for bit because every stage sums in a fixed order (the real-space rows, the
// interpolation's block sums and shuffles, the Lanczos inner products) or in integers (the
// spreading's 64-bit fixed-point atomics), and cuFFT runs the same plan on the same data.
TEST(PseCuda, ProductsDoNotDependOnCallHistory) {
  REQUIRE_DEVICE();
  const std::array<double, 3> L{18.0, 20.0, 19.0};
  const std::size_t n = 3000;
  const auto x = pse_test::random_points(n, L, 81);
  auto f = pse_test::random_points(n, {2.0, 2.0, 2.0}, 82);
  for (auto& v : f) v -= 1.0;
  const auto z = pse_test::random_points(n, {1.0, 1.0, 1.0}, 83);
  for (const WavePrecision precision : {WavePrecision::single_precision, WavePrecision::double_precision}) {
    for (const int bin : {-1, 6}) {
      SCOPED_TRACE(std::string(precision == WavePrecision::single_precision ? "float" : "double") + " grids, bin " +
                   std::to_string(bin));
      PseOptions o;
      o.tolerance = precision == WavePrecision::single_precision ? 1e-4 : 1e-7;
      o.wave_precision = precision;
      PseRpyCuda gpu(Geometry::periodic(L[0], L[1], L[2]), 1.0, o, PseCudaOptions{.window_bin = bin});
      gpu.set_positions(x, 1.0);
      ASSERT_EQ(gpu.window_bin_edge(), bin < 0 ? 0 : bin);
      std::vector<double> first(3 * n), again(3 * n), w(3 * n), block(6 * n);
      gpu.apply(f, first);
      std::vector<std::function<void()>> calls = {
          [&] { gpu.apply_sqrt(z, w); },
          [&] { gpu.sample(3, 4, w); },
          [&] { gpu.apply_with_noise(f, 1.0, 3, 5, w); },
          [&] {
            std::vector<double> two(f);
            two.insert(two.end(), z.begin(), z.end());
            gpu.apply_block(two, block, 2);
          },
          [&] { gpu.set_positions(x, 1.0); },
          [&] { gpu.apply(z, w); },
      };
      for (std::size_t k = 0; k < calls.size(); ++k) {
        calls[k]();
        gpu.apply(f, again);
        EXPECT_EQ(again, first) << "after call " << k;
      }
      // Samples and noisy products repeat bit for bit too.
      std::vector<double> s1(3 * n), s2(3 * n);
      gpu.sample(7, 2, s1);
      gpu.apply(z, w);
      gpu.sample(7, 2, s2);
      EXPECT_EQ(s1, s2) << "sample";
      gpu.apply_with_noise(f, 0.5, 7, 3, s1);
      gpu.apply_sqrt(z, w);
      gpu.apply_with_noise(f, 0.5, 7, 3, s2);
      EXPECT_EQ(s1, s2) << "apply_with_noise";
#ifdef RPYFMM_HAVE_CUDA_PSE
      // The device-array product equals the host-array one bit for bit.
      DeviceVector df(f), du(f.size());
      gpu.apply_device(df.get(), du.get());
      EXPECT_EQ(du.host(), first) << "apply_device";
#endif
    }
  }
}

// Non-finite forces reach the velocities as NaN (the fixed-point spreading cannot hold them, so
// the grid is set to NaN instead of silently dropping them); finite forces after them give the
// product of a fresh operator again.
TEST(PseCuda, NonFiniteDeviceForcesGiveNaN) {
  REQUIRE_DEVICE();
#ifdef RPYFMM_HAVE_CUDA_PSE
  const std::array<double, 3> L{12.0, 12.0, 12.0};
  const std::size_t n = 200;
  const auto x = pse_test::random_points(n, L, 91);
  auto f = pse_test::random_points(n, {2.0, 2.0, 2.0}, 92);
  for (auto& v : f) v -= 1.0;
  PseOptions o;
  o.tolerance = 1e-4;
  PseRpyCuda gpu(Geometry::periodic(L[0], L[1], L[2]), 1.0, o);
  gpu.set_positions(x, 1.0);
  std::vector<double> u0(3 * n), u(3 * n);
  gpu.apply(f, u0);
  auto bad = f;
  bad[7] = std::numeric_limits<double>::infinity();
  DeviceVector df(bad), du(f.size());
  gpu.apply_device(df.get(), du.get());
  u = du.host();
  EXPECT_TRUE(std::any_of(u.begin(), u.end(), [](double v) { return std::isnan(v); }));
  df.upload(f);
  gpu.apply_device(df.get(), du.get());
  EXPECT_EQ(du.host(), u0);
#endif
}
