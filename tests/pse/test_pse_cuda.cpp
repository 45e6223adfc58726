// PSE: CPU and CUDA operators agree for the same positions, forces, seed and step.
// Skips cleanly without a usable device (any CUDA error counts as none).
#include <gtest/gtest.h>

#include "ewald_reference.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

TEST(PseCuda, NoDeviceMeansCleanRefusal) {
  if (PseRpyCuda::device_available()) GTEST_SKIP() << "a device is present";
  EXPECT_THROW(PseRpyCuda(Geometry::periodic(20.0), 1.0), rpyfmm::Error);
}

TEST(PseCuda, CpuAndGpuAgree) {
  if (!PseRpyCuda::device_available()) GTEST_SKIP() << "no usable CUDA device";
  for (const std::array<double, 3> L : {std::array<double, 3>{14.0, 14.0, 14.0}, {12.0, 15.0, 10.0}}) {
    const auto x = pse_test::random_points(500, L, 51);
    auto f = pse_test::random_points(500, {2.0, 2.0, 2.0}, 52);
    for (auto& v : f) v -= 1.0;
    PseOptions o;
    o.tolerance = 1e-6;
    o.xi = 1.0;
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
  }
}
