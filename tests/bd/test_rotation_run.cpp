// BD runs with rotation from a config: the keys and their errors, orientations from a particle
// file, the trajectory's orientation column, the log's rotational moments, and restarts that
// continue bit for bit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "one_thread.hpp"
#include "restart_pair.hpp"
#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/core/error.hpp"
#include "text_edit.hpp"

using namespace rpyfmm::bd;
using rpyfmm::Error;

namespace {

using bdtest::replace;
// Free-draining dipoles in a field with a torque, on a lattice: every rotation key in use.
const std::string kRotating = R"(
[system]
rotation = true
[[types]]
name = "A"
dipole = 2.0
external_torque = [0.0, 0.1, 0.0]
[particles]
source = "lattice"
count = 64
[external]
dipole_field = [0.0, 0.0, 1.5]
torque = [0.05, 0.0, 0.0]
[integrator]
dt = 0.01
steps = 40
seed = 3
[mobility]
method = "none"
[output]
trajectory_every = 5
log_every = 5
checkpoint_every = 10
)";

// kRotating (or a variant) without its torques and dipoles: free rotating spheres.
std::string without_torques(std::string text) {
  text = replace(text, "dipole = 2.0\nexternal_torque = [0.0, 0.1, 0.0]\n", "");
  return replace(text, "dipole_field = [0.0, 0.0, 1.5]\ntorque = [0.05, 0.0, 0.0]\n", "");
}

// ... and without rotation: a run as before rotation existed.
std::string without_rotation(const std::string& text) {
  return replace(without_torques(text), "rotation = true\n", "");
}

// Expects parsing, particle generation or the start of the run to fail naming `needle`.
void expect_error(const std::string& text, const std::string& needle) {
  try {
    RunConfig c = parse_config(text, "test.toml");
    c.output.dir = std::filesystem::temp_directory_path() / "rpyfmm_bd_rotation_refused";
    RunOptions o;
    o.steps = 0;
    (void)run_bd(c, o);
    ADD_FAILURE() << "no error; expected one mentioning '" << needle << "'";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << "message: " << e.what();
  }
}

std::filesystem::path scratch(const std::string& name) {
  auto p = std::filesystem::temp_directory_path() / ("rpyfmm_bd_rotation_" + name);
  std::filesystem::remove_all(p);
  return p;
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

std::vector<double> numbers_of(const std::string& line, char sep) {
  std::vector<double> out;
  std::istringstream in(line);
  for (std::string f; std::getline(in, f, sep);)
    if (!f.empty()) out.push_back(std::stod(f));
  return out;
}
}  // namespace

TEST(BdRotationConfig, KeysParseAndRotationIsOffByDefault) {
  const RunConfig c = parse_config(kRotating, "rotating");
  EXPECT_TRUE(c.integrator.rotation);
  ASSERT_EQ(c.type_torques.size(), 1u);
  EXPECT_EQ(c.type_torques[0].dipole, 2.0);
  EXPECT_EQ(c.type_torques[0].torque[1], 0.1);
  EXPECT_EQ(c.dipole_field[2], 1.5);
  EXPECT_EQ(c.external_torque[0], 0.05);
  EXPECT_TRUE(make_force_field(c).torque_field().active());
  EXPECT_FALSE(parse_config(without_rotation(kRotating), "plain").integrator.rotation);
  EXPECT_FALSE(make_force_field(parse_config(without_torques(kRotating), "free")).torque_field().active());
}

TEST(BdRotationConfig, EveryBadRotationKeyIsNamed) {
  const std::string off = replace(kRotating, "rotation = true", "rotation = false");
  expect_error(off, "types[0].external_torque");  // rotation keys without rotation = true
  expect_error(replace(off, "external_torque = [0.0, 0.1, 0.0]\n", ""), "types[0].dipole");
  expect_error(replace(replace(off, "external_torque = [0.0, 0.1, 0.0]\n", ""), "dipole = 2.0\n", ""),
               "external.torque");
  expect_error(replace(kRotating, "rotation = true", "rotation = 1"), "system.rotation");
  expect_error(replace(kRotating, "dipole = 2.0", "dipole = -1.0"), "types[0].dipole");
  expect_error(replace(kRotating, "torque = [0.05, 0.0, 0.0]", "torque = [nan, 0.0, 0.0]"), "external.torque");
  expect_error(replace(kRotating, "dipole_field = [0.0, 0.0, 1.5]", "dipole_field = [0.0, 1.5]"),
               "external.dipole_field");
  expect_error(replace(kRotating, "torque = [0.05, 0.0, 0.0]", "torq = [0.05, 0.0, 0.0]"), "external.torq");
  expect_error(replace(kRotating, "dipole = 2.0\n", ""), "external.dipole_field");  // a field with no dipole
}

