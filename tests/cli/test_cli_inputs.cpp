// Hostile and out-of-range input to the `rpyfmm` tool and to the readers behind it: .npy headers
// that lie about their size, endless or binary text, directories, thread counts, integer options
// past their range, subnormal scales, non-finite results. Each must end with exit status 2, one
// line on stderr naming the problem, and no output file; the ranges come from
// rpyfmm/core/ranges.hpp, the one definition that help texts and the library share.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "../../apps/rpyfmm/array_io.hpp"
#include "rpyfmm/bd/checkpoint.hpp"
#include "rpyfmm/bd/config.hpp"
#include "rpyfmm/core/error.hpp"
#include "rpyfmm/core/ranges.hpp"
#include "rpyfmm/core/threads.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"

namespace fs = std::filesystem;
namespace ranges = rpyfmm::ranges;

namespace {

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif
#else
constexpr bool kAddressSanitizer = false;
#endif

// A .npy v1.0 header declaring float64 data of `shape` (given as text), then `data_bytes` zeros.
std::string npy_bytes(const std::string& shape, std::size_t data_bytes) {
  std::string dict = "{'descr': '<f8', 'fortran_order': False, 'shape': " + shape + ", }";
  while ((10 + dict.size() + 1) % 64 != 0) dict += ' ';
  dict += '\n';
  std::string out("\x93NUMPY\x01\x00", 8);
  out += static_cast<char>(dict.size() & 0xff);
  out += static_cast<char>(dict.size() >> 8);
  return out + dict + std::string(data_bytes, '\0');
}

struct Result {
  int code = -1;
  std::string out, err;
};

class CliInputs : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("rpyfmm_cli_inputs_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    write("x.txt", "0 0 0\n3 0 0\n0 3 0\n");
    write("f.txt", "1 0 0\n0 1 0\n0 0 1\n");
  }
  void TearDown() override { fs::remove_all(dir_); }

  [[nodiscard]] std::string path(const std::string& name) const { return (dir_ / name).string(); }
  void write(const std::string& name, const std::string& bytes) const {
    std::ofstream(path(name), std::ios::binary) << bytes;
  }

  // Runs the tool under `timeout` (a hang is a failure, not a stuck test); `prefix` goes before
  // it in the shell (e.g. a ulimit).
  Result run(const std::string& args, int seconds = 60, const std::string& prefix = "") const {
    const std::string out = path("stdout.txt"), err = path("stderr.txt");
    const std::string cmd = prefix + "timeout " + std::to_string(seconds) + " '" + RPYFMM_CLI_PATH + "' " + args +
                            " >'" + out + "' 2>'" + err + "'";
    const int status = std::system(cmd.c_str());
    Result r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    auto slurp = [](const std::string& p) {
      std::ifstream in(p, std::ios::binary);
      return std::string(std::istreambuf_iterator<char>(in), {});
    };
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }

  // Exit status 2, one printable line on stderr containing every needle, nothing on stdout, no
  // output file.
  void expect_refused(const std::string& args, const std::vector<std::string>& needles,
                      const std::string& out_name = "u.npy", const std::string& prefix = "") const {
    const Result r = run(args, 60, prefix);
    EXPECT_EQ(r.code, 2) << args << "\nstderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << args << "\nstderr: " << r.err;
    EXPECT_TRUE(std::all_of(r.err.begin(), r.err.end() - (r.err.empty() ? 0 : 1),
                            [](char c) { return static_cast<unsigned char>(c) >= 0x20; }))
        << args << ": control bytes on stderr";
    for (const auto& needle : needles)
      EXPECT_NE(r.err.find(needle), std::string::npos) << args << "\nstderr: " << r.err;
    EXPECT_TRUE(r.out.empty()) << args << "\nstdout: " << r.out;
    EXPECT_FALSE(fs::exists(path(out_name))) << args;
  }

  [[nodiscard]] std::string mobility_with(const std::string& positions, const std::string& extra = "",
                                          const std::string& radius = "0.5") const {
    return "mobility --positions '" + positions + "' --forces " + path("f.txt") + " --radius " + radius + " --out " +
           path("u.npy") + extra;
  }

