#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <vector>

#include "rpyfmm/core/atomic_file.hpp"
#include "rpyfmm/core/validate.hpp"

using rpyfmm::Error;
using rpyfmm::ErrorCode;

TEST(Validate, FiniteNamesTheEntry) {
  std::vector<double> v = {0, 1, 2, 3, std::nan(""), 5};
  try {
    rpyfmm::require_finite(v, "f", "positions", 3);
    FAIL() << "no throw";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::invalid_input);
    EXPECT_NE(std::string(e.what()).find("positions entry (1, 1) is NaN"), std::string::npos) << e.what();
  }
  v[4] = std::numeric_limits<double>::infinity();
  EXPECT_THROW(rpyfmm::require_finite(v, "f", "x"), Error);
}

TEST(Validate, PositiveAndRange) {
  EXPECT_NO_THROW(rpyfmm::require_positive(1.0, "f", "radius"));
  EXPECT_THROW(rpyfmm::require_positive(0.0, "f", "radius"), Error);
  EXPECT_THROW(rpyfmm::require_positive(-1.0, "f", "radius"), Error);
  EXPECT_THROW(rpyfmm::require_positive(std::nan(""), "f", "radius"), Error);
  EXPECT_THROW(rpyfmm::require_in_range(2.0, 0.0, 1.0, "f", "tol"), Error);
  EXPECT_NO_THROW(rpyfmm::require_in_range(0.5, 0.0, 1.0, "f", "tol"));
}

TEST(AtomicFile, FailureKeepsOldFile) {
  const auto path = std::filesystem::temp_directory_path() / "rpyfmm_atomic_test.txt";
  rpyfmm::write_file_atomically(path, [](std::ostream& out) { out << "good"; });
  EXPECT_THROW(rpyfmm::write_file_atomically(path,
                                             [](std::ostream& out) {
                                               out << "partial";
                                               throw Error(ErrorCode::io_error, "simulated crash");
                                             }),
               Error);
  std::ifstream in(path);
  std::string s;
  in >> s;
  EXPECT_EQ(s, "good");
  // No temporary left behind.
  for (const auto& entry : std::filesystem::directory_iterator(path.parent_path())) {
    EXPECT_EQ(entry.path().filename().string().find("rpyfmm_atomic_test.txt.tmp"), std::string::npos);
  }
  std::filesystem::remove(path);
}
