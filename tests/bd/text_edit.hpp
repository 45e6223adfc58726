// Test helper: variants of a config text, made by replacing one fragment that must be present.
#pragma once

#include <gtest/gtest.h>

#include <string>

namespace bdtest {

/// `s` with the first `from` replaced by `to` (a test failure when `from` is missing).
inline std::string replace(std::string s, const std::string& from, const std::string& to) {
  const auto pos = s.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  return s.replace(pos, from.size(), to);
}

}  // namespace bdtest