  fs::path dir_;
};

// ---- the array readers ---------------------------------------------------------------------

// The shape is checked against the file's size before anything is allocated: a 4.9 KB file
// declaring (5e7, 3) float64 or (1e11, 3) is "truncated", at once, naming the file and the shape.
TEST_F(CliInputs, NpyShapeIsCheckedAgainstTheFileSizeFirst) {
  write("big.npy", npy_bytes("(50000000, 3)", 4800));
  write("huge.npy", npy_bytes("(100000000000, 3)", 4800));
  write("overflow.npy", npy_bytes("(4294967296, 4294967296, 3)", 4800));
  expect_refused(mobility_with(path("big.npy")), {"big.npy", "truncated .npy data", "(50000000, 3)", "4800 bytes"});
  expect_refused(mobility_with(path("huge.npy")), {"huge.npy", "truncated .npy data", "(100000000000, 3)"});
  expect_refused(mobility_with(path("overflow.npy")), {"overflow.npy", "too large"});
}

TEST_F(CliInputs, NpyReaderRefusesSignsTrailingBytesAndEscapesTheDtype) {
  using rpyfmm::cli::read_array_bytes;
  EXPECT_EQ(read_array_bytes(npy_bytes("(2, 3)", 48), "ok.npy").shape, (std::vector<std::size_t>{2, 3}));
  const auto message = [](const std::string& bytes) {
    try {
      (void)read_array_bytes(bytes, "in.npy");
    } catch (const rpyfmm::Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message(npy_bytes("(-1, 3)", 48)).find("malformed .npy shape"), std::string::npos);
  EXPECT_NE(message(npy_bytes("(2, 3)", 56)).find("extra bytes"), std::string::npos);
  // Found by fuzzing: a shape that is not a tuple threw std::out_of_range from substr.
  EXPECT_NE(message(npy_bytes("   ", 0)).find("malformed .npy shape '' (expected a tuple"), std::string::npos)
      << message(npy_bytes("   ", 0));
  std::string dtype = npy_bytes("(2,)", 16);
  dtype.replace(dtype.find("<f8"), 3, "\n\x01x");
  EXPECT_NE(message(dtype).find("'\\x0a\\x01x'"), std::string::npos) << message(dtype);
}

// An endless input without newlines (/dev/zero) stops at the line-length limit instead of
// filling memory; run under a memory cap so that a reader without limits fails fast here.
TEST_F(CliInputs, EndlessTextInputStopsAtTheLineLimit) {
  const std::string cap = kAddressSanitizer ? "" : "ulimit -v 4000000; ";
  expect_refused(mobility_with("/dev/zero"), {"/dev/zero", "line 1 is longer than 1048576 bytes"}, "u.npy", cap);
}

TEST_F(CliInputs, TextLinesLongerThanTheLimitAreRefused) {
  write("long.txt", std::string(rpyfmm::cli::kMaxTextLineBytes, ' ') + "0 0 0\n3 0 0\n0 3 0\n");
  expect_refused(mobility_with(path("long.txt")), {"long.txt", "line 1 is longer than"});
}

TEST_F(CliInputs, DirectoryIsNamedAsOne) {
  expect_refused(mobility_with(dir_.string()), {"is a directory"});
}

// Binary bytes in a text array: a short escaped excerpt on one line, not the raw bytes.
TEST_F(CliInputs, BinaryTextIsQuotedEscaped) {
  // Lengths from the arrays (sizeof - 1: all but the terminating NUL), as the texts hold NULs.
  constexpr char binary[] = "0 0 0\n\x01\x02\x1b[2J\rxy\x00z\x0b\x0c\n0 3 0\n";
  write("bin.txt", std::string(binary, sizeof binary - 1));
  expect_refused(mobility_with(path("bin.txt")), {"bin.txt", "line 2: not a number near '\\x01\\x02\\x1b[2J\\x0dxy"});
  // A NUL byte ends nothing: the rest of the line is still read (and refused).
  constexpr char with_nul[] = "0 0 0\n3 0 0 \x00 7\n0 3 0\n";
  write("nul.txt", std::string(with_nul, sizeof with_nul - 1));
  expect_refused(mobility_with(path("nul.txt")), {"nul.txt", "line 2: not a number near '\\x00 7'"});
}

// Found by fuzzing: a checkpoint whose config text is empty was read with a memcpy from a null
// pointer (undefined behaviour; the sanitizer build stops on it).
TEST_F(CliInputs, CheckpointWithEmptyConfigReadsBack) {
  rpyfmm::bd::Checkpoint c;
  c.positions = {1.0, 2.0, 3.0};
  c.reference_positions = {0.0, 0.0, 0.0};
  c.types = {0};
  rpyfmm::bd::write_checkpoint(path("empty.bin"), c);
  const rpyfmm::bd::Checkpoint back = rpyfmm::bd::read_checkpoint(path("empty.bin"));
  EXPECT_EQ(back.positions, c.positions);
  EXPECT_TRUE(back.config.empty());
}

// ---- threads -------------------------------------------------------------------------------

TEST_F(CliInputs, ThreadCountsBeyondTheMachineAreRefused) {
  const std::string range = "[0, " + std::to_string(rpyfmm::max_threads()) + "]";
  for (const char* n : {"100000", "20000", "-1", "1.5", "99999999999999999999"}) {
    expect_refused(mobility_with(path("x.txt"), std::string(" --threads ") + n), {"--threads", range});
  }
  const Result help = run("mobility --help");
  EXPECT_NE(help.out.find("at most 4 x the hardware threads"), std::string::npos) << help.out;
  EXPECT_NE(help.out.find("(integer in " + range + ")"), std::string::npos) << help.out;
  EXPECT_EQ(run(mobility_with(path("x.txt"), " --threads " + std::to_string(rpyfmm::max_threads()))).code, 0);
}

// ---- integer options -----------------------------------------------------------------------

TEST_F(CliInputs, IntegerOptionsOutOfRangeAreRefusedNeverWrapped) {
  write("sizes.txt", "3\n");
  write("ft.txt", "0 0 1 0 0 0\n");
  write("run.toml",
        "[[types]]\nname = \"A\"\n[particles]\nsource = \"lattice\"\ncount = 8\n"
        "[integrator]\ndt = 0.001\nsteps = 2\n[mobility]\nmethod = \"none\"\n[output]\ndir = \"" +
            path("bd") + "\"\n");
  const std::string sample = "sample --positions " + path("x.txt") + " --radius 0.5 --out " + path("u.npy");
  const std::string bodies = " --positions " + path("x.txt") + " --radius 0.5 --body-sizes " + path("sizes.txt");
  const std::string rigid = "rigid" + bodies + " --forces " + path("ft.txt") + " --out " + path("u.npy");
  const std::string rigid_bd = "rigid-bd" + bodies + " --dt 0.01 --out " + path("u.npy");
  const std::string bd = "bd --quiet --config " + path("run.toml") + " --out-dir " + path("u.npy");
  struct Case {
    std::string args, option, range;
  };
  const std::vector<Case> cases = {
      {bd + " --steps -1", "--steps", ranges::kSteps.str()},
      {sample + " --seed -1", "--seed", "[0, 2^64-1]"},
      {sample + " --step -1", "--step", "[0, 2^64-1]"},
      {sample + " --step 18446744073709551616", "--step", "[0, 2^64-1]"},
      {sample + " --step 1e3", "--step", "[0, 2^64-1]"},
      {sample + " --max-iterations -1", "--max-iterations", ranges::kSqrtIterations.str()},
      {sample + " --max-iterations 4294967297", "--max-iterations", ranges::kSqrtIterations.str()},
      {sample + " --preconditioner-block 100000", "--preconditioner-block", ranges::kPreconditionerBlock.str()},
      {rigid + " --max-iterations 0", "--max-iterations", ranges::kGmresIterations.str()},
      {rigid + " --max-iterations -5", "--max-iterations", ranges::kGmresIterations.str()},
      {rigid_bd + " --steps -1", "--steps", "[1, 2^63-1]"},
      {rigid_bd + " --steps 9223372036854775808", "--steps", "[1, 2^63-1]"},
      {rigid_bd + " --steps 2 --every -1", "--every", ranges::kSteps.str()},
      {rigid_bd + " --steps 2 --seed -1", "--seed", "[0, 2^64-1]"},
      {rigid_bd + " --steps 2 --first-step -1", "--first-step", "[0, 2^64-1]"},
  };
  for (const Case& c : cases) expect_refused(c.args, {c.option, "must be an integer in " + c.range});

  // The ends of the ranges are accepted, and reported exactly.
  const Result top = run(sample + " --seed 18446744073709551615 --step 18446744073709551615 --json");
  ASSERT_EQ(top.code, 0) << top.err;
  EXPECT_NE(top.out.find("\"seed\":18446744073709551615,\"step\":18446744073709551615"), std::string::npos) << top.out;
  fs::remove(path("u.npy"));
  ASSERT_EQ(run(bd + " --steps 0").code, 0);
}

// ---- real parameters -----------------------------------------------------------------------

TEST_F(CliInputs, SubnormalAndHugeScalesAreRefused) {
  expect_refused(mobility_with(path("x.txt"), "", "1e-320"),
                 {"--radius", "[1e-30, 1e+30]", "got the subnormal 9.99989e-321"});
  expect_refused(mobility_with(path("x.txt"), "", "1e31"), {"--radius", "[1e-30, 1e+30]"});
  expect_refused(mobility_with(path("x.txt"), " --viscosity 1e-310"), {"--viscosity", "[1e-30, 1e+30]"});
  expect_refused(mobility_with(path("x.txt"), " --method fmm --tolerance 1e-320"), {"--tolerance", "[1e-12, 0.1]"});
  expect_refused("sample --positions " + path("x.txt") + " --radius 1e-320 --out " + path("u.npy"), {"--radius"});
  expect_refused("sample --positions " + path("x.txt") + " --radius 1 --sqrt-tolerance 1e-320 --out " + path("u.npy"),
                 {"--sqrt-tolerance", "must lie in (0, 1), got the subnormal 9.99989e-321"});
}

// Messages print numbers as %g: "[1e-12, 0.1], got 0.7", never "[0.000000, 0.500000]".
TEST_F(CliInputs, RangesAreStatedOnceAndPrintedReadably) {
  expect_refused(mobility_with(path("x.txt"), " --method fmm --tolerance 0.7"), {"must lie in [1e-12, 0.1], got 0.7"});
  const Result help = run("mobility --help");
  EXPECT_NE(help.out.find("relative tolerance of fmm/pse, in " + ranges::kMobilityTolerance.str()), std::string::npos)
      << help.out;
  // The library's tolerance range is the one in the help text: make_mobility and FmmRpy agree.
  using rpyfmm::rpy::MobilityMethod;
  const auto& r = ranges::kMobilityTolerance;
  for (double tol : {r.lo, r.hi}) {
    EXPECT_NO_THROW((void)rpyfmm::rpy::make_mobility({.method = MobilityMethod::fmm, .tolerance = tol}, 10)) << tol;
    EXPECT_NO_THROW(rpyfmm::rpy::FmmRpy(rpyfmm::rpy::Geometry::open(), 1.0, {.tolerance = tol})) << tol;
  }
  for (double tol : {r.lo / 2, r.hi * 1.5, 0.3}) {
    EXPECT_THROW((void)rpyfmm::rpy::make_mobility({.method = MobilityMethod::fmm, .tolerance = tol}, 10), rpyfmm::Error)
        << tol;
    EXPECT_THROW(rpyfmm::rpy::FmmRpy(rpyfmm::rpy::Geometry::open(), 1.0, {.tolerance = tol}), rpyfmm::Error) << tol;
  }
  try {
    rpyfmm::require_in_range(1e-13, 1e-12, 0.5, "where", "x");
    ADD_FAILURE() << "no error";
  } catch (const rpyfmm::Error& e) {
    EXPECT_STREQ(e.what(), "where: x must lie in [1e-12, 0.5], got 1e-13");
  }
  EXPECT_THROW(rpyfmm::require_positive(1e-320, "where", "x"), rpyfmm::Error);
  EXPECT_NO_THROW(rpyfmm::require_positive(1e-300, "where", "x"));
}

// ---- BD configs ----------------------------------------------------------------------------

TEST_F(CliInputs, ConfigNumbersOutOfRangeAreRefusedNamingTheKey) {
  const std::string base =
      "[[types]]\nname = \"A\"\nradius = RADIUS\n[particles]\nsource = \"random\"\ncount = COUNT\n"
      "[integrator]\ndt = 0.001\nsteps = 2\n[mobility]\nmethod = \"none\"\nEXTRA\n";
  const auto config = [&](const std::string& radius, const std::string& count, const std::string& extra) {
    std::string s = base;
    s.replace(s.find("RADIUS"), 6, radius);
    s.replace(s.find("COUNT"), 5, count);
    s.replace(s.find("EXTRA"), 5, extra);
    return s;
  };
  const auto message = [](const std::string& text) {
    try {
      (void)rpyfmm::bd::parse_config(text, "t.toml");
    } catch (const rpyfmm::Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message(config("1.0", "10", "")), "no error");
  // Found by fuzzing: toml++ 3.3 reaches undefined behaviour on some non-ASCII characters (U+01CE
  // between tokens, U+FCFF after a backslash); outside comments they are refused first.
  EXPECT_NE(message("\xc7\x8e").find("t.toml:1:1: non-ASCII character"), std::string::npos) << message("\xc7\x8e");
  EXPECT_NE(message("x = \"\"\"a \\\xef\xb3\xbf\n\"\"\"\n").find("t.toml:1:11: non-ASCII"), std::string::npos)
      << message("x = \"\"\"a \\\xef\xb3\xbf\n\"\"\"\n");
  EXPECT_NE(message(config("1.0", "10", "") + "[output]\ndir = \"\xc7\x8e\"\n").find("t.toml:14:8: non-ASCII"),
            std::string::npos);
  EXPECT_EQ(message("# \xce\xb7 = 1, \xc7\x8e\n" + config("1.0", "10", "# \xef\xb3\xbf \\\xef\xb3\xbf")), "no error");
  EXPECT_NE(message(config("1.0", "1000000000000000", "")).find("particles.count"), std::string::npos);
  EXPECT_NE(message(config("1e-320", "10", "")).find("types[0].radius"), std::string::npos);
  EXPECT_NE(message(config("1.0", "10", "tolerance = 0.3")).find("mobility.tolerance' must lie in [1e-12, 0.1]"),
            std::string::npos)
      << message(config("1.0", "10", "tolerance = 0.3"));
  EXPECT_NE(message(config("1.0", "10", "sqrt_max_iterations = 4294967297")).find("mobility.sqrt_max_iterations"),
            std::string::npos);
  EXPECT_NE(message(config("1.0", "10", "sqrt_preconditioner_block = -1")).find("sqrt_preconditioner_block"),
            std::string::npos);
}

// The count check also guards the CLI: a config asking for 10^15 particles is one line, exit 2.
TEST_F(CliInputs, ParticleCountBeyondMemoryIsRefusedByTheCli) {
  write("huge.toml",
        "[[types]]\nname = \"A\"\n[particles]\nsource = \"random\"\ncount = 1000000000000000\n"
        "[integrator]\ndt = 0.001\nsteps = 2\n[mobility]\nmethod = \"none\"\n");
  const Result r = run("bd --quiet --config " + path("huge.toml") + " --out-dir " + path("out"));
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("particles.count"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("bad_alloc"), std::string::npos) << r.err;
}

// ---- results -------------------------------------------------------------------------------

// Finite input whose result overflows: exit 2 and no file, never exit 0 with Inf in the output.
TEST_F(CliInputs, NonFiniteResultsAreNotWritten) {
  write("s.txt", "0 0 0\n1e-150 0 0\n");
  write("q.txt", "1e300\n1e300\n");
  expect_refused(
      "laplace --sources " + path("s.txt") + " --charges " + path("q.txt") + " --direct --out " + path("u.npy"),
      {"laplace", "is infinite", "nothing written"});
}

// ---- paths ---------------------------------------------------------------------------------

// An empty path names nothing: refused at parsing, never read as "not given" (an optional output
// silently not written, the built-in demo run in place of a config) or failing late about a
// temporary file.
TEST_F(CliInputs, EmptyValuesAreRefusedNamingTheOption) {
  write("sizes.txt", "3\n");
  write("ft.txt", "0 0 1 0 0 0\n");
  const std::string rigid = "rigid --positions " + path("x.txt") + " --radius 0.5 --body-sizes " + path("sizes.txt") +
                            " --forces " + path("ft.txt");
  expect_refused(mobility_with(path("x.txt")) + " --out ''", {"--out", "must not be empty"});
  expect_refused(rigid + " --out " + path("u.npy") + " --bead-forces ''", {"--bead-forces", "must not be empty"});
  expect_refused("bd --quiet --config ''", {"--config", "must not be empty"});
  expect_refused("bd --quiet --steps 0 --out-dir ''", {"--out-dir", "must not be empty"});
  expect_refused(mobility_with(path("x.txt"), " --method ''"), {"--method", "must not be empty"});
}

// A command's two outputs are written together: when the second cannot be written (its folder is
// missing), the first is not left behind either.
TEST_F(CliInputs, SecondOutputFailingLeavesNoFirstOutput) {
  write("sizes.txt", "3\n");
  write("ft.txt", "0 0 1 0 0 0\n");
  const std::string bodies = " --positions " + path("x.txt") + " --radius 0.5 --body-sizes " + path("sizes.txt");
  const std::string missing = path("missing/b.npy");
  expect_refused(
      "rigid" + bodies + " --forces " + path("ft.txt") + " --out " + path("u.npy") + " --bead-forces " + missing,
      {"missing/b.npy"});
  expect_refused("rigid-bd" + bodies + " --dt 0.01 --steps 1 --kT 0 --out " + path("u.npy") + " --beads-out " + missing,
                 {"missing/b.npy"});
  for (const auto& entry : fs::directory_iterator(dir_))
    EXPECT_EQ(entry.path().filename().string().find(".tmp."), std::string::npos) << entry.path() << " left behind";
  // Both written when both can be.
  const Result ok = run("rigid" + bodies + " --forces " + path("ft.txt") + " --out " + path("u.npy") +
                        " --bead-forces " + path("b.npy"));
  EXPECT_EQ(ok.code, 0) << ok.err;
  EXPECT_TRUE(fs::exists(path("u.npy")) && fs::exists(path("b.npy")));
}

// A config that is a device (/dev/zero: endless) or a directory is refused before it is read,
// under a memory cap so that a reader without the check fails fast here.
TEST_F(CliInputs, ConfigThatIsNotARegularFileIsRefused) {
  const std::string cap = kAddressSanitizer ? "" : "ulimit -v 4000000; ";
  expect_refused("bd --quiet --config /dev/zero --out-dir " + path("u.npy"), {"--config", "'/dev/zero' is a device"},
                 "u.npy", cap);
  expect_refused("bd --quiet --config " + dir_.string() + " --out-dir " + path("u.npy"),
                 {"--config", "is a directory"});
}

// One-dimensional shapes read as NumPy prints them, "(4,)", not "(4)".
TEST_F(CliInputs, OneDimensionalShapesKeepTheirComma) {
  write("q.npy", npy_bytes("(4,)", 32));
  expect_refused(
      "laplace --sources " + path("x.txt") + " --charges " + path("q.npy") + " --direct --out " + path("u.npy"),
      {"charges must have shape (3,), got (4,)"});
  write("p.npy", npy_bytes("(4,)", 32));
  expect_refused(mobility_with(path("p.npy")), {"positions must have shape (N,3) or (3N,), got (4,)"});
}

}  // namespace
