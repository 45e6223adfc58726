// GSD trajectories (`[output] format = "gsd"`), read back through the gsd C library: every chunk of
// every frame against the run's own state (HOOMD schema, bd/hoomd_frame.hpp), restarts equal to
// uninterrupted runs frame by frame, and the file rules of the XYZ trajectory (a restart never
// cuts or replaces a file it did not write; links, FIFOs and inputs are refused).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "restart_pair.hpp"
#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/gsd_trajectory.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/core/error.hpp"
#include "run_files_fixture.hpp"
#include "text_edit.hpp"

#if RPYFMM_TEST_HAVE_GSD
#include <gsd.h>
#endif

namespace fs = std::filesystem;
using namespace rpyfmm::bd;
using rpyfmm::Error;

namespace {

using bdtest::replace;

// Two types (names of different lengths), rotation, free space, free draining.
const std::string kRun = R"(
[system]
rotation = true
[[types]]
name = "A"
radius = 1.0
[[types]]
name = "Big"
radius = 1.5
[particles]
source = "random"
count = 24
types = ["A", "Big"]
[integrator]
dt = 0.01
steps = 20
[mobility]
method = "none"
[output]
format = "gsd"
trajectory_every = 5
log_every = 5
checkpoint_every = 10
)";

using BdGsd = bdtest::RunFiles;

}  // namespace

TEST_F(BdGsd, UnknownFormatNamesTheKey) {
  expect_error([] { (void)parse_config(replace(kRun, "format = \"gsd\"", "format = \"pdb\""), "t"); },
               {"output.format", "\"xyz\" or \"gsd\"", "pdb"});
  expect_error([] { (void)parse_config(replace(kRun, "format = \"gsd\"", "format = 3"), "t"); },
               {"output.format", "string"});
  EXPECT_EQ(parse_config(replace(kRun, "format = \"gsd\"", ""), "t").output.format, TrajectoryFormat::xyz);
}

#if !RPYFMM_TEST_HAVE_GSD

// Without the gsd sources at configure time the format is refused while parsing, naming the key,
// why and how to enable it.
TEST_F(BdGsd, RefusedWithTheReasonInABuildWithoutGsd) {
  EXPECT_FALSE(gsd_supported());
  expect_error([] { (void)parse_config(kRun, "t"); }, {"output.format", "GSD support", "fetch-gsd.sh"});
  GTEST_SKIP() << "this build has no GSD support (scripts/fetch-gsd.sh, then configure again): "
                  "the GSD file tests are skipped";
}

#else

namespace {

/// A GSD file opened read-only through the gsd C library.
class GsdReader {
 public:
  explicit GsdReader(const fs::path& path) {
    const int rc = gsd_open(&h_, path.c_str(), GSD_OPEN_READONLY);
    if (rc != GSD_SUCCESS) throw std::runtime_error("gsd_open " + path.string() + ": " + std::to_string(rc));
  }
  GsdReader(const GsdReader&) = delete;
  GsdReader& operator=(const GsdReader&) = delete;
  ~GsdReader() { (void)gsd_close(&h_); }

  std::uint64_t frames() { return gsd_get_nframes(&h_); }
  std::string schema() const { return h_.header.schema; }
  std::uint32_t schema_version() const { return h_.header.schema_version; }
  bool has(std::uint64_t frame, const std::string& name) { return gsd_find_chunk(&h_, frame, name.c_str()); }
  std::vector<std::string> names() {
    std::vector<std::string> out;
    for (const char* n = gsd_find_matching_chunk_name(&h_, "", nullptr); n;
         n = gsd_find_matching_chunk_name(&h_, "", n))
      out.emplace_back(n);
    return out;
  }
  /// The chunk's values; its type and its shape (rows x columns) must be as given.
  template <class T>
  std::vector<T> read(std::uint64_t frame, const std::string& name, gsd_type type, std::uint64_t rows,
                      std::uint32_t columns) {
    const gsd_index_entry* e = gsd_find_chunk(&h_, frame, name.c_str());
    if (!e) throw std::runtime_error("no chunk " + name + " in frame " + std::to_string(frame));
    EXPECT_EQ(e->type, type) << name;
    EXPECT_EQ(e->N, rows) << name;
    EXPECT_EQ(e->M, columns) << name;
    std::vector<T> v(e->N * e->M * gsd_sizeof_type(static_cast<gsd_type>(e->type)) / sizeof(T));
    EXPECT_EQ(gsd_read_chunk(&h_, v.data(), e), GSD_SUCCESS);
    return v;
  }
  /// The raw bytes and header of a chunk, for bitwise comparisons.
  std::string raw(std::uint64_t frame, const std::string& name) {
    const gsd_index_entry* e = gsd_find_chunk(&h_, frame, name.c_str());
    if (!e) return "<absent>";
    std::string bytes(e->N * e->M * gsd_sizeof_type(static_cast<gsd_type>(e->type)), '\0');
    (void)gsd_read_chunk(&h_, bytes.data(), e);
    return std::to_string(e->type) + ":" + std::to_string(e->N) + "x" + std::to_string(e->M) + ":" + bytes;
  }

