// The run driver on the device engine ([mobility] device = "cuda", method = "none";
// docs/gpu-bd.md): trajectory, log and checkpoint written from the engine's positions, step and
// energy, checked here on the host launcher (RunOptions::device_launcher) bit for bit against the
// CPU engine's files, a restart from its checkpoint continuing bit for bit, features the device
// engine lacks refused at start-up by name, and, without a usable device, the run stopped at
// start-up saying why.
#include <gtest/gtest.h>

#include <cstddef>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "../run_files_fixture.hpp"
#include "require_device.hpp"
#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/device/device_engine.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/core/error.hpp"

namespace fs = std::filesystem;
using namespace rpyfmm::bd;

namespace {

// The outputs and the free-draining mobility of both runs below (60 steps).
const std::string kOutputs = R"(
[output]
trajectory_every = 10
log_every = 5
checkpoint_every = 30
[mobility]
method = "none"
)";

// WCA spheres in a periodic box with a constant force: rebuilds from the cell grid.
const std::string kPeriodic = R"(
[system]
geometry = "periodic"
box = [16.0, 16.0, 16.0]
[[types]]
name = "A"
radius = 0.5
[particles]
source = "random"
count = 400
seed = 3
[[pair]]
types = ["A", "A"]
kind = "wca"
[external]
force = [0.5, 0.0, -0.25]
[integrator]
dt = 1e-4
steps = 60
seed = 5
[neighbours]
skin = 0.3
)";

// FENE chains with WCA beads and a trap in free space.
const std::string kChains = R"(
[system]
geometry = "open"
[[types]]
name = "bead"
radius = 0.5
[particles]
source = "chains"
chains = 6
beads = 20
bond_length = 1.05
seed = 7
[bonds]
kind = "fene"
k = 30.0
length = 1.5
[[pair]]
types = ["bead", "bead"]
kind = "wca"
[external]
trap_stiffness = 0.01
[integrator]
dt = 1e-3
steps = 60
seed = 11
max_displacement = 0.5
[neighbours]
skin = 0.2
)";

/// The CPU engine's run of `text` (outputs and mobility appended).
RunConfig on_cpu(const std::string& text) {
  return parse_config(text + kOutputs, "cpu run");
}

/// The device engine's run of `text` (outputs and mobility appended).
RunConfig on_device(const std::string& text) {
  return parse_config(text + kOutputs + "device = \"cuda\"\n", "device run");
}

RunOptions host_launcher(const fs::path& out, std::uint64_t steps) {
  RunOptions o;
  o.out_dir = out;
  o.steps = steps;
  o.device_launcher = DeviceLauncher::host;
  return o;
}

