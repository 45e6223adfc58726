// Test fixture for whole BD runs and their files: a scratch directory per test (removed after
// it), runs into a directory, file contents, and errors that must name the problem.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <string>

#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/core/error.hpp"

namespace bdtest {

class RunFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           ("rpyfmm_" + std::string(test->test_suite_name()) + "_" + std::to_string(::getpid()) + "_" + test->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  static std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  /// Number of entries in a directory (a refused or finished run leaves no temporaries).
  static std::size_t entries(const std::filesystem::path& dir) {
    return static_cast<std::size_t>(
        std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator{}));
  }
  /// Runs `config` into `out`, `steps` steps.
  static rpyfmm::bd::RunSummary run(const rpyfmm::bd::RunConfig& config, const std::filesystem::path& out,
                                    std::uint64_t steps) {
    rpyfmm::bd::RunOptions o;
    o.out_dir = out;
    o.steps = steps;
    return rpyfmm::bd::run_bd(config, o);
  }
  /// `f()` must throw an rpyfmm::Error whose message contains every needle.
  template <class F>
  static void expect_error(F f, std::initializer_list<std::string> needles) {
    try {
      f();
      ADD_FAILURE() << "no error";
    } catch (const rpyfmm::Error& e) {
      for (const auto& n : needles) EXPECT_NE(std::string(e.what()).find(n), std::string::npos) << e.what();
    }
  }

  std::filesystem::path dir_;
};

}  // namespace bdtest
