// PseRpyCuda's entry points for a BD step kept on the device (docs/gpu-bd.md, "PSE on the
// device"): apply_with_noise_device is apply_with_noise with device arrays, bit for bit, and
// set_positions_device places the particles as set_positions does (the same wrap into the box, the
// same cell list or the CPU's lists where the device one does not fit), so the products after it
// are bit for bit those after set_positions, and positions() reads the moved positions back.
// Skips without a usable device.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "cuda_test_device.hpp"
#include "ewald_reference.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

using namespace rpyfmm::rpy;
using namespace rpyfmm::rpy::pse;

#ifdef RPYFMM_HAVE_CUDA_PSE
namespace {

constexpr std::size_t kN = 300;
constexpr double kL = 14.0;

PseOptions options() {
  PseOptions o;
  o.tolerance = 1e-4;
  o.wave_precision = WavePrecision::double_precision;
  return o;
}

std::vector<double> forces_of(std::size_t n) {
  auto f = pse_test::random_points(n, {2.0, 2.0, 2.0}, 41);
  for (auto& v : f) v -= 1.0;
  return f;
}

}  // namespace
#endif

// The same forces, positions and key: the same velocities and report, bit for bit.
TEST(PseCudaDeviceStep, ApplyWithNoiseDeviceIsTheHostProduct) {
  REQUIRE_DEVICE();
#ifdef RPYFMM_HAVE_CUDA_PSE
  const auto x = pse_test::random_points(kN, {kL, kL, kL}, 40);
  const auto f = forces_of(kN);
  PseRpyCuda gpu(Geometry::periodic(kL), 0.8, options());
  gpu.set_positions(x, 1.0);
  for (const double scale : {0.0, 3.5}) {
    std::vector<double> u(3 * kN);
    const SqrtReport host = gpu.apply_with_noise(f, scale, 7, 12, u);
    pse_test::DeviceVector df(f), du(3 * kN);
    const SqrtReport device = gpu.apply_with_noise_device(df.get(), scale, 7, 12, du.get());
    EXPECT_EQ(du.host(), u) << "noise scale " << scale;
    EXPECT_EQ(device.iterations, host.iterations);
    EXPECT_EQ(device.operator_applications, host.operator_applications);
  }
  pse_test::DeviceVector df(f);
  EXPECT_THROW(gpu.apply_with_noise_device(df.get(), -1.0, 7, 12, df.get()), rpyfmm::Error);
  EXPECT_THROW(gpu.apply_with_noise_device(nullptr, 1.0, 7, 12, df.get()), rpyfmm::Error);
#endif
}

// Moved on the device (positions up to two boxes away) or on the host: the same wrapped positions,
// the same products, with the device cell list and with the CPU's lists.
TEST(PseCudaDeviceStep, SetPositionsDeviceIsSetPositions) {
  REQUIRE_DEVICE();
#ifdef RPYFMM_HAVE_CUDA_PSE
  const auto x0 = pse_test::random_points(kN, {kL, kL, kL}, 42);
  auto x1 = pse_test::random_points(kN, {kL, kL, kL}, 43);
  for (std::size_t k = 0; k < x1.size(); k += 7) x1[k] += (k % 2 == 0 ? 2.0 : -1.0) * kL;  // other images
  const auto f = forces_of(kN);
  for (const bool device_cells : {true, false}) {
    PseCudaOptions cuda;
    cuda.device_cell_list = device_cells;
    PseRpyCuda host(Geometry::periodic(kL), 0.8, options(), cuda);
    PseRpyCuda moved(Geometry::periodic(kL), 0.8, options(), cuda);
    host.set_positions(x0, 1.0);
    moved.set_positions(x0, 1.0);
    host.set_positions(x1, 1.0);
    pse_test::DeviceVector dx(x1);
    moved.set_positions_device(dx.get());
    EXPECT_EQ(moved.device_cell_list_active(), host.device_cell_list_active());
    if (!device_cells) {
      EXPECT_FALSE(moved.device_cell_list_active());
    }
    const auto a = moved.positions();
    const auto b = host.positions();
    EXPECT_EQ(std::vector<double>(a.begin(), a.end()), std::vector<double>(b.begin(), b.end()));
    std::vector<double> ua(3 * kN), ub(3 * kN);
    moved.apply_with_noise(f, 2.0, 3, 4, ua);
    host.apply_with_noise(f, 2.0, 3, 4, ub);
    EXPECT_EQ(ua, ub) << "device cell list " << device_cells;
  }
#endif
}

// Before any set_positions there is no plan to move: refused.
TEST(PseCudaDeviceStep, SetPositionsDeviceNeedsAPlan) {
  REQUIRE_DEVICE();
#ifdef RPYFMM_HAVE_CUDA_PSE
  PseRpyCuda gpu(Geometry::periodic(kL), 0.8, options());
  pse_test::DeviceVector dx(3 * kN);
  EXPECT_THROW(gpu.set_positions_device(dx.get()), rpyfmm::Error);
#endif
}

// The finiteness check of device arrays (what the Python bindings run on device inputs): finite
// values pass, one NaN or Inf anywhere (first, middle, last entry; beyond one block of threads)
// fails, an empty range passes.
TEST(PseCudaDeviceStep, DeviceValuesFiniteFindsEveryNonFiniteEntry) {
  REQUIRE_DEVICE();
#ifdef RPYFMM_HAVE_CUDA_PSE
  const std::size_t n = 3 * 100003;
  std::vector<double> values = forces_of(n / 3);
  pse_test::DeviceVector d(values);
  EXPECT_TRUE(PseRpyCuda::device_values_finite(d.get(), n));
  EXPECT_TRUE(PseRpyCuda::device_values_finite(d.get(), 0));
  for (const std::size_t at : {std::size_t{0}, n / 2, n - 1}) {
    for (const double bad : {std::numeric_limits<double>::quiet_NaN(), -std::numeric_limits<double>::infinity()}) {
      std::vector<double> broken = values;
      broken[at] = bad;
      d.upload(broken);
      EXPECT_FALSE(PseRpyCuda::device_values_finite(d.get(), n)) << "entry " << at;
      EXPECT_TRUE(PseRpyCuda::device_values_finite(d.get(), at)) << "the entries before " << at;
    }
  }
#endif
}
