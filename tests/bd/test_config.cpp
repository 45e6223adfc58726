// Config parsing (every bad config names its key or particle), particle
// generators, and whole runs: output files, restart equal to an uninterrupted run.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "restart_pair.hpp"
#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/bd/particles.hpp"
#include "rpyfmm/bd/run.hpp"
#include "rpyfmm/core/error.hpp"

using namespace rpyfmm::bd;
using rpyfmm::Error;
using rpyfmm::rpy::ComputeDevice;
using rpyfmm::rpy::MobilityMethod;

namespace {
const std::string kBase = R"(
[system]
viscosity = 1.0
kT = 1.0
[[types]]
name = "A"
radius = 1.0
[particles]
source = "random"
count = 50
volume_fraction = 0.05
[[pair]]
types = ["A", "A"]
kind = "wca"
[integrator]
dt = 0.001
steps = 10
[mobility]
method = "none"
)";

// Expects parse (and particle generation) to fail with a message containing `needle`.
void expect_error(const std::string& text, const std::string& needle) {
  try {
    RunConfig c = parse_config(text, "test.toml");
    ForceField ff = make_force_field(c);
    (void)make_particles(c, ff);
    ADD_FAILURE() << "no error; expected one mentioning '" << needle << "'";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << "message: " << e.what();
  }
}

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const auto pos = s.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  return s.replace(pos, from.size(), to);
}

std::filesystem::path scratch(const std::string& name) {
  auto p = std::filesystem::temp_directory_path() / ("rpyfmm_bd_test_" + name);
  std::filesystem::remove_all(p);
  return p;
}
}  // namespace

TEST(BdConfig, ParsesDefaultsAndTheDemo) {
  const RunConfig c = parse_config(kBase, "base");
  EXPECT_EQ(c.steps, 10u);
  EXPECT_DOUBLE_EQ(c.integrator.dt, 0.001);
  EXPECT_EQ(c.mobility.method, MobilityMethod::none);
  EXPECT_EQ(c.output.trajectory_every, 100u);
  const RunConfig demo = parse_config(demo_config_text(), "demo");
  EXPECT_EQ(demo.particles.count, 2000u);
  EXPECT_EQ(demo.mobility.method, MobilityMethod::automatic);
  EXPECT_EQ(demo.mobility.fmm_crossover, 0u);  // the machine's measured crossover
  EXPECT_EQ(parse_config(replace(kBase, "[mobility]", "[mobility]\nfmm_crossover = 500"), "c").mobility.fmm_crossover,
            500u);
  EXPECT_FALSE(c.mobility.fft_measure);
  EXPECT_TRUE(parse_config(replace(kBase, "[mobility]", "[mobility]\nfft_measure = true"), "c").mobility.fft_measure);
  EXPECT_EQ(c.mobility.wave_precision, rpyfmm::rpy::pse::WavePrecision::automatic);
  EXPECT_EQ(parse_config(replace(kBase, "[mobility]", "[mobility]\nwave_precision = \"double\""), "c")
                .mobility.wave_precision,
            rpyfmm::rpy::pse::WavePrecision::double_precision);
  EXPECT_EQ(c.mobility.device, ComputeDevice::cpu);
  EXPECT_EQ(parse_config(replace(kBase, "[mobility]", "[mobility]\ndevice = \"cuda\""), "c").mobility.device,
            ComputeDevice::cuda);
  EXPECT_EQ(c.integrator.sqrt.preconditioner, rpyfmm::rpy::SqrtPreconditioner::automatic);
  const RunConfig block = parse_config(
      replace(kBase, "[mobility]", "[mobility]\nsqrt_preconditioner = \"block\"\nsqrt_preconditioner_block = 32"), "c");
  EXPECT_EQ(block.integrator.sqrt.preconditioner, rpyfmm::rpy::SqrtPreconditioner::block);
  EXPECT_EQ(block.integrator.sqrt.preconditioner_block, 32);
}

