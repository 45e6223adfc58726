// `rpyfmm rigid --body-sizes` with entries too large to be counts: each must end with exit status
// 2 and one line naming the limit (an entry of 1e30 was called "not a whole number"), and no
// output file.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

namespace {

namespace fs = std::filesystem;

class HostileBodySizes : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("rpyfmm_hostile_body_sizes_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    write("x.txt", "0 0 0\n1 0 0\n0 1 0\n");
    write("ft.txt", "1 0 0 0 0 0\n");
  }
  void TearDown() override { fs::remove_all(dir_); }
  [[nodiscard]] std::string path(const std::string& name) const { return (dir_ / name).string(); }
  void write(const std::string& name, const std::string& text) const { std::ofstream(path(name)) << text; }

  // Runs `rigid` with the given body sizes; returns the exit status and stderr.
  std::pair<int, std::string> run(const std::string& sizes) const {
    write("sizes.txt", sizes);
    const std::string err = path("stderr.txt");
    const std::string cmd = "timeout 60 '" + std::string(RPYFMM_CLI_PATH) + "' rigid --positions " + path("x.txt") +
                            " --radius 0.3 --forces " + path("ft.txt") + " --body-sizes " + path("sizes.txt") +
                            " --out " + path("uw.npy") + " >/dev/null 2>'" + err + "'";
    const int status = std::system(cmd.c_str());
    std::ifstream in(err);
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, std::string(std::istreambuf_iterator<char>(in), {})};
  }

  void expect_refused(const std::string& sizes, const std::string& needle) const {
    const auto [code, err] = run(sizes);
    EXPECT_EQ(code, 2) << sizes << ": " << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    EXPECT_NE(err.find(needle), std::string::npos) << sizes << ": " << err;
    EXPECT_FALSE(fs::exists(path("uw.npy")));
  }

  fs::path dir_;
};

TEST_F(HostileBodySizes, TooLargeEntriesNameTheLimit) {
  expect_refused("1e30\n", "entry 0 (1e+30) is too large: a body holds at most 2^53 = 9007199254740992 beads");
  expect_refused("3 1e16\n", "entry 1 (1e+16) is too large");
  // Whole entries within the limit whose sum passes it: named as a sum, never wrapped.
  expect_refused("9007199254740992 9007199254740992\n", "entries 0 to 1 add up to more than 2^53");
  expect_refused("2.5\n", "entry 0 (2.5) is not a whole number of beads >= 1");
}

}  // namespace
