// The device tests' guard: skip, saying why, without a usable CUDA device (cudaGetDeviceCount
// failing, e.g. "insufficient driver", no device, no kernel image for it, or a build without CUDA);
// fail instead when RPYFMM_EXPECT_CUDA is set (the GPU machine's check script), so that a broken
// setup cannot pass by skipping, as for the PSE CUDA tests.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>

#include "rpyfmm/bd/device/device_engine.hpp"

namespace device_test {

inline bool device_expected() {
  return std::getenv("RPYFMM_EXPECT_CUDA") != nullptr;
}

}  // namespace device_test

#define REQUIRE_BD_DEVICE()                                                                                 \
  do {                                                                                                      \
    if (!rpyfmm::bd::device::DeviceEngine::device_available()) {                                            \
      if (device_test::device_expected()) FAIL() << "RPYFMM_EXPECT_CUDA is set, but no usable CUDA device"; \
      GTEST_SKIP() << "no usable CUDA device (or a build without CUDA): the device engine is not run";      \
    }                                                                                                       \
  } while (false)