TEST(BdConfig, EveryBadConfigNamesTheKey) {
  expect_error("[particles]\nsource = \"random\"\ncount = 5\n", "integrator");          // missing section
  expect_error(replace(kBase, "steps = 10", ""), "integrator.steps");                   // missing key
  expect_error(replace(kBase, "dt = 0.001", "dt = -0.1"), "integrator.dt");             // negative dt
  expect_error(replace(kBase, "dt = 0.001", "dt = \"fast\""), "integrator.dt");         // wrong type
  expect_error(replace(kBase, "dt = 0.001", "dt = 0.001\ndtt = 1"), "integrator.dtt");  // unknown key
  expect_error(kBase + "[solver]\nx = 1\n", "solver");                                  // unknown section
  expect_error(replace(kBase, "kind = \"wca\"", "kind = \"lj\""), "pair[0].kind");      // bad enum
  expect_error(replace(kBase, "types = [\"A\", \"A\"]", "types = [\"A\", \"B\"]"), "pair[0].types");
  expect_error(replace(kBase, "radius = 1.0", "radius = 0"), "types[0].radius");
  expect_error(replace(kBase, "method = \"none\"", "method = \"magic\""), "mobility.method");
  expect_error(replace(kBase, "[mobility]", "[mobility]\nfft_measure = 1"), "mobility.fft_measure");  // not a boolean
  expect_error(replace(kBase, "[mobility]", "[mobility]\nwave_precision = \"half\""), "mobility.wave_precision");
  expect_error(replace(kBase, "[mobility]", "[mobility]\ndevice = \"gpu\""), "mobility.device");
  expect_error(replace(kBase, "[mobility]", "[mobility]\nsqrt_preconditioner = \"jacobi\""),
               "mobility.sqrt_preconditioner");
  expect_error(replace(kBase, "[mobility]", "[mobility]\nsqrt_preconditioner = \"block\"\nsqrt_method = \"eigen\""),
               "mobility.sqrt_preconditioner");
  expect_error(replace(kBase, "[mobility]", "[mobility]\nsqrt_preconditioner_block = -4"),
               "mobility.sqrt_preconditioner_block");
  expect_error(replace(kBase, "viscosity = 1.0", "viscosity = nan"), "system.viscosity");
  expect_error(replace(kBase, "volume_fraction = 0.05", "volume_fraction = 0.6"), "particles.volume_fraction");
  expect_error(replace(kBase, "source = \"random\"\ncount = 50\nvolume_fraction = 0.05",
                       "source = \"chains\"\nchains = 2\nbeads = 3"),
               "bonds");
  expect_error(kBase + "[output]\nlog = \"../x.csv\"\n", "output");
  expect_error(kBase + "[output]\ndir = \"\"\n", "output.dir");
  expect_error("[integrator\n", "test.toml:1");  // TOML syntax error with its position
}

// A config or particle file that is a device or a directory is refused by name before it is read
// (/dev/zero would be read forever).
TEST(BdConfig, InputsThatAreNotRegularFilesAreRefused) {
  for (const char* path : {"/dev/zero", "/"}) {
    try {
      (void)load_config(path);
      ADD_FAILURE() << "load_config(" << path << ") accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("config"), std::string::npos) << e.what();
    }
  }
  expect_error(replace(kBase, "source = \"random\"\ncount = 50\nvolume_fraction = 0.05",
                       "source = \"file\"\nfile = \"/dev/zero\""),
               "/dev/zero");
}

TEST(BdRun, EmptyOutputDirectoryIsRefused) {
  RunOptions options;
  options.out_dir = std::filesystem::path();
  try {
    (void)run_bd(parse_config(kBase, "base"), options);
    ADD_FAILURE() << "an empty out_dir accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("out_dir"), std::string::npos) << e.what();
  }
}

