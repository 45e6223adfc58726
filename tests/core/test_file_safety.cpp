// The file-output rules (rpyfmm/core/file_safety.hpp, atomic_file.hpp): a planted link at
// a temporary name is never followed, targets that are not regular files are refused and
// left as they were, and outputs that alias an input or another output are detected.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "rpyfmm/core/atomic_file.hpp"
#include "rpyfmm/core/file_safety.hpp"

namespace fs = std::filesystem;
using rpyfmm::Error;

namespace {

class FileSafety : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("rpyfmm_file_safety_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  [[nodiscard]] fs::path path(const std::string& name) const { return dir_ / name; }

  static std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
  }
  static void write(const fs::path& p, const std::string& s) { std::ofstream(p, std::ios::binary) << s; }

  // write_file_atomically(target) must throw an Error naming the target.
  static void expect_refused(const fs::path& target) {
    try {
      rpyfmm::write_file_atomically(target, [](std::ostream& out) { out << "new"; });
      ADD_FAILURE() << "no error for " << target;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(target.string()), std::string::npos) << e.what();
    }
  }

  // Nothing but `expected` in the directory (no temporary left behind).
  void expect_entries(std::vector<std::string> expected) const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(names, expected);
  }

  fs::path dir_;
};

}  // namespace

// The old temporary name, "<out>.tmp.<pid>", planted as a link to a precious file: the write
// must neither follow it nor leave `out` a link.
TEST_F(FileSafety, PlantedLinkAtTheOldTemporaryNameIsNotFollowed) {
  write(path("precious"), "keep me");
  fs::create_symlink(path("precious"), path("out.npy.tmp." + std::to_string(::getpid())));
  rpyfmm::write_file_atomically(path("out.npy"), [](std::ostream& out) { out << "result"; });
  EXPECT_EQ(slurp(path("precious")), "keep me");
  EXPECT_TRUE(fs::is_regular_file(fs::symlink_status(path("out.npy"))));
  EXPECT_EQ(slurp(path("out.npy")), "result");
}

TEST_F(FileSafety, TargetsThatAreNotRegularFilesAreRefusedAndKept) {
  ASSERT_EQ(::mkfifo(path("fifo").c_str(), 0600), 0);
  expect_refused(path("fifo"));
  EXPECT_TRUE(fs::is_fifo(fs::symlink_status(path("fifo"))));

  fs::create_directory(path("sub"));
  expect_refused(path("sub"));
  EXPECT_TRUE(fs::is_directory(path("sub")));

  write(path("real"), "real");
  fs::create_symlink(path("real"), path("link"));
  expect_refused(path("link"));
  EXPECT_TRUE(fs::is_symlink(path("link")));
  EXPECT_EQ(slurp(path("real")), "real");
  expect_entries({"fifo", "sub", "real", "link"});
}

// A device node (as for --out /dev/null run as root), made here so that nothing of the system's
// is at stake; skipped where this process may not create device nodes.
TEST_F(FileSafety, DeviceNodeIsRefusedAndKept) {
  if (::mknod(path("null").c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0) GTEST_SKIP() << "cannot create a device node";
  expect_refused(path("null"));
  EXPECT_TRUE(fs::is_character_file(fs::symlink_status(path("null"))));
}

TEST_F(FileSafety, SameFileSeesThroughSpellingsLinksAndHardLinks) {
  write(path("x.npy"), "x");
  fs::create_hard_link(path("x.npy"), path("hard.npy"));
  fs::create_symlink(path("x.npy"), path("soft.npy"));
  fs::create_directory(path("sub"));
  EXPECT_TRUE(rpyfmm::same_file(path("x.npy"), dir_ / "." / "sub" / ".." / "x.npy"));
  EXPECT_TRUE(rpyfmm::same_file(path("x.npy"), path("hard.npy")));
  EXPECT_TRUE(rpyfmm::same_file(path("x.npy"), path("soft.npy")));
  EXPECT_TRUE(rpyfmm::same_file(path("new.npy"), dir_ / "sub" / ".." / "new.npy"));  // neither exists yet
  EXPECT_FALSE(rpyfmm::same_file(path("x.npy"), path("new.npy")));
  EXPECT_FALSE(rpyfmm::same_file(path("a.npy"), path("b.npy")));
}

TEST_F(FileSafety, OutputsMustDifferFromInputsAndFromEachOther) {
  using rpyfmm::NamedPath;
  write(path("x.npy"), "x");
  const std::vector<NamedPath> inputs{{"--positions", path("x.npy")}, {"--radii", ""}};
  EXPECT_NO_THROW(rpyfmm::require_distinct_files(inputs, std::vector<NamedPath>{{"--out", path("u.npy")}}));
  try {
    rpyfmm::require_distinct_files(inputs, std::vector<NamedPath>{{"--out", dir_ / "." / "x.npy"}});
    ADD_FAILURE() << "output = input accepted";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("--out"), std::string::npos) << m;
    EXPECT_NE(m.find("--positions"), std::string::npos) << m;
    EXPECT_NE(m.find("input"), std::string::npos) << m;
  }
  try {
    rpyfmm::require_distinct_files(inputs,
                                   std::vector<NamedPath>{{"--out", path("u.npy")}, {"--bead-forces", path("u.npy")}});
    ADD_FAILURE() << "two outputs in one file accepted";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("--bead-forces"), std::string::npos) << m;
    EXPECT_NE(m.find("--out"), std::string::npos) << m;
  }
  EXPECT_FALSE(fs::exists(path("u.npy")));
}

TEST(Fnv1a, PiecewiseEqualsWholeAndResumes) {
  rpyfmm::Fnv1a whole, pieces;
  whole.add("hello, world");
  pieces.add("hello, ");
  rpyfmm::Fnv1a resumed(pieces.value());
  pieces.add("world");
  resumed.add("world");
  EXPECT_EQ(whole.value(), pieces.value());
  EXPECT_EQ(whole.value(), resumed.value());
  EXPECT_NE(whole.value(), rpyfmm::Fnv1a{}.value());
}
