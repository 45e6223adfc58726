// Test helper shared by the suites: expect an rpyfmm::Error with a given code whose message
// names the problem.
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "rpyfmm/core/error.hpp"

namespace rpyfmm_test {

/// Runs `f`, expects rpyfmm::Error with `code` and `needle` in the message.
template <class F>
void expect_error(F&& f, rpyfmm::ErrorCode code, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "expected rpyfmm::Error containing '" << needle << "'";
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

}  // namespace rpyfmm_test