 private:
  gsd_handle h_{};
};

std::vector<float> as_float(const std::vector<double>& v) {
  return {v.begin(), v.end()};
}

/// Every chunk of every frame of two files is the same, bit for bit.
void expect_same_frames(const fs::path& a, const fs::path& b) {
  GsdReader ra(a), rb(b);
  ASSERT_EQ(ra.frames(), rb.frames());
  ASSERT_EQ(ra.names(), rb.names());
  for (std::uint64_t f = 0; f < ra.frames(); ++f)
    for (const auto& name : ra.names()) EXPECT_EQ(ra.raw(f, name), rb.raw(f, name)) << name << " in frame " << f;
}

}  // namespace

// Frame k holds the state at step 5k, read from the checkpoint of a run stopped there: positions
// and orientations as float32 of the run's doubles, the step, the time, the free-space box (four
// times the largest |x_d| + a); frame 0 alone the types, type ids and diameters.
TEST_F(BdGsd, FramesHoldTheRunsState) {
  const RunConfig c = parse_config(kRun, "gsd");
  EXPECT_EQ(c.output.trajectory, "trajectory.gsd");
  (void)run(c, dir_ / "run", 20);
  GsdReader file(dir_ / "run" / "trajectory.gsd");
  EXPECT_EQ(file.schema(), "hoomd");
  EXPECT_EQ(file.schema_version(), gsd_make_version(1, 4));
  ASSERT_EQ(file.frames(), 5u);
  for (std::uint64_t f = 0; f < 5; ++f) {
    const std::uint64_t step = 5 * f;
    (void)run(c, dir_ / "at", step);
    const Checkpoint state = read_checkpoint(dir_ / "at" / "checkpoint.bin");
    const std::size_t n = state.types.size();
    EXPECT_EQ(file.read<std::uint64_t>(f, "configuration/step", GSD_TYPE_UINT64, 1, 1)[0], step);
    EXPECT_EQ(file.read<double>(f, "log/bd/time", GSD_TYPE_DOUBLE, 1, 1)[0], static_cast<double>(step) * 0.01);
    EXPECT_EQ(file.read<std::uint32_t>(f, "particles/N", GSD_TYPE_UINT32, 1, 1)[0], n);
    EXPECT_EQ(file.read<float>(f, "particles/position", GSD_TYPE_FLOAT, n, 3), as_float(state.positions));
    EXPECT_EQ(file.read<float>(f, "particles/orientation", GSD_TYPE_FLOAT, n, 4), as_float(state.orientations));
    std::vector<float> box{0, 0, 0, 0, 0, 0};
    for (std::size_t i = 0; i < n; ++i)
      for (int d = 0; d < 3; ++d) {
        const double reach = std::abs(state.positions[3 * i + d]) + (state.types[i] == 0 ? 1.0 : 1.5);
        box[d] = std::max(box[d], static_cast<float>(4 * reach));
      }
    EXPECT_EQ(file.read<float>(f, "configuration/box", GSD_TYPE_FLOAT, 6, 1), box);
    EXPECT_EQ(file.has(f, "particles/typeid"), f == 0);
    EXPECT_EQ(file.has(f, "particles/image"), false);
    if (f > 0) continue;
    EXPECT_EQ(file.read<std::uint8_t>(f, "configuration/dimensions", GSD_TYPE_UINT8, 1, 1)[0], 3);
    EXPECT_EQ(file.read<std::uint32_t>(f, "particles/typeid", GSD_TYPE_UINT32, n, 1), state.types);
    const auto names = file.read<char>(f, "particles/types", GSD_TYPE_INT8, 2, 4);
    EXPECT_EQ(std::string(names.data(), 8), std::string("A\0\0\0Big\0", 8));
    const auto diameter = file.read<float>(f, "particles/diameter", GSD_TYPE_FLOAT, n, 1);
    for (std::size_t i = 0; i < n; ++i) EXPECT_EQ(diameter[i], state.types[i] == 0 ? 2.0f : 3.0f);
  }
}

