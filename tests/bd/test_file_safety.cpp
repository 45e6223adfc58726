// The files of a BD run (docs/safety-files.md): two outputs never share a file, no output
// replaces an input, a restart touches only the files its checkpoint wrote, a run refused at
// start-up leaves nothing behind, and checkpoint errors name the file.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/core/error.hpp"
#include "run_files_fixture.hpp"

namespace fs = std::filesystem;
using namespace rpyfmm::bd;
using rpyfmm::Error;

namespace {

/// Run options that only set the total step count.
RunOptions steps_to(std::uint64_t steps) {
  RunOptions o;
  o.steps = steps;
  return o;
}

const std::string kRun = R"(
[system]
geometry = "open"
[[types]]
name = "A"
radius = 1.0
[particles]
source = "random"
count = 30
volume_fraction = 0.05
[[pair]]
types = ["A", "A"]
kind = "wca"
[integrator]
dt = 0.001
steps = 20
[mobility]
method = "none"
)";

// `text` with the noise seed set to `seed`.
std::string replace_seed(std::string text, int seed) {
  return text.replace(text.find("[integrator]\n"), 13, "[integrator]\nseed = " + std::to_string(seed) + "\n");
}

using BdFiles = bdtest::RunFiles;

}  // namespace

TEST_F(BdFiles, TwoOutputsWithOneNameAreRefused) {
  expect_error([] { (void)parse_config(kRun + "[output]\nlog = \"trajectory.xyz\"\n", "t"); },
               {"output.trajectory", "output.log", "trajectory.xyz"});
  expect_error([] { (void)parse_config(kRun + "[output]\ncheckpoint = \"trajectory.xyz\"\n", "t"); },
               {"output.trajectory", "output.checkpoint"});
  expect_error([] { (void)parse_config(kRun + "[output]\ncheckpoint = \"log.csv\"\n", "t"); },
               {"output.log", "output.checkpoint"});
  // A disabled output writes nothing, so its name may repeat another's.
  EXPECT_NO_THROW((void)parse_config(kRun + "[output]\nlog = \"trajectory.xyz\"\nlog_every = 0\n", "t"));
}

// The particle file and the config file are inputs: naming one as an output is refused before
// anything is written, and the input keeps its content.
TEST_F(BdFiles, OutputNamingAnInputIsRefused) {
  const fs::path particles = dir_ / "start.txt";
  std::ofstream(particles) << "0 0 0\n5 0 0\n0 5 0\n";
  std::string text = kRun;
  text.replace(text.find("source = \"random\""),
               std::string("source = \"random\"\ncount = 30\nvolume_fraction = 0.05").size(),
               "source = \"file\"\nfile = \"" + particles.string() + "\"");
  const std::string before = slurp(particles);
  expect_error([&] { (void)run(parse_config(text + "[output]\ntrajectory = \"start.txt\"\n", "t"), dir_, 5); },
               {"output.trajectory", "particles.file", particles.string()});
  EXPECT_EQ(slurp(particles), before);

  const fs::path config = dir_ / "run.toml";
  std::ofstream(config) << kRun + "[output]\nlog = \"run.toml\"\n";
  const std::string config_text = slurp(config);
  expect_error([&] { (void)run(load_config(config), dir_, 5); }, {"output.log", "config", config.string()});
  EXPECT_EQ(slurp(config), config_text);
  EXPECT_FALSE(fs::exists(dir_ / "trajectory.xyz"));
}

// Run B, then a restart of run A's checkpoint into B's directory: refused naming the file
// that is not A's, and B's files are left byte for byte as they were.
TEST_F(BdFiles, RestartRefusesFilesItDidNotWrite) {
  const RunConfig a = parse_config(kRun + "[output]\ntrajectory_every = 5\nlog_every = 5\n", "a");
  const RunConfig b = parse_config(replace_seed(kRun, 7) + "[output]\ntrajectory_every = 5\nlog_every = 5\n", "b");
  (void)run(a, dir_ / "a", 10);
  (void)run(b, dir_ / "b", 20);
  const std::string traj = slurp(dir_ / "b" / "trajectory.xyz"), log = slurp(dir_ / "b" / "log.csv");
  RunOptions into_b;
  into_b.out_dir = dir_ / "b";
  expect_error([&] { (void)restart_bd(dir_ / "a" / "checkpoint.bin", into_b); },
               {(dir_ / "b" / "trajectory.xyz").string(), "another run"});
  EXPECT_EQ(slurp(dir_ / "b" / "trajectory.xyz"), traj);
  EXPECT_EQ(slurp(dir_ / "b" / "log.csv"), log);
}

// Same config and seed: B's trajectory equals A's (it is the same run), but B's log differs in
// its timing columns. The log is refused, and the trajectory, checked first, is not cut.
TEST_F(BdFiles, RestartChecksEveryFileBeforeCuttingAny) {
  const RunConfig c = parse_config(kRun + "[output]\ntrajectory_every = 5\nlog_every = 5\n", "c");
  (void)run(c, dir_ / "a", 10);
  (void)run(c, dir_ / "b", 20);
  const std::string traj = slurp(dir_ / "b" / "trajectory.xyz"), log = slurp(dir_ / "b" / "log.csv");
  ASSERT_EQ(traj.substr(0, slurp(dir_ / "a" / "trajectory.xyz").size()), slurp(dir_ / "a" / "trajectory.xyz"));
  RunOptions into_b;
  into_b.out_dir = dir_ / "b";
  expect_error([&] { (void)restart_bd(dir_ / "a" / "checkpoint.bin", into_b); }, {(dir_ / "b" / "log.csv").string()});
  EXPECT_EQ(slurp(dir_ / "b" / "trajectory.xyz"), traj);
  EXPECT_EQ(slurp(dir_ / "b" / "log.csv"), log);
  // Its own directory restarts fine.
  EXPECT_EQ(restart_bd(dir_ / "a" / "checkpoint.bin", steps_to(20)).last_step, 20u);
}

