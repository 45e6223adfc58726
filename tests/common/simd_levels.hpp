// Tests that compare the kernels of the instruction-set levels (core/include/rpyfmm/core/
// cpu_features.hpp): the levels a machine can run, and a fixture that runs a test at one level.
#pragma once

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "rpyfmm/core/cpu_features.hpp"

namespace rpyfmm::test {

/// Every level, lowest first.
inline std::vector<SimdLevel> all_simd_levels() {
  return {SimdLevel::scalar, SimdLevel::avx2, SimdLevel::avx512};
}

/// The levels this build and CPU can run, lowest first.
inline std::vector<SimdLevel> available_simd_levels() {
  std::vector<SimdLevel> levels;
  for (const SimdLevel level : all_simd_levels())
    if (level <= detected_simd_level()) levels.push_back(level);
  return levels;
}

/// Test names "scalar", "avx2", "avx512" for INSTANTIATE_TEST_SUITE_P.
inline std::string simd_level_param_name(const ::testing::TestParamInfo<SimdLevel>& info) {
  return simd_level_name(info.param);
}

/// A fixture whose tests run at the level GetParam(), skipped where the machine lacks it.
class SimdLevelTest : public ::testing::TestWithParam<SimdLevel> {
 protected:
  void SetUp() override {
    if (GetParam() > detected_simd_level())
      GTEST_SKIP() << "this machine runs at most " << simd_level_name(detected_simd_level());
    previous_ = set_simd_level(GetParam());
  }
  void TearDown() override { set_simd_level(previous_); }

 private:
  SimdLevel previous_ = simd_level();
};

}  // namespace rpyfmm::test