// In a periodic box positions are wrapped into [-L/2, L/2) with their images (x = p + n L), the
// box is the run's, and without rotation there is no orientation chunk.
TEST_F(BdGsd, PeriodicFramesWrapIntoTheCentredBoxWithImages) {
  const fs::path particles = dir_ / "start.txt";
  std::ofstream(particles) << "0 0 0\n5.999999 0 0\n-7 3 20\n13 -13 6\n-6 -6.000001 30.5\n";
  std::string text = replace(kRun, "rotation = true", "geometry = \"periodic\"\nbox = [12, 12, 12]");
  text = replace(text, "source = \"random\"\ncount = 24\ntypes = [\"A\", \"Big\"]",
                 "source = \"file\"\nfile = \"" + particles.string() + "\"");
  text = replace(text, "dt = 0.01", "dt = 0.001");
  const RunConfig c = parse_config(text, "periodic");
  (void)run(c, dir_ / "run", 5);
  GsdReader file(dir_ / "run" / "trajectory.gsd");
  ASSERT_EQ(file.frames(), 2u);
  const std::vector<double> start{0, 0, 0, 5.999999, 0, 0, -7, 3, 20, 13, -13, 6, -6, -6.000001, 30.5};
  const Checkpoint end = read_checkpoint(dir_ / "run" / "checkpoint.bin");
  for (std::uint64_t f = 0; f < 2; ++f) {
    const std::vector<double>& x = f == 0 ? start : end.positions;
    const auto p = file.read<float>(f, "particles/position", GSD_TYPE_FLOAT, 5, 3);
    const auto image = file.read<std::int32_t>(f, "particles/image", GSD_TYPE_INT32, 5, 3);
    for (std::size_t k = 0; k < 15; ++k) {
      EXPECT_GE(p[k], -6.0f);
      EXPECT_LT(p[k], 6.0f);
      EXPECT_EQ(p[k], static_cast<float>(x[k] - image[k] * 12.0)) << k;
    }
    EXPECT_EQ(file.read<float>(f, "configuration/box", GSD_TYPE_FLOAT, 6, 1),
              (std::vector<float>{12, 12, 12, 0, 0, 0}));
    EXPECT_FALSE(file.has(f, "particles/orientation"));
  }
  const auto image0 = file.read<std::int32_t>(0, "particles/image", GSD_TYPE_INT32, 5, 3);
  EXPECT_EQ(image0, (std::vector<std::int32_t>{0, 0, 0, 0, 0, 0, -1, 0, 2, 1, -1, 1, 0, -1, 3}));
}

// A 40-step run equals a run stopped at 15 and restarted, frame by frame and bit for bit; so does
// a restart from a checkpoint older than the file's last frames (a crash after step 20 with the
// checkpoint of step 10): the restart keeps the checkpoint's frames and rewrites the rest.
TEST_F(BdGsd, RestartEqualsUninterruptedRunFrameByFrame) {
  const RunConfig c = parse_config(replace(kRun, "steps = 20", "steps = 40"), "restart");
  const RunSummary s = bdtest::run_whole_and_restarted(c, dir_ / "whole", dir_ / "split", 15);
  EXPECT_EQ(s.first_step, 15u);
  EXPECT_EQ(read_checkpoint(dir_ / "whole" / "checkpoint.bin").positions,
            read_checkpoint(dir_ / "split" / "checkpoint.bin").positions);
  EXPECT_EQ(GsdReader(dir_ / "whole" / "trajectory.gsd").frames(), 9u);
  expect_same_frames(dir_ / "whole" / "trajectory.gsd", dir_ / "split" / "trajectory.gsd");

  (void)run(c, dir_ / "crash", 10);
  fs::copy_file(dir_ / "crash" / "checkpoint.bin", dir_ / "step10.bin");
  RunOptions to20;
  to20.steps = 20;
  (void)restart_bd(dir_ / "crash" / "checkpoint.bin", to20);
  EXPECT_EQ(GsdReader(dir_ / "crash" / "trajectory.gsd").frames(), 5u);
  fs::copy_file(dir_ / "step10.bin", dir_ / "crash" / "checkpoint.bin", fs::copy_options::overwrite_existing);
  EXPECT_EQ(restart_bd(dir_ / "crash" / "checkpoint.bin").last_step, 40u);
  expect_same_frames(dir_ / "whole" / "trajectory.gsd", dir_ / "crash" / "trajectory.gsd");
  EXPECT_EQ(entries(dir_ / "crash"), 3u);  // trajectory, log, checkpoint: no temporaries
}