// Refused at start-up (a periodic box with the open-geometry direct mobility; overlapping
// particles from a file, found by the first force evaluation): no directory, no file, and an
// earlier run's trajectory in the directory keeps its content.
TEST_F(BdFiles, RefusedStartLeavesNothingBehind) {
  std::string periodic = kRun;
  periodic.replace(periodic.find("geometry = \"open\""), 17, "geometry = \"periodic\"\nbox = [20, 20, 20]");
  periodic.replace(periodic.find("method = \"none\""), 15, "method = \"direct\"");
  periodic.replace(periodic.find("volume_fraction = 0.05\n"), 23, "");                     // the box sets the density
  const RunConfig refused = parse_config(periodic, "p");                                   // valid as a config ...
  expect_error([&] { (void)run(refused, dir_ / "new" / "deep", 5); }, {"open geometry"});  // ... not as a run
  EXPECT_FALSE(fs::exists(dir_ / "new"));

  const fs::path file = dir_ / "x.txt";
  std::ofstream(file) << "0 0 0\n10 0 0\n10.5 0 0\n";  // particles 1 and 2 overlap
  std::string overlap = kRun;
  overlap.replace(overlap.find("source = \"random\""),
                  std::string("source = \"random\"\ncount = 30\nvolume_fraction = 0.05").size(),
                  "source = \"file\"\nfile = \"" + file.string() + "\"");
  expect_error([&] { (void)run(parse_config(overlap, "o"), dir_ / "fresh", 5); }, {"overlap"});
  EXPECT_FALSE(fs::exists(dir_ / "fresh"));

  fs::create_directories(dir_ / "old");
  std::ofstream(dir_ / "old" / "trajectory.xyz") << "an earlier run\n";
  expect_error([&] { (void)run(parse_config(overlap, "o"), dir_ / "old", 5); }, {"overlap"});
  EXPECT_EQ(slurp(dir_ / "old" / "trajectory.xyz"), "an earlier run\n");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_ / "old"), fs::directory_iterator{}), 1);  // no temporaries
}

// A crash after the checkpoint leaves a partial record behind it: the restart cuts it off and
// ends where an uninterrupted run does, byte for byte in the trajectory.
TEST_F(BdFiles, RestartDropsATailWrittenAfterTheCheckpoint) {
  const RunConfig c = parse_config(kRun + "[output]\ntrajectory_every = 5\nlog_every = 5\n", "c");
  (void)run(c, dir_ / "full", 20);
  (void)run(c, dir_ / "cut", 10);
  std::ofstream(dir_ / "cut" / "trajectory.xyz", std::ios::app) << "30\npbc=\"F F F\" Properties=spec";
  std::ofstream(dir_ / "cut" / "log.csv", std::ios::app) << "15,0.01";
  EXPECT_EQ(restart_bd(dir_ / "cut" / "checkpoint.bin", steps_to(20)).last_step, 20u);
  EXPECT_EQ(slurp(dir_ / "cut" / "trajectory.xyz"), slurp(dir_ / "full" / "trajectory.xyz"));
  const std::string log = slurp(dir_ / "cut" / "log.csv");
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1 + 5);  // header + steps 0, 5, ..., 20
  EXPECT_EQ(log.find("15,0.01\n"), std::string::npos);
}

// An output name that is a symbolic link (here to a precious file) is refused, not followed;
// a checkpoint name that is a FIFO is refused at start-up, not at the first checkpoint.
TEST_F(BdFiles, OutputThatIsALinkIsRefused) {
  std::ofstream(dir_ / "precious") << "keep me\n";
  fs::create_directories(dir_ / "out");
  fs::create_symlink(dir_ / "precious", dir_ / "out" / "log.csv");
  expect_error([&] { (void)run(parse_config(kRun, "l"), dir_ / "out", 5); },
               {(dir_ / "out" / "log.csv").string(), "symbolic link"});
  EXPECT_EQ(slurp(dir_ / "precious"), "keep me\n");
  EXPECT_TRUE(fs::is_symlink(dir_ / "out" / "log.csv"));

  fs::create_directories(dir_ / "fifo");
  ASSERT_EQ(::mkfifo((dir_ / "fifo" / "checkpoint.bin").c_str(), 0600), 0);
  expect_error([&] { (void)run(parse_config(kRun, "f"), dir_ / "fifo", 5); },
               {(dir_ / "fifo" / "checkpoint.bin").string(), "FIFO"});
  EXPECT_TRUE(fs::is_fifo(dir_ / "fifo" / "checkpoint.bin"));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_ / "fifo"), fs::directory_iterator{}), 1);
}

TEST_F(BdFiles, CheckpointErrorsNameTheFile) {
  expect_error([&] { (void)read_checkpoint(dir_); }, {dir_.string(), "directory"});
  expect_error([&] { (void)read_checkpoint(dir_ / "missing.bin"); }, {(dir_ / "missing.bin").string()});
  std::ofstream(dir_ / "junk.bin") << "not a checkpoint";
  expect_error([&] { (void)read_checkpoint(dir_ / "junk.bin"); }, {(dir_ / "junk.bin").string(), "not an rpyfmm"});
}
