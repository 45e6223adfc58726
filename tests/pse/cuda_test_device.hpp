// Helpers of the CUDA PSE tests (test_pse_cuda.cpp, test_pse_cuda_rotation.cpp): REQUIRE_DEVICE
// skips cleanly without a usable device (any CUDA error counts as none) unless RPYFMM_EXPECT_CUDA is
// set (scripts/device-suite.sh sets it on a device machine), where a missing device is a failure;
// DeviceVector holds the device arrays of the device-array entry points.
#pragma once

#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"

#ifdef RPYFMM_HAVE_CUDA_PSE
#include <cuda_runtime.h>
#endif

namespace pse_test {

inline bool device_expected() {
  return std::getenv("RPYFMM_EXPECT_CUDA") != nullptr;
}

#ifdef RPYFMM_HAVE_CUDA_PSE
/// A vector of doubles in device memory (freed at scope exit) for the device-array entry points;
/// a failed CUDA call throws, which gtest reports as a failure.
class DeviceVector {
 public:
  explicit DeviceVector(std::size_t n) : n_(n) {
    if (cudaMalloc(reinterpret_cast<void**>(&p_), n * sizeof(double)) != cudaSuccess)
      throw std::runtime_error("cudaMalloc");
  }
  explicit DeviceVector(const std::vector<double>& host) : DeviceVector(host.size()) { upload(host); }
  DeviceVector(const DeviceVector&) = delete;
  DeviceVector& operator=(const DeviceVector&) = delete;
  ~DeviceVector() { cudaFree(p_); }
  void upload(const std::vector<double>& host) {
    if (host.size() != n_ || cudaMemcpy(p_, host.data(), n_ * sizeof(double), cudaMemcpyHostToDevice) != cudaSuccess)
      throw std::runtime_error("upload to the device");
  }
  [[nodiscard]] std::vector<double> host() const {
    std::vector<double> h(n_);
    if (cudaMemcpy(h.data(), p_, n_ * sizeof(double), cudaMemcpyDeviceToHost) != cudaSuccess)
      throw std::runtime_error("download from the device");
    return h;
  }
  double* get() { return p_; }

 private:
  double* p_ = nullptr;
  std::size_t n_;
};
#endif

}  // namespace pse_test

#define REQUIRE_DEVICE()                                                                                 \
  do {                                                                                                   \
    if (!rpyfmm::rpy::pse::PseRpyCuda::device_available()) {                                             \
      if (pse_test::device_expected()) FAIL() << "RPYFMM_EXPECT_CUDA is set, but no usable CUDA device"; \
      GTEST_SKIP() << "no usable CUDA device";                                                           \
    }                                                                                                    \
  } while (false)