// A restart into a directory whose trajectory another run wrote is refused naming the file, which
// is left byte for byte as it was, with no temporary beside it.
TEST_F(BdGsd, RestartRefusesAnotherRunsFileAndLeavesItUntouched) {
  const RunConfig a = parse_config(kRun, "a");
  const RunConfig b = parse_config(replace(kRun, "dt = 0.01", "dt = 0.01\nseed = 7"), "b");
  (void)run(a, dir_ / "a", 10);
  (void)run(b, dir_ / "b", 20);
  const std::string before = slurp(dir_ / "b" / "trajectory.gsd");
  RunOptions into_b;
  into_b.out_dir = dir_ / "b";
  expect_error([&] { (void)restart_bd(dir_ / "a" / "checkpoint.bin", into_b); },
               {(dir_ / "b" / "trajectory.gsd").string(), "another run"});
  EXPECT_EQ(slurp(dir_ / "b" / "trajectory.gsd"), before);
  EXPECT_EQ(entries(dir_ / "b"), 3u);

  std::ofstream(dir_ / "b" / "trajectory.gsd", std::ios::trunc) << "not a GSD file";
  expect_error([&] { (void)restart_bd(dir_ / "a" / "checkpoint.bin", into_b); },
               {(dir_ / "b" / "trajectory.gsd").string(), "not a GSD file"});
  EXPECT_EQ(slurp(dir_ / "b" / "trajectory.gsd"), "not a GSD file");
}

// The trajectory matches (same run) but the log does not: the restart is refused after the
// trajectory's frames were copied, and the trajectory is left as it was.
TEST_F(BdGsd, RefusedRestartLeavesTheTrajectoryAsItWas) {
  const RunConfig c = parse_config(kRun, "c");
  (void)run(c, dir_ / "a", 10);
  (void)run(c, dir_ / "b", 20);
  const std::string before = slurp(dir_ / "b" / "trajectory.gsd");
  RunOptions into_b;
  into_b.out_dir = dir_ / "b";
  expect_error([&] { (void)restart_bd(dir_ / "a" / "checkpoint.bin", into_b); }, {(dir_ / "b" / "log.csv").string()});
  EXPECT_EQ(slurp(dir_ / "b" / "trajectory.gsd"), before);
  EXPECT_EQ(entries(dir_ / "b"), 3u);
}

// Hostile names: a link (to a precious file) and a FIFO in the trajectory's place are refused at
// start-up, as is a trajectory that is the config file itself.
TEST_F(BdGsd, HostileTrajectoryPathsAreRefused) {
  std::ofstream(dir_ / "precious") << "keep me\n";
  fs::create_directories(dir_ / "link");
  fs::create_symlink(dir_ / "precious", dir_ / "link" / "trajectory.gsd");
  expect_error([&] { (void)run(parse_config(kRun, "l"), dir_ / "link", 5); },
               {(dir_ / "link" / "trajectory.gsd").string(), "symbolic link"});
  EXPECT_EQ(slurp(dir_ / "precious"), "keep me\n");
  EXPECT_TRUE(fs::is_symlink(dir_ / "link" / "trajectory.gsd"));
  EXPECT_EQ(entries(dir_ / "link"), 1u);

  fs::create_directories(dir_ / "fifo");
  ASSERT_EQ(::mkfifo((dir_ / "fifo" / "trajectory.gsd").c_str(), 0600), 0);
  expect_error([&] { (void)run(parse_config(kRun, "f"), dir_ / "fifo", 5); },
               {(dir_ / "fifo" / "trajectory.gsd").string(), "FIFO"});
  EXPECT_EQ(entries(dir_ / "fifo"), 1u);

  const fs::path config = dir_ / "run.toml";
  std::ofstream(config) << kRun + "trajectory = \"run.toml\"\n";
  const std::string text = slurp(config);
  expect_error([&] { (void)run(load_config(config), dir_, 5); }, {"output.trajectory", "config", config.string()});
  EXPECT_EQ(slurp(config), text);
}

#endif