// [partition] (docs/bd-config.md): read by runs across MPI ranks, accepted and ignored by one process.
TEST(BdConfig, PartitionSection) {
  using rpyfmm::bd::PartitionSpec;
  const RunConfig defaults = parse_config(kBase, "base");
  EXPECT_EQ(defaults.partition.curve, PartitionSpec::Curve::morton);
  EXPECT_EQ(defaults.partition.repartition_imbalance, 1.25);
  EXPECT_EQ(defaults.partition.repartition_cost, PartitionSpec::Cost::model);
  const RunConfig c = parse_config(
      kBase + "[partition]\ncurve = \"hilbert\"\nrepartition_imbalance = 1.5\nrepartition_cost = \"measured_time\"\n",
      "c");
  EXPECT_EQ(c.partition.curve, PartitionSpec::Curve::hilbert);
  EXPECT_EQ(c.partition.repartition_imbalance, 1.5);
  EXPECT_EQ(c.partition.repartition_cost, PartitionSpec::Cost::measured_time);
  EXPECT_TRUE(std::isinf(
      parse_config(kBase + "[partition]\nrepartition_imbalance = inf\n", "c").partition.repartition_imbalance));
  expect_error(kBase + "[partition]\ncurve = \"peano\"\n", "partition.curve");
  expect_error(kBase + "[partition]\nrepartition_imbalance = 0.9\n", "partition.repartition_imbalance");
  expect_error(kBase + "[partition]\nrepartition_imbalance = nan\n", "partition.repartition_imbalance");
  expect_error(kBase + "[partition]\nrepartition_imbalance = \"never\"\n", "partition.repartition_imbalance");
  expect_error(kBase + "[partition]\nrepartition_cost = \"time\"\n", "partition.repartition_cost");
  expect_error(kBase + "[partition]\nranks = 4\n", "partition.ranks");
}

// The DLVO pair's short-range repulsion: core = "none" (default) or "born", with born_sigma only
// beside core = "born" (docs/bd-config.md).
TEST(BdConfig, DlvoCoreKeys) {
  const std::string dlvo = replace(kBase, "kind = \"wca\"", "kind = \"dlvo\"\nhamaker = 3.0\nkappa = 0.5");
  EXPECT_EQ(parse_config(dlvo, "c").pairs[0].potential.core, DlvoCore::none);
  const RunConfig born = parse_config(replace(dlvo, "kappa = 0.5", "kappa = 0.5\ncore = \"born\""), "c");
  EXPECT_EQ(born.pairs[0].potential.core, DlvoCore::born);
  EXPECT_EQ(born.pairs[0].potential.born_sigma, 0.0);  // resolved to 0.8 / kappa
  EXPECT_EQ(parse_config(replace(dlvo, "kappa = 0.5", "kappa = 0.5\ncore = \"born\"\nborn_sigma = 0.2"), "c")
                .pairs[0]
                .potential.born_sigma,
            0.2);
  expect_error(replace(dlvo, "kappa = 0.5", "kappa = 0.5\ncore = \"hard\""), "pair[0].core");
  expect_error(replace(dlvo, "kappa = 0.5", "kappa = 0.5\ncore = 1"), "pair[0].core");
  expect_error(replace(dlvo, "kappa = 0.5", "kappa = 0.5\ncore = \"born\"\nborn_sigma = -1"), "pair[0].born_sigma");
  expect_error(replace(dlvo, "kappa = 0.5", "kappa = 0.5\nborn_sigma = 0.2"), "pair[0].born_sigma");
  expect_error(replace(kBase, "kind = \"wca\"", "kind = \"wca\"\ncore = \"born\""), "pair[0].core");
}

TEST(BdConfig, ParticleFileErrorsNameTheParticle) {
  const auto dir = scratch("file");
  std::filesystem::create_directories(dir);
  const auto file = dir / "x.txt";
  std::ofstream(file) << "# x y z type\n0 0 0 A\n3 0 0\n0 nan 0\n";
  expect_error(replace(kBase, "source = \"random\"\ncount = 50\nvolume_fraction = 0.05",
                       "source = \"file\"\nfile = \"" + file.string() + "\""),
               "coordinate 1 of particle 2 is not finite");
  std::ofstream(file) << "0 0 0 B\n";
  expect_error(replace(kBase, "source = \"random\"\ncount = 50\nvolume_fraction = 0.05",
                       "source = \"file\"\nfile = \"" + file.string() + "\""),
               "unknown type 'B'");
  std::filesystem::remove_all(dir);
}