/// The log's columns that time nothing: step, time, mean displacement, MSD, mean velocity,
/// potential energy, square-root iterations and mobility products per step (0 for free
/// draining), and then, unless `with_builds` is false, the neighbour-list builds of the process
/// (which start again at a restart). The wall seconds per part that follow differ from run to
/// run on any engine.
std::vector<std::vector<std::string>> untimed_rows(const std::string& csv, bool with_builds) {
  const std::size_t columns = with_builds ? 11 : 10;
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(csv);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::istringstream fields(line);
    std::string cell;
    while (cells.size() < columns && std::getline(fields, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

class DeviceRun : public bdtest::RunFiles {
 protected:
  /// The files of `dir` equal to `ref`'s: trajectory byte for byte, the log's untimed columns
  /// (the builds where both ran in one process), the checkpoint's state.
  static void expect_same_files(const fs::path& dir, const fs::path& ref, bool with_builds) {
    const std::string trajectory = slurp(dir / "trajectory.xyz");
    EXPECT_NE(trajectory.find(" Step=60\n"), std::string::npos) << "the last frame is written";
    EXPECT_EQ(trajectory, slurp(ref / "trajectory.xyz"));
    EXPECT_EQ(untimed_rows(slurp(dir / "log.csv"), with_builds), untimed_rows(slurp(ref / "log.csv"), with_builds));
    const Checkpoint a = read_checkpoint(dir / "checkpoint.bin");
    const Checkpoint b = read_checkpoint(ref / "checkpoint.bin");
    EXPECT_EQ(a.step, b.step);
    EXPECT_EQ(a.positions, b.positions);
    EXPECT_EQ(a.reference_positions, b.reference_positions);
    EXPECT_EQ(a.types, b.types);
    EXPECT_EQ(a.trajectory_bytes, b.trajectory_bytes);
    EXPECT_EQ(a.trajectory_hash, b.trajectory_hash);
  }
};

}  // namespace

// The run on the host launcher writes the CPU engine's trajectory, log and checkpoint.
TEST_F(DeviceRun, HostLauncherWritesTheCpuEnginesFiles) {
  for (const std::string* text : {&kPeriodic, &kChains}) {
    const fs::path cpu = dir_ / "cpu", dev = dir_ / "device";
    fs::remove_all(cpu);
    fs::remove_all(dev);
    const RunSummary a = run(on_cpu(*text), cpu, 60);
    const RunSummary b = run_bd(on_device(*text), host_launcher(dev, 60));
    EXPECT_EQ(b.last_step, 60u);
    EXPECT_EQ(b.neighbour_rebuilds, a.neighbour_rebuilds);
    EXPECT_GE(a.neighbour_rebuilds, 2u) << "the run must rebuild its lists";
    EXPECT_EQ(b.mobility, a.mobility);
    EXPECT_EQ(a.engine, "cpu");
    EXPECT_EQ(b.engine, "host launcher");
    for (const char* part : {"neighbours", "forces", "update"}) EXPECT_GT(b.seconds.at(part), 0.0) << part;
    expect_same_files(dev, cpu, true);
  }
}

// Stopped at step 30 and restarted from its checkpoint, the device run ends with the files of
// the run straight through, and of the CPU engine's run.
TEST_F(DeviceRun, RestartFromTheCheckpointContinuesBitForBit) {
  for (const std::string* text : {&kPeriodic, &kChains}) {
    const fs::path whole = dir_ / "whole", split = dir_ / "split", cpu = dir_ / "cpu";
    for (const auto& d : {whole, split, cpu}) fs::remove_all(d);
    (void)run(on_cpu(*text), cpu, 60);
    (void)run_bd(on_device(*text), host_launcher(whole, 60));
    (void)run_bd(on_device(*text), host_launcher(split, 30));
    RunOptions resume;
    resume.device_launcher = DeviceLauncher::host;
    const RunSummary r = restart_bd(split / "checkpoint.bin", resume);
    EXPECT_EQ(r.first_step, 30u);
    EXPECT_EQ(r.last_step, 60u);
    expect_same_files(split, whole, false);
    expect_same_files(split, cpu, false);
  }
}

// A step refused by the blow-up guard stops the run with the CPU engine's error code and the last
// good state in the checkpoint.
TEST_F(DeviceRun, BlowUpSavesTheLastGoodStateAsTheCpuEngine) {
  std::string text = kChains;
  text.replace(text.find("dt = 1e-3"), 9, "dt = 5.0");
  rpyfmm::ErrorCode codes[2] = {};
  const fs::path dirs[2] = {dir_ / "cpu", dir_ / "device"};
  for (int k = 0; k < 2; ++k) {
    try {
      (void)(k == 0 ? run(on_cpu(text), dirs[k], 60) : run_bd(on_device(text), host_launcher(dirs[k], 60)));
      ADD_FAILURE() << dirs[k] << ": no blow-up";
    } catch (const rpyfmm::Error& e) {
      codes[k] = e.code();
      EXPECT_NE(std::string(e.what()).find("last good state (step 0) saved"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(codes[0], rpyfmm::ErrorCode::numerical_failure);
  EXPECT_EQ(codes[1], codes[0]);
  const Checkpoint a = read_checkpoint(dirs[1] / "checkpoint.bin");
  const Checkpoint b = read_checkpoint(dirs[0] / "checkpoint.bin");
  EXPECT_EQ(a.step, 0u);
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.trajectory_hash, b.trajectory_hash);
}

// With [mobility] method = "pse" the run on the host launcher writes the CPU engine's files, and a
// restart from its checkpoint at step 30 ends with the files of the run straight through.
TEST_F(DeviceRun, PseRunOnTheHostLauncherWritesTheCpuEnginesFiles) {
  std::string text = kPeriodic;
  text.replace(text.find("count = 400"), 11, "count = 100");
  text.replace(text.find("box = [16.0, 16.0, 16.0]"), 24, "box = [12.0, 12.0, 12.0]");
  text.replace(text.find("skin = 0.3"), 10, "skin = 0.1");  // rebuilds within the short run
  std::string outputs = kOutputs;
  outputs.replace(outputs.find("method = \"none\""), 15,
                  "method = \"pse\"\ntolerance = 1e-4\nwave_precision = \"double\"");
  const RunConfig cpu_config = parse_config(text + outputs, "cpu run");
  const RunConfig device_config = parse_config(text + outputs + "device = \"cuda\"\n", "device run");
  const fs::path cpu = dir_ / "cpu", dev = dir_ / "device", split = dir_ / "split";
  const RunSummary a = run(cpu_config, cpu, 60);
  const RunSummary b = run_bd(device_config, host_launcher(dev, 60));
  EXPECT_EQ(a.engine, "cpu");
  EXPECT_EQ(b.engine, "host launcher");
  EXPECT_EQ(b.mobility, a.mobility);
  EXPECT_EQ(b.neighbour_rebuilds, a.neighbour_rebuilds);
  EXPECT_GE(a.neighbour_rebuilds, 2u) << "the run must rebuild its lists";
  expect_same_files(dev, cpu, true);
  (void)run_bd(device_config, host_launcher(split, 30));
  RunOptions resume;
  resume.device_launcher = DeviceLauncher::host;
  const RunSummary r = restart_bd(split / "checkpoint.bin", resume);
  EXPECT_EQ(r.last_step, 60u);
  expect_same_files(split, cpu, false);
}

// Each feature the device engine lacks stops the run at start-up, naming it, before any file.
TEST_F(DeviceRun, RefusesWhatTheDeviceEngineLacksByName) {
  const std::string langevin = R"(
[system]
geometry = "open"
[[types]]
name = "A"
radius = 0.5
dynamics = "langevin"
mass = 1.0
[particles]
source = "random"
count = 10
[integrator]
dt = 1e-4
steps = 5
)";
  std::string rotation = kChains;
  rotation.insert(rotation.find("[[types]]"), "rotation = true\n");
  std::string split = kChains;
  split.insert(split.find("[neighbours]"), "split_displacements = true\n");
  const struct {
    const std::string* text;
    const char* feature;
  } cases[] = {{&rotation, "rotation"}, {&split, "split displacements"}, {&langevin, "inertial (Langevin)"}};
  for (const auto& c : cases) {
    const fs::path out = dir_ / "refused";
    try {
      (void)run_bd(on_device(*c.text), host_launcher(out, 5));
      ADD_FAILURE() << "accepted " << c.feature;
    } catch (const rpyfmm::Error& e) {
      EXPECT_EQ(e.code(), rpyfmm::ErrorCode::not_supported) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.feature), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(out)) << c.feature;
  }
}

// Without a usable device the run stops at start-up with the reason, before any file.
TEST_F(DeviceRun, WithoutADeviceStopsAtStartUpSayingWhy) {
  if (device_test::device_expected() || device::DeviceEngine::device_available())
    GTEST_SKIP() << "a usable CUDA device: the run starts (DeviceRunOnDevice)";
  const fs::path out = dir_ / "no-device";
  RunOptions o;
  o.out_dir = out;
  try {
    (void)run_bd(on_device(kPeriodic), o);
    ADD_FAILURE() << "ran without a device";
  } catch (const rpyfmm::Error& e) {
    EXPECT_EQ(e.code(), rpyfmm::ErrorCode::not_supported) << e.what();
    const std::string what = e.what();
    EXPECT_TRUE(what.find("no usable CUDA device: ") != std::string::npos ||
                what.find("no CUDA support") != std::string::npos)
        << what;
  }
  EXPECT_FALSE(fs::exists(out));
}

// On a device: the CUDA engine's run writes the host launcher's files and restarts bit for bit
// (the chains' FENE logarithms aside: the periodic WCA run only).
TEST_F(DeviceRun, DeviceRunOnDeviceWritesTheLaunchersFiles) {
  REQUIRE_BD_DEVICE();
  const fs::path host = dir_ / "host", dev = dir_ / "device", split = dir_ / "split";
  (void)run_bd(on_device(kPeriodic), host_launcher(host, 60));
  RunOptions o;
  o.out_dir = dev;
  o.steps = 60;
  (void)run_bd(on_device(kPeriodic), o);
  expect_same_files(dev, host, true);
  o.out_dir = split;
  o.steps = 30;
  (void)run_bd(on_device(kPeriodic), o);
  (void)restart_bd(split / "checkpoint.bin");
  expect_same_files(split, host, false);
}