// Rows "x y z [type] [qw qx qy qz]": normalized, written back as x y z w (OVITO's order); refused
// without rotation, on some rows only, or zero.
TEST(BdRotationConfig, OrientationsComeFromTheParticleFile) {
  const auto dir = scratch("file");
  std::filesystem::create_directories(dir);
  const auto file = dir / "x.txt";
  std::ofstream(file) << "0 0 0 A 0 2 0 0\n5 0 0 A 1 0 0 0\n";  // a half turn about x, unnormalized
  std::string text =
      replace(kRotating, "source = \"lattice\"\ncount = 64", "source = \"file\"\nfile = \"" + file.string() + "\"");
  RunConfig c = parse_config(text, "file");
  c.output.dir = dir / "out";
  RunOptions o;
  o.steps = 0;
  (void)run_bd(c, o);
  const auto frame = lines_of(slurp(dir / "out" / "trajectory.xyz"));
  ASSERT_EQ(frame.size(), 4u);
  EXPECT_EQ(numbers_of(frame[2].substr(2), ' '), (std::vector<double>{0, 0, 0, 1, 1, 0, 0, 0}));
  EXPECT_EQ(numbers_of(frame[3].substr(2), ' '), (std::vector<double>{5, 0, 0, 1, 0, 0, 0, 1}));
  const auto file_error = [&](const std::string& rows, const std::string& config, const std::string& needle) {
    std::ofstream(file) << rows;
    expect_error(config, needle);
  };
  file_error("0 0 0 A 1 0 0 0\n", without_rotation(text), "has orientation columns, which need system.rotation");
  file_error("0 0 0 A 1 0 0 0\n5 0 0 A\n", text, "x.txt:2: orientation columns on some rows only");
  file_error("0 0 0 0 0 0 0\n", text, "x.txt:1: the orientation of particle 0 is a zero quaternion");
  std::filesystem::remove_all(dir);
}

// The trajectory declares orientation:R:4 and every row carries a unit quaternion; the log adds
// rotational_msd and orientation_correlation. Free spheres (no dipoles here), N = 1000, t = 1,
// D_r = 1 / (8 pi): rotational_msd = 6 D_r t with relative standard error sqrt(2/3 / N) = 2.6%,
// tolerance 10% (4 SE); orientation_correlation = exp(-2 D_r t) with standard error
// sqrt(((1 + 2 exp(-6 D_r t)) / 3 - exp(-4 D_r t)) / N) = 0.0025, tolerance 0.01 (4 SE).
TEST(BdRotationRun, TrajectoryAndLogCarryTheRotation) {
  std::string text = without_torques(kRotating);
  text = replace(replace(text, "count = 64", "count = 1000"), "dt = 0.01\nsteps = 40", "dt = 0.05\nsteps = 20");
  RunConfig c = parse_config(text, "free");
  const auto dir = scratch("free");
  c.output.dir = dir;
  (void)run_bd(c);
  const auto traj = lines_of(slurp(dir / "trajectory.xyz"));
  ASSERT_EQ(traj.size(), 5u * 1002u);  // steps 0, 5, ..., 20
  EXPECT_NE(traj[1].find("Properties=species:S:1:pos:R:3:radius:R:1:orientation:R:4 Time=0 Step=0"), std::string::npos);
  for (std::size_t row = 2; row < 1002; ++row) {
    const auto v = numbers_of(traj[4 * 1002 + row].substr(2), ' ');
    ASSERT_EQ(v.size(), 8u);
    EXPECT_NEAR(v[4] * v[4] + v[5] * v[5] + v[6] * v[6] + v[7] * v[7], 1.0, 1e-9);
  }
  const auto log = lines_of(slurp(dir / "log.csv"));
  ASSERT_EQ(log.size(), 6u);
  EXPECT_NE(log[0].find(",wall_output,rotational_msd,orientation_correlation"), std::string::npos) << log[0];
  const auto first = numbers_of(log[1], ','), last = numbers_of(log[5], ',');
  EXPECT_EQ(first[first.size() - 2], 0.0);
  EXPECT_EQ(first.back(), 1.0);
  const double dr = 1.0 / (8 * std::numbers::pi), t = 1.0;
  EXPECT_NEAR(last[last.size() - 2] / (6 * dr * t), 1.0, 0.10);
  EXPECT_NEAR(last.back(), std::exp(-2 * dr * t), 0.01);
  std::filesystem::remove_all(dir);
}