TEST(BdConfig, OverlappingHardParticlesAreRejectedByName) {
  const auto dir = scratch("overlap");
  std::filesystem::create_directories(dir);
  const auto file = dir / "x.txt";
  std::ofstream(file) << "0 0 0\n10 0 0\n10.5 0 0\n";  // particles 1 and 2 overlap (r = 0.5 < 2a)
  RunConfig c = parse_config(replace(kBase, "source = \"random\"\ncount = 50\nvolume_fraction = 0.05",
                                     "source = \"file\"\nfile = \"" + file.string() + "\""),
                             "t");
  c.output.dir = dir / "out";
  try {
    (void)run_bd(c);
    FAIL() << "overlap not rejected";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("particles 1 and 2 overlap"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

// Random insertion in periodic boxes: no two particles closer than contact under the minimum
// image (brute force over all pairs), across the faces too, in a dense cube and in a slab whose
// thin side holds only two placement cells (wrapped cell neighbours repeat there).
TEST(BdConfig, RandomParticlesDoNotOverlapAcrossPeriodicFaces) {
  for (const auto& [box, count] : {std::pair{std::array<double, 3>{24.0, 24.0, 24.0}, std::size_t{1000}},
                                   std::pair{std::array<double, 3>{5.0, 40.0, 40.0}, std::size_t{600}}}) {
    std::string text = replace(kBase, "source = \"random\"\ncount = 50\nvolume_fraction = 0.05",
                               "source = \"random\"\ncount = " + std::to_string(count));
    text = replace(text, "[system]\n",
                   "[system]\ngeometry = \"periodic\"\nbox = [" + std::to_string(box[0]) + ", " +
                       std::to_string(box[1]) + ", " + std::to_string(box[2]) + "]\n");
    const RunConfig c = parse_config(text, "periodic random");
    const ForceField ff = make_force_field(c);
    const InitialState s = make_particles(c, ff);
    ASSERT_EQ(s.types.size(), count);
    double rmin = 1e300;
    for (std::size_t i = 0; i < count; ++i) {
      for (int k = 0; k < 3; ++k) {
        EXPECT_GE(s.positions[3 * i + k], 0.0);
        EXPECT_LT(s.positions[3 * i + k], box[k]);
      }
      for (std::size_t j = i + 1; j < count; ++j) {
        double r2 = 0;
        for (int k = 0; k < 3; ++k) {
          double d = s.positions[3 * i + k] - s.positions[3 * j + k];
          d -= box[k] * std::nearbyint(d / box[k]);
          r2 += d * d;
        }
        rmin = std::min(rmin, std::sqrt(r2));
      }
    }
    EXPECT_GE(rmin, 2.0 * 1.02 - 1e-12) << box[0];  // radius 1, generated with a 2% gap
  }
}

TEST(BdConfig, GeneratorsProduceNonOverlappingParticles) {
  for (const std::string src :
       {"source = \"random\"\ncount = 300\nvolume_fraction = 0.2", "source = \"lattice\"\ncount = 100",
        "source = \"chains\"\nchains = 5\nbeads = 20", "source = \"clusters\"\nclusters = 4\ncluster_size = 25"}) {
    std::string text = replace(kBase, "source = \"random\"\ncount = 50\nvolume_fraction = 0.05", src);
    if (src.find("chains") != std::string::npos) text += "[bonds]\nkind = \"fene\"\nk = 30\nlength = 3.0\n";
    const RunConfig c = parse_config(text, "gen");
    const ForceField ff = make_force_field(c);
    const InitialState s = make_particles(c, ff);
    const std::size_t n = s.types.size();
    ASSERT_GE(n, 100u) << src;
    double rmin = 1e300;
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t j = i + 1; j < n; ++j) {
        double r2 = 0;
        for (int k = 0; k < 3; ++k) r2 += std::pow(s.positions[3 * i + k] - s.positions[3 * j + k], 2);
        rmin = std::min(rmin, std::sqrt(r2));
      }
    EXPECT_GE(rmin, 2.0) << src;  // radius 1: no overlaps
    if (src.find("chains") != std::string::npos) {
      EXPECT_EQ(s.bonds.size(), 5u * 19u);
      for (const auto& b : s.bonds) {
        double r2 = 0;
        for (int k = 0; k < 3; ++k) r2 += std::pow(s.positions[3 * b.i + k] - s.positions[3 * b.j + k], 2);
        EXPECT_NEAR(std::sqrt(r2), 2.1, 1e-9);  // default bond length 2.1 a
      }
    }
  }
}

// A run interrupted at step 15 (by asking for 15 steps) and restarted to 40 ends in the
// same state, bitwise, as a 40-step run; the log and trajectory are identical too.
TEST(BdRun, RestartEqualsUninterruptedRun) {
  std::string text = replace(kBase, "steps = 10", "steps = 40");
  text = replace(text, "kT = 1.0", "kT = 1.0\ngeometry = \"open\"");
  text += "[output]\ntrajectory_every = 5\nlog_every = 5\ncheckpoint_every = 10\n";
  RunConfig c = parse_config(text, "run");
  const auto a = scratch("full"), b = scratch("split");
  const RunSummary s = bdtest::run_whole_and_restarted(c, a, b, 15);
  EXPECT_EQ(s.first_step, 15u);
  EXPECT_EQ(s.last_step, 40u);
  const Checkpoint ca = read_checkpoint(a / "checkpoint.bin"), cb = read_checkpoint(b / "checkpoint.bin");
  EXPECT_EQ(ca.step, 40u);
  EXPECT_EQ(ca.positions, cb.positions);
  auto slurp = [](const std::filesystem::path& p) {
    std::ifstream in(p);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  EXPECT_EQ(slurp(a / "trajectory.xyz"), slurp(b / "trajectory.xyz"));
  const std::string log = slurp(a / "log.csv");
  EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1 + 9);  // header + steps 0, 5, ..., 40
  EXPECT_NE(slurp(a / "trajectory.xyz").find("Properties=species:S:1:pos:R:3:radius:R:1 Time=0.04 Step=40"),
            std::string::npos);
  std::filesystem::remove_all(a);
  std::filesystem::remove_all(b);
}

TEST(BdRun, BlowUpLeavesTheLastGoodCheckpoint) {
  std::string text = replace(kBase, "[[pair]]", "[external]\nforce = [0, 0, -1e6]\n[[pair]]");
  RunConfig c = parse_config(text, "blowup");
  const auto dir = scratch("blowup");
  try {
    RunOptions o;
    o.out_dir = dir;
    (void)run_bd(c, o);
    FAIL() << "blow-up not reported";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("blow-up at step 0"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("checkpoint.bin"), std::string::npos) << e.what();
  }
  const Checkpoint chk = read_checkpoint(dir / "checkpoint.bin");
  EXPECT_EQ(chk.step, 0u);
  EXPECT_EQ(chk.positions, chk.reference_positions);
  std::filesystem::remove_all(dir);
}

// The shipped example configs and the built-in demo stay valid (docs drift guard).
TEST(BdConfig, ExamplesParse) {
  for (const char* name : {"sedimentation.toml", "polymer.toml", "colloids_dlvo.toml"}) {
    const auto path = std::filesystem::path(RPYFMM_SOURCE_DIR) / "examples" / "bd" / name;
    const RunConfig c = load_config(path);
    const ForceField ff = make_force_field(c);
    EXPECT_GT(make_particles(c, ff).types.size(), 100u) << name;
  }
}