// Interrupted at step 15 and restarted to 40: orientations, the summed rotation vectors, the
// trajectory and the log equal those of an uninterrupted run, bitwise (the dipole torques make
// the dynamics depend on the orientations carried by the checkpoint), free draining and with RPY
// (direct: the grand mobility's Lanczos sample).
TEST(BdRotationRun, RestartContinuesBitwise) {
  const bdtest::OneThread one;
  for (const std::string method : {"none", "direct"}) {
    const RunConfig c = parse_config(replace(kRotating, "method = \"none\"", "method = \"" + method + "\""), method);
    const auto a = scratch("full"), b = scratch("split");
    EXPECT_EQ(bdtest::run_whole_and_restarted(c, a, b, 15).last_step, 40u);
    const Checkpoint ca = read_checkpoint(a / "checkpoint.bin"), cb = read_checkpoint(b / "checkpoint.bin");
    ASSERT_EQ(ca.orientations.size(), 4u * 64u);
    EXPECT_EQ(ca.positions, cb.positions) << method;
    EXPECT_EQ(ca.orientations, cb.orientations) << method;
    EXPECT_EQ(ca.reference_orientations, cb.reference_orientations) << method;
    EXPECT_EQ(ca.rotation_vectors, cb.rotation_vectors) << method;
    EXPECT_NE(ca.orientations, ca.reference_orientations) << method;
    EXPECT_EQ(slurp(a / "trajectory.xyz"), slurp(b / "trajectory.xyz")) << method;
    // The log's rotational moments (its last two columns; wall times differ between the runs).
    const auto log_a = lines_of(slurp(a / "log.csv")), log_b = lines_of(slurp(b / "log.csv"));
    ASSERT_EQ(log_a.size(), log_b.size());
    for (std::size_t row = 1; row < log_a.size(); ++row) {
      const auto va = numbers_of(log_a[row], ','), vb = numbers_of(log_b[row], ',');
      EXPECT_EQ(std::vector<double>(va.end() - 2, va.end()), std::vector<double>(vb.end() - 2, vb.end())) << row;
    }
    std::filesystem::remove_all(a);
    std::filesystem::remove_all(b);
  }
}

// Without rotation the checkpoint keeps format version 2, byte for byte the layout it had.
TEST(BdRotationRun, RunsWithoutRotationKeepCheckpointVersion2) {
  RunConfig c = parse_config(without_rotation(kRotating), "plain");
  const auto dir = scratch("plain");
  c.output.dir = dir;
  (void)run_bd(c);
  const std::string bytes = slurp(dir / "checkpoint.bin");
  std::uint32_t version = 0;
  std::memcpy(&version, bytes.data() + 8, 4);
  EXPECT_EQ(version, 2u);
  EXPECT_EQ(bytes.size(), 8 + 4 + 8 * 8 + 64 * (3 * 8 + 3 * 8 + 4) + 8 + c.text.size() + 8);
  EXPECT_TRUE(read_checkpoint(dir / "checkpoint.bin").orientations.empty());
  EXPECT_EQ(lines_of(slurp(dir / "log.csv"))[0].find("rotational_msd"), std::string::npos);
  std::filesystem::remove_all(dir);
}

// The shipped example runs (5 steps) and writes its rotation columns.
TEST(BdRotationRun, ExampleRuns) {
  const bdtest::OneThread one;
  const RunConfig c =
      load_config(std::filesystem::path(RPYFMM_SOURCE_DIR) / "examples" / "bd" / "rotation" / "dipoles.toml");
  EXPECT_TRUE(c.integrator.rotation);
  const auto dir = scratch("example");
  RunOptions o;
  o.steps = 5;
  o.out_dir = dir;
  EXPECT_EQ(run_bd(c, o).last_step, 5u);
  EXPECT_NE(slurp(dir / "log.csv").find("orientation_correlation"), std::string::npos);
  std::filesystem::remove_all(dir);
}
