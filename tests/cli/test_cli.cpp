// Runs the built `rpyfmm` binary (path from CMake) on .npy/text files written
// here, and checks outputs against the library and failures against the CLI
// contract: exit code 2, exactly one line on stderr, no output file.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "rpyfmm/bd/rigid_dynamics.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/fmm/direct.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"
#include "rpyfmm/rpy/rigid_bodies.hpp"

namespace fs = std::filesystem;

namespace {

// Minimal .npy (v1.0, little-endian float64, C order) writer/reader, written
// here independently of the CLI's array_io.cpp.
void write_npy(const fs::path& p, const std::vector<std::size_t>& shape, const std::vector<double>& data,
               std::size_t truncate_bytes = 0) {
  std::string dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (";
  for (std::size_t s : shape) dict += std::to_string(s) + ", ";
  dict += "), }";
  while ((10 + dict.size() + 1) % 64 != 0) dict += ' ';
  dict += '\n';
  std::ofstream out(p, std::ios::binary);
  out.write("\x93NUMPY\x01\x00", 8);
  const std::uint16_t len = static_cast<std::uint16_t>(dict.size());
  out.put(static_cast<char>(len & 0xff));
  out.put(static_cast<char>(len >> 8));
  out << dict;
  out.write(reinterpret_cast<const char*>(data.data()),
            static_cast<std::streamsize>(data.size() * sizeof(double) - truncate_bytes));
}

struct Npy {
  std::vector<std::size_t> shape;
  std::vector<double> data;
};

Npy read_npy(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  char magic[10];
  in.read(magic, 10);
  EXPECT_EQ(std::memcmp(magic, "\x93NUMPY\x01\x00", 8), 0);
  const std::size_t len = static_cast<unsigned char>(magic[8]) | (static_cast<unsigned char>(magic[9]) << 8);
  std::string header(len, '\0');
  in.read(header.data(), static_cast<std::streamsize>(len));
  EXPECT_NE(header.find("'<f8'"), std::string::npos) << header;
  Npy a;
  const auto open = header.find('('), close = header.find(')');
  std::stringstream ss(header.substr(open + 1, close - open - 1));
  std::string item;
  std::size_t count = 1;
  while (std::getline(ss, item, ',')) {
    if (item.find_first_not_of(' ') == std::string::npos) continue;
    a.shape.push_back(std::stoul(item));
    count *= a.shape.back();
  }
  a.data.resize(count);
  in.read(reinterpret_cast<char*>(a.data.data()), static_cast<std::streamsize>(count * 8));
  EXPECT_TRUE(in.good()) << p;
  return a;
}

std::vector<double> random_vec(std::size_t n, unsigned seed, double lo, double hi) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<double> v(n);
  for (auto& x : v) x = u(rng);
  return v;
}

struct Result {
  int code = -1;
  std::string out, err;
};

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("rpyfmm_cli_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  [[nodiscard]] std::string path(const std::string& name) const { return (dir_ / name).string(); }

  Result run(const std::string& args) const { return run_with_env("", args); }

  // `env`: variable assignments put before the command ("NAME=value ...").
  Result run_with_env(const std::string& env, const std::string& args) const {
    const std::string out = path("stdout.txt"), err = path("stderr.txt");
    const std::string cmd =
        env + (env.empty() ? "" : " ") + "'" + RPYFMM_CLI_PATH + "' " + args + " >'" + out + "' 2>'" + err + "'";
    const int status = std::system(cmd.c_str());
    Result r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    auto slurp = [](const std::string& p) {
      std::ifstream in(p);
      return std::string(std::istreambuf_iterator<char>(in), {});
    };
    r.out = slurp(out);
    r.err = slurp(err);
    return r;
  }

  // Bad input: exit code 2, one line on stderr that contains `needle`, no stdout, no output file.
  void expect_failure(const std::string& args, const std::string& needle, const std::string& out_name) const {
    const Result r = run(args);
    EXPECT_EQ(r.code, 2) << args << "\nstderr: " << r.err;
    EXPECT_FALSE(r.err.empty()) << args;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << args << "\nstderr: " << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << args << "\nstderr: " << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_FALSE(fs::exists(path(out_name))) << args;
    for (const auto& e : fs::directory_iterator(dir_)) {  // no temporary left behind either
      EXPECT_EQ(e.path().filename().string().find(out_name + ".tmp"), std::string::npos) << e.path();
    }
  }

  fs::path dir_;
};

}  // namespace

TEST_F(Cli, LaplaceAtSourcesMatchesLibrary) {
  const std::size_t n = 200;
  const auto s = random_vec(3 * n, 1, -1, 1);
  const auto q = random_vec(n, 2, -1, 1);
  write_npy(path("s.npy"), {n, 3}, s);
  write_npy(path("q.npy"), {n}, q);
  const Result r = run("laplace --sources " + path("s.npy") + " --charges " + path("q.npy") + " --direct --out " +
                       path("r.npy") + " --threads 2 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1);
  EXPECT_NE(r.out.find("\"command\":\"laplace\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"n_sources\":200"), std::string::npos) << r.out;
  const Npy out = read_npy(path("r.npy"));
  ASSERT_EQ(out.shape, (std::vector<std::size_t>{n, 10}));
  std::vector<double> ref(n * 10);
  rpyfmm::fmm::laplace_direct(s, q, 1, {}, rpyfmm::fmm::all_outputs, ref);
  EXPECT_EQ(out.data, ref);  // same code, deterministic: bitwise
}

TEST_F(Cli, LaplaceSeveralChargeVectorsAtTextTargets) {
  const std::size_t n = 50, nd = 3, m = 7;
  const auto s = random_vec(3 * n, 3, -1, 1);
  const auto q = random_vec(nd * n, 4, -1, 1);
  const auto t = random_vec(3 * m, 5, -2, 2);
  write_npy(path("s.npy"), {n, 3}, s);
  write_npy(path("q.npy"), {nd, n}, q);
  {
    std::ofstream txt(path("t.txt"));
    txt.precision(17);
    for (std::size_t i = 0; i < m; ++i) txt << t[3 * i] << ' ' << t[3 * i + 1] << ' ' << t[3 * i + 2] << '\n';
  }
  const Result r = run("laplace --sources " + path("s.npy") + " --targets " + path("t.txt") + " --charges " +
                       path("q.npy") + " --direct --out " + path("r.npy"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(r.out.empty());
  const Npy out = read_npy(path("r.npy"));
  ASSERT_EQ(out.shape, (std::vector<std::size_t>{nd, m, 10}));
  std::vector<double> ref(nd * m * 10);
  rpyfmm::fmm::laplace_direct(s, q, nd, t, rpyfmm::fmm::all_outputs, ref);  // %.17g text round-trips exactly
  EXPECT_EQ(out.data, ref);
}

// --torques: the grand mobility with rotation, (N, 6) rows Ux Uy Uz Wx Wy Wz, equal bit for bit to
// DirectRpy::apply(F, T, U, W) (and PseRpy's with --method pse); --angular alone: T = 0.
TEST_F(Cli, MobilityWithTorquesWritesVelocitiesAndAngularVelocities) {
  const std::size_t n = 40;
  const auto x = random_vec(3 * n, 16, 0, 6);
  const auto f = random_vec(3 * n, 17, -1, 1);
  const auto t = random_vec(3 * n, 18, -1, 1);
  write_npy(path("x.npy"), {n, 3}, x);
  write_npy(path("f.npy"), {n, 3}, f);
  write_npy(path("t.npy"), {n, 3}, t);
  const std::string base = "mobility --positions " + path("x.npy") + " --forces " + path("f.npy") +
                           " --radius 0.5 --viscosity 2 --method direct --out " + path("uw.npy");
  rpyfmm::rpy::DirectRpy op(rpyfmm::rpy::Geometry::open(), 2.0);
  op.set_positions(x, 0.5);
  for (const bool torques : {true, false}) {
    const Result r = run(base + (torques ? " --torques " + path("t.npy") : std::string(" --angular")));
    ASSERT_EQ(r.code, 0) << r.err;
    const Npy uw = read_npy(path("uw.npy"));
    ASSERT_EQ(uw.shape, (std::vector<std::size_t>{n, 6}));
    std::vector<double> u(3 * n), w(3 * n);
    op.apply(f, torques ? t : std::vector<double>(3 * n, 0.0), u, w);
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(uw.data[6 * i + c], u[3 * i + c]) << i;
        EXPECT_EQ(uw.data[6 * i + 3 + c], w[3 * i + c]) << i;
      }
    fs::remove(path("uw.npy"));
  }
  // PSE (periodic) too: the same rows from PseRpy's grand mobility.
  const Result r = run("mobility --positions " + path("x.npy") + " --forces " + path("f.npy") +
                       " --radius 0.5 --viscosity 2 --method pse --tolerance 1e-4 --box 20 --torques " + path("t.npy") +
                       " --out " + path("uw.npy"));
  ASSERT_EQ(r.code, 0) << r.err;
  const Npy uw = read_npy(path("uw.npy"));
  ASSERT_EQ(uw.shape, (std::vector<std::size_t>{n, 6}));
  rpyfmm::rpy::pse::PseOptions options;
  options.tolerance = 1e-4;
  rpyfmm::rpy::pse::PseRpy pse(rpyfmm::rpy::Geometry::periodic(20, 20, 20), 2.0, options);
  pse.set_positions(x, 0.5);
  std::vector<double> u(3 * n), w(3 * n);
  pse.apply(f, t, u, w);
  for (std::size_t i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(uw.data[6 * i + c], u[3 * i + c]) << i;
      EXPECT_EQ(uw.data[6 * i + 3 + c], w[3 * i + c]) << i;
    }
}

TEST_F(Cli, MobilityMatchesLibrary) {
  const std::size_t n = 120;
  const auto x = random_vec(3 * n, 6, 0, 8);
  const auto f = random_vec(3 * n, 7, -1, 1);
  const auto a = random_vec(n, 8, 0.2, 0.9);
  write_npy(path("x.npy"), {n, 3}, x);
  write_npy(path("f.npy"), {n, 3}, f);
  write_npy(path("a.npy"), {n}, a);
  // common radius
  Result r = run("mobility --positions " + path("x.npy") + " --forces " + path("f.npy") +
                 " --radius 0.5 --viscosity 2 --method direct --out " + path("u.npy") + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"command\":\"mobility\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"method\":\"direct\""), std::string::npos) << r.out;
  Npy out = read_npy(path("u.npy"));
  ASSERT_EQ(out.shape, (std::vector<std::size_t>{n, 3}));
  rpyfmm::rpy::DirectRpy op(rpyfmm::rpy::Geometry::open(), 2.0);
  op.set_positions(x, 0.5);
  std::vector<double> ref(3 * n);
  op.apply(f, ref);
  EXPECT_EQ(out.data, ref);
  // per-particle radii, default viscosity and method
  r = run("mobility --positions " + path("x.npy") + " --forces " + path("f.npy") + " --radii " + path("a.npy") +
          " --out " + path("u2.npy") + " --threads 1");
  ASSERT_EQ(r.code, 0) << r.err;
  out = read_npy(path("u2.npy"));
  rpyfmm::rpy::DirectRpy op2;
  op2.set_positions(x, a);
  op2.apply(f, ref);
  EXPECT_EQ(out.data, ref);
}

namespace {
double rel_l2(const std::vector<double>& a, const std::vector<double>& b) {
  double num = 0, den = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    num += (a[i] - b[i]) * (a[i] - b[i]);
    den += b[i] * b[i];
  }
  return std::sqrt(num / den);
}
}  // namespace

TEST_F(Cli, LaplaceFmmMatchesDirectToTolerance) {
  const std::size_t n = 3000;
  const auto s = random_vec(3 * n, 21, -1, 1);
  const auto q = random_vec(n, 22, -1, 1);
  write_npy(path("s.npy"), {n, 3}, s);
  write_npy(path("q.npy"), {n}, q);
  const Result r = run("laplace --sources " + path("s.npy") + " --charges " + path("q.npy") +
                       " --tolerance 1e-6 --out " + path("r.npy") + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"method\":\"fmm\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"tolerance\":"), std::string::npos) << r.out;  // the option's name, not "eps"
  const Npy out = read_npy(path("r.npy"));
  ASSERT_EQ(out.shape, (std::vector<std::size_t>{n, 10}));
  std::vector<double> ref(n * 10);
  rpyfmm::fmm::laplace_direct(s, q, 1, {}, rpyfmm::fmm::all_outputs, ref);
  // Relative l2 error of each output (potential, gradient, Hessian) <= eps: the FMM's contract.
  for (auto [lo, hi] : {std::pair{0, 1}, std::pair{1, 4}, std::pair{4, 10}}) {
    std::vector<double> a, b;
    for (std::size_t i = 0; i < n; ++i)
      for (int c = lo; c < hi; ++c) {
        a.push_back(out.data[10 * i + c]);
        b.push_back(ref[10 * i + c]);
      }
    EXPECT_LE(rel_l2(a, b), 1e-6) << "columns " << lo << ".." << hi;
  }
}

// One name for accuracy: the former spellings (--eps, sample's --tol) still work, print one warning
// line naming the new option and give the same output; given with the new name and a different
// value they fail.
TEST_F(Cli, FormerToleranceSpellingsWarnAndGiveTheSameOutput) {
  const std::size_t n = 300;
  write_npy(path("x.npy"), {n, 3}, random_vec(3 * n, 31, 0, 12));
  write_npy(path("f.npy"), {n, 3}, random_vec(3 * n, 32, -1, 1));
  const std::string mobility =
      "mobility --positions " + path("x.npy") + " --forces " + path("f.npy") + " --radius 0.5 --method fmm ";
  const std::string sample = "sample --positions " + path("x.npy") + " --radius 0.5 --seed 3 --operator fmm ";
  write_npy(path("q.npy"), {n}, random_vec(n, 33, -1, 1));
  const std::string laplace = "laplace --sources " + path("x.npy") + " --charges " + path("q.npy") + " ";
  struct Case {
    std::string command, current, former, warning;
  };
  const std::vector<Case> cases = {
      {mobility, "--tolerance 1e-5", "--eps 1e-5", "rpyfmm: warning: --eps is deprecated; use --tolerance\n"},
      {sample, "--sqrt-tolerance 1e-4", "--tol 1e-4", "rpyfmm: warning: --tol is deprecated; use --sqrt-tolerance\n"},
      {sample, "--tolerance 1e-7", "--eps 1e-7", "rpyfmm: warning: --eps is deprecated; use --tolerance\n"},
      {laplace, "--tolerance 1e-3", "--eps 1e-3", "rpyfmm: warning: --eps is deprecated; use --tolerance\n"},
  };
  for (const Case& c : cases) {
    const Result a = run(c.command + c.current + " --out " + path("a.npy"));
    const Result b = run(c.command + c.former + " --out " + path("b.npy"));
    ASSERT_EQ(a.code, 0) << a.err;
    ASSERT_EQ(b.code, 0) << b.err;
    EXPECT_EQ(b.err, a.err + c.warning);
    EXPECT_EQ(read_npy(path("a.npy")).data, read_npy(path("b.npy")).data) << c.former;
    const Result both = run(c.command + c.current + " " + c.former + " --out " + path("c.npy"));
    EXPECT_EQ(both.code, 0) << both.err;  // the same value twice
  }
  expect_failure(mobility + "--tolerance 1e-5 --eps 1e-4 --out " + path("d.npy"), "different value", "d.npy");
  expect_failure(laplace + "--direct --eps 1e-3 --out " + path("d.npy"), "--eps", "d.npy");
}

TEST_F(Cli, MobilityFmmAndAutoMatchDirect) {
  const std::size_t n = 2000;
  const auto x = random_vec(3 * n, 23, 0, 30);
  const auto f = random_vec(3 * n, 24, -1, 1);
  write_npy(path("x.npy"), {n, 3}, x);
  write_npy(path("f.npy"), {n, 3}, f);
  rpyfmm::rpy::DirectRpy op;
  op.set_positions(x, 0.5);
  std::vector<double> ref(3 * n);
  op.apply(f, ref);
  for (const std::string method : {"fmm", "auto"}) {
    const Result r = run("mobility --positions " + path("x.npy") + " --forces " + path("f.npy") +
                         " --radius 0.5 --method " + method + " --tolerance 1e-5 --out " + path("u.npy") + " --json");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("\"tolerance\":"), std::string::npos) << r.out;
    const Npy out = read_npy(path("u.npy"));
    ASSERT_EQ(out.shape, (std::vector<std::size_t>{n, 3}));
    EXPECT_LE(rel_l2(out.data, ref), 1e-5) << method;
  }
}

TEST_F(Cli, MobilityPseSingleParticleIsHasimoto) {
  // One sphere in a periodic cube: M = mu0 (1 - 2.837297 (a/L) + (4 pi / 3) (a/L)^3) I, exact for RPY
  // (Hasimoto, J. Fluid Mech. 5 (1959) 317; docs/theory/pse.md), reached through the CLI's --method pse --box.
  write_npy(path("x1.npy"), {1, 3}, {1.0, 2.0, 3.0});
  write_npy(path("f1.npy"), {1, 3}, {1.0, -2.0, 0.5});
  const double a = 0.5, L = 10.0;
  const Result r = run("mobility --positions " + path("x1.npy") + " --forces " + path("f1.npy") +
                       " --radius 0.5 --method pse --box 10 --tolerance 1e-6 --out " + path("u1.npy"));
  ASSERT_EQ(r.code, 0) << r.err;
  const Npy out = read_npy(path("u1.npy"));
  const double mu = (1.0 - 2.837297 * a / L + 4.0 * M_PI / 3.0 * std::pow(a / L, 3)) / (6.0 * M_PI * a);
  const double f[3] = {1.0, -2.0, 0.5};
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(out.data[k], mu * f[k], 1e-5 * mu * 2.0);
  // --wave-precision single at the same tolerance: float grids, the same answer within float
  // round-off (~1e-7 relative, tests/pse/test_pse_precision.cpp).
  const Result rs =
      run("mobility --positions " + path("x1.npy") + " --forces " + path("f1.npy") +
          " --radius 0.5 --method pse --box 10 --tolerance 1e-6 --wave-precision single --out " + path("u1s.npy"));
  ASSERT_EQ(rs.code, 0) << rs.err;
  const Npy single = read_npy(path("u1s.npy"));
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(single.data[k], out.data[k], 1e-6 * mu * 2.0);
}

TEST_F(Cli, LaplaceBadInput) {
  const std::size_t n = 4;
  write_npy(path("s.npy"), {n, 3}, random_vec(3 * n, 9, -1, 1));
  write_npy(path("q.npy"), {n}, {1, 2, 3, 4});
  write_npy(path("q5.npy"), {5}, {1, 2, 3, 4, 5});
  write_npy(path("q_nan.npy"), {n}, {1, NAN, 3, 4});
  write_npy(path("s2.npy"), {n, 2}, random_vec(2 * n, 10, -1, 1));
  write_npy(path("s_inf.npy"), {n, 3}, {0, 0, 0, 1, 1, 1, 2, INFINITY, 2, 3, 3, 3});
  write_npy(path("s0.npy"), {0, 3}, {});
  write_npy(path("s_trunc.npy"), {n, 3}, random_vec(3 * n, 11, -1, 1), 8);
  write_npy(path("t_nan.npy"), {1, 3}, {0, NAN, 0});
  {
    std::ofstream bad(path("bad.npy"), std::ios::binary);
    bad << "\x93NUMPY garbage";
  }
  {
    std::ofstream txt(path("bad.txt"));
    txt << "1 2 3\n4 five 6\n";
  }
  const std::string S = " --sources " + path("s.npy"), Q = " --charges " + path("q.npy");
  const std::string O = " --out " + path("r.npy");
  expect_failure("laplace --sources " + path("missing.npy") + Q + " --direct" + O, "missing.npy", "r.npy");
  expect_failure("laplace --sources " + path("bad.npy") + Q + " --direct" + O, "bad.npy", "r.npy");
  expect_failure("laplace --sources " + path("s_trunc.npy") + Q + " --direct" + O, "truncated", "r.npy");
  expect_failure("laplace --sources " + path("bad.txt") + Q + " --direct" + O, "not a number", "r.npy");
  expect_failure("laplace --sources " + path("s2.npy") + Q + " --direct" + O, "sources", "r.npy");
  expect_failure("laplace --sources " + path("s_inf.npy") + Q + " --direct" + O, "infinite", "r.npy");
  expect_failure("laplace --sources " + path("s0.npy") + Q + " --direct" + O, "N = 0", "r.npy");
  expect_failure("laplace" + S + " --charges " + path("q5.npy") + " --direct" + O, "charges", "r.npy");
  expect_failure("laplace" + S + " --charges " + path("q_nan.npy") + " --direct" + O, "NaN", "r.npy");
  expect_failure("laplace" + S + Q + " --targets " + path("t_nan.npy") + " --direct" + O, "NaN", "r.npy");
  expect_failure("laplace" + S + Q + O, "--direct or --tolerance", "r.npy");
  expect_failure("laplace" + S + Q + " --direct --tolerance 1e-6" + O, "--tolerance", "r.npy");
  expect_failure("laplace" + S + Q + " --tolerance 0.5" + O, "tolerance", "r.npy");
  expect_failure("laplace" + S + Q + " --tolerance 1e-20" + O, "tolerance", "r.npy");
  expect_failure("laplace" + S + " --direct" + O, "--charges", "r.npy");
  expect_failure("laplace" + S + Q + " --direct", "--out", "r.npy");
  expect_failure("laplace" + S + Q + " --direct --threads -1" + O, "threads", "r.npy");
  // unwritable output: directory does not exist
  expect_failure("laplace" + S + Q + " --direct --out " + path("nodir/r.npy"), "nodir", "nodir");
}

TEST_F(Cli, MobilityBadInput) {
  const std::size_t n = 3;
  write_npy(path("x.npy"), {n, 3}, {0, 0, 0, 3, 0, 0, 0, 3, 0});
  write_npy(path("f.npy"), {n, 3}, {1, 0, 0, 0, 1, 0, 0, 0, 1});
  write_npy(path("f2.npy"), {2, 3}, {1, 0, 0, 0, 1, 0});
  write_npy(path("f_nan.npy"), {n, 3}, {1, 0, 0, 0, NAN, 0, 0, 0, 1});
  write_npy(path("x_inf.npy"), {n, 3}, {0, 0, 0, 3, -INFINITY, 0, 0, 3, 0});
  write_npy(path("x0.npy"), {0, 3}, {});
  write_npy(path("x4.npy"), {n, 4}, std::vector<double>(4 * n, 1.0));
  write_npy(path("a.npy"), {n}, {1, 1, 1});
  write_npy(path("a2.npy"), {2}, {1, 1});
  write_npy(path("a_neg.npy"), {n}, {1, -1, 1});
  write_npy(path("x_trunc.npy"), {n, 3}, std::vector<double>(3 * n, 1.0), 16);
  const std::string X = " --positions " + path("x.npy"), F = " --forces " + path("f.npy");
  const std::string O = " --out " + path("u.npy");
  const std::string good = "mobility" + X + F;
  expect_failure("mobility --positions " + path("nope.npy") + F + " --radius 1" + O, "nope.npy", "u.npy");
  expect_failure("mobility --positions " + path("x_trunc.npy") + F + " --radius 1" + O, "truncated", "u.npy");
  expect_failure("mobility --positions " + path("x4.npy") + F + " --radius 1" + O, "positions", "u.npy");
  expect_failure("mobility --positions " + path("x_inf.npy") + F + " --radius 1" + O, "infinite", "u.npy");
  expect_failure("mobility --positions " + path("x0.npy") + F + " --radius 1" + O, "N = 0", "u.npy");
  expect_failure("mobility" + X + " --forces " + path("f2.npy") + " --radius 1" + O, "forces", "u.npy");
  expect_failure("mobility" + X + " --forces " + path("f_nan.npy") + " --radius 1" + O, "NaN", "u.npy");
  expect_failure(good + " --radius 0" + O, "radius", "u.npy");
  expect_failure(good + " --radius -2" + O, "radius", "u.npy");
  expect_failure(good + " --radius nan" + O, "radius", "u.npy");
  expect_failure(good + " --radius 1 --viscosity 0" + O, "viscosity", "u.npy");
  expect_failure(good + " --radius 1 --viscosity -1" + O, "viscosity", "u.npy");
  expect_failure(good + O, "--radius", "u.npy");
  expect_failure(good + " --radius 1 --radii " + path("a.npy") + O, "--radi", "u.npy");
  expect_failure(good + " --radii " + path("a2.npy") + O, "radii", "u.npy");
  expect_failure(good + " --radii " + path("a_neg.npy") + O, "radius of particle 1", "u.npy");
  expect_failure(good + " --radius 1 --method warp" + O, "unknown method 'warp'", "u.npy");
  expect_failure(good + " --radius 1 --method pse --device cuda" + O, "periodic", "u.npy");  // open PSE: CPU only
  expect_failure(good + " --radius 1 --method fmm --box 10" + O, "open geometry", "u.npy");
  expect_failure(good + " --radius 1 --method fmm --tolerance 0.7" + O, "tolerance", "u.npy");
  expect_failure(good + " --radius 1 --box 10 20" + O, "--box", "u.npy");
  expect_failure(good + " --radius 1 --method pse --box 10 --wave-precision half" + O, "--wave-precision", "u.npy");
  expect_failure(good + " --radius 1 --method fmm --wave-precision single" + O, "pse method only", "u.npy");
  expect_failure(good + " --radius 1 --method pse --box 10 --device gpu" + O, "--device", "u.npy");
  expect_failure(good + " --radius 1 --method fmm --device cuda" + O, "no CUDA version", "u.npy");
  if (!rpyfmm::rpy::pse::PseRpyCuda::device_available()) {
    expect_failure(good + " --radius 1 --method pse --box 10 --device cuda" + O, "no usable CUDA device", "u.npy");
  }
  expect_failure("mobility" + F + " --radius 1" + O, "--positions", "u.npy");
  expect_failure(good + " --radius 1", "--out", "u.npy");
  expect_failure(good + " --radius 1 --threads -3" + O, "threads", "u.npy");
}

namespace {
/// Two bead-shell spheres (42 beads, radius 2) and a tetrahedron of 4 beads, body after body.
struct RigidCase {
  std::vector<double> x;
  std::vector<std::size_t> offsets{0};
  double radius = 0.0;
};
RigidCase rigid_case() {
  RigidCase c;
  const std::vector<double> shell = rpyfmm::rpy::icosphere_beads(1);
  c.radius = 2.0 * rpyfmm::rpy::icosphere_bead_radius(1);
  for (double shift : {0.0, 7.0}) {
    for (std::size_t i = 0; i < shell.size(); ++i) c.x.push_back(2.0 * shell[i] + (i % 3 == 0 ? shift : 0.0));
    c.offsets.push_back(c.x.size() / 3);
  }
  for (double v : {0.0, 9.0, 0.0, 2.0, 9.0, 0.0, 1.0, 10.7, 0.0, 1.0, 9.6, 1.6}) c.x.push_back(v);
  c.offsets.push_back(c.x.size() / 3);
  return c;
}
}  // namespace

// `rpyfmm rigid` gives the library's body velocities and bead forces (same solver and options).
TEST_F(Cli, RigidMatchesLibrary) {
  const RigidCase c = rigid_case();
  const std::size_t n = c.x.size() / 3, m = 3;
  const auto ft = random_vec(6 * m, 12, -1, 1);
  write_npy(path("x.npy"), {n, 3}, c.x);
  write_npy(path("ft.npy"), {m, 6}, ft);
  {
    std::ofstream sizes(path("sizes.txt"));
    sizes << "42\n42\n4\n";
  }
  const Result r =
      run("rigid --positions " + path("x.npy") + " --radius " + std::to_string(c.radius) + " --body-sizes " +
          path("sizes.txt") + " --forces " + path("ft.npy") + " --viscosity 1.5 --solver-tolerance 1e-10 --out " +
          path("uw.npy") + " --bead-forces " + path("lambda.npy") + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"command\":\"rigid\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"iterations\":"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"solver_tolerance\":"), std::string::npos) << r.out;
  const Npy uw = read_npy(path("uw.npy")), lambda = read_npy(path("lambda.npy"));
  ASSERT_EQ(uw.shape, (std::vector<std::size_t>{m, 6}));
  ASSERT_EQ(lambda.shape, (std::vector<std::size_t>{n, 3}));
  rpyfmm::rpy::DirectRpy beads(rpyfmm::rpy::Geometry::open(), 1.5);
  rpyfmm::rpy::RigidBodies bodies(beads, {.tolerance = 1e-10});
  bodies.set_configuration(c.x, std::stod(std::to_string(c.radius)), c.offsets);
  std::vector<double> ref(6 * m), ref_lambda(3 * n);
  bodies.apply(ft, ref, ref_lambda);
  EXPECT_LE(rel_l2(uw.data, ref), 1e-12);
  EXPECT_LE(rel_l2(lambda.data, ref_lambda), 1e-12);
}

TEST_F(Cli, RigidBadInput) {
  const RigidCase c = rigid_case();
  const std::size_t n = c.x.size() / 3;
  write_npy(path("x.npy"), {n, 3}, c.x);
  write_npy(path("ft.npy"), {3, 6}, std::vector<double>(18, 1.0));
  write_npy(path("ft5.npy"), {3, 5}, std::vector<double>(15, 1.0));
  std::vector<double> ft_nan(18, 1.0);
  ft_nan[7] = NAN;
  write_npy(path("ft_nan.npy"), {3, 6}, ft_nan);
  write_npy(path("q2.npy"), {2, 3}, std::vector<double>(6, 0.0));
  auto text = [&](const std::string& name, const std::string& content) {
    std::ofstream(path(name)) << content;
    return path(name);
  };
  const std::string sizes = text("sizes.txt", "42 42 4\n");
  const std::string base = "rigid --positions " + path("x.npy") + " --radius 0.5 --forces " + path("ft.npy");
  const std::string O = " --out " + path("uw.npy");
  expect_failure(base + " --body-sizes " + text("s1.txt", "42 42 5\n") + O, "add up to 89", "uw.npy");
  expect_failure(base + " --body-sizes " + text("s2.txt", "42 42.5 3.5\n") + O, "whole number", "uw.npy");
  expect_failure(base + " --body-sizes " + text("s3.txt", "42 44 2\n") + O, "at least 3", "uw.npy");
  expect_failure(base + " --body-sizes " + text("s4.txt", "84 4\n") + O, "--forces", "uw.npy");
  expect_failure(
      "rigid --positions " + path("x.npy") + " --radius 0.5 --forces " + path("ft5.npy") + " --body-sizes " + sizes + O,
      "--forces", "uw.npy");
  expect_failure("rigid --positions " + path("x.npy") + " --radius 0.5 --forces " + path("ft_nan.npy") +
                     " --body-sizes " + sizes + O,
                 "NaN", "uw.npy");
  expect_failure(base + " --body-sizes " + sizes + " --reference " + path("q2.npy") + O, "--reference", "uw.npy");
  expect_failure(base + " --body-sizes " + sizes + " --solver-tolerance 0" + O, "--solver-tolerance", "uw.npy");
  expect_failure(base + " --body-sizes " + sizes + " --method pse --device cuda" + O, "periodic", "uw.npy");
  expect_failure(base + " --body-sizes " + sizes + " --max-iterations 1 --solver-tolerance 1e-12" + O, "did not reach",
                 "uw.npy");
  expect_failure(base + O, "--body-sizes", "uw.npy");
  expect_failure("rigid --positions " + path("x.npy") + " --forces " + path("ft.npy") + " --body-sizes " + sizes + O,
                 "--radius", "uw.npy");
  // Beads on one line.
  write_npy(path("line.npy"), {3, 3}, {0, 0, 0, 2, 0, 0, 4, 0, 0});
  write_npy(path("ft1.npy"), {1, 6}, std::vector<double>(6, 1.0));
  expect_failure("rigid --positions " + path("line.npy") + " --radius 1 --forces " + path("ft1.npy") +
                     " --body-sizes " + text("s5.txt", "3\n") + O,
                 "one line", "uw.npy");
}

// `rpyfmm rigid-bd` follows the library's RigidBodyDynamics step for step (same seed, options and
// constant body force and torque): frames at 0, every K and the last step, bodies' centroids as
// reference points, identity orientations at t = 0; --beads-out is the last bead configuration.
TEST_F(Cli, RigidBdMatchesLibrary) {
  const RigidCase c = rigid_case();
  const std::size_t n = c.x.size() / 3, m = 3;
  write_npy(path("x.npy"), {n, 3}, c.x);
  std::ofstream(path("sizes.txt")) << "42\n42\n4\n";
  const Result r = run("rigid-bd --positions " + path("x.npy") + " --radius " + std::to_string(c.radius) +
                       " --body-sizes " + path("sizes.txt") +
                       " --dt 0.02 --steps 7 --every 3 --kT 0.5 --seed 9 --body-force 0 0 -1 --body-torque 0.1 0 0"
                       " --out " +
                       path("traj.npy") + " --beads-out " + path("beads.npy") + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"command\":\"rigid-bd\""), std::string::npos) << r.out;
  const Npy traj = read_npy(path("traj.npy")), beads = read_npy(path("beads.npy"));
  ASSERT_EQ(traj.shape, (std::vector<std::size_t>{4, m, 7}));  // steps 0, 3, 6, 7
  ASSERT_EQ(beads.shape, (std::vector<std::size_t>{n, 3}));

  std::vector<double> reference(3 * m, 0.0), shape(c.x.size());
  for (std::size_t k = 0; k < m; ++k) {
    const double count = double(c.offsets[k + 1] - c.offsets[k]);
    for (std::size_t i = c.offsets[k]; i < c.offsets[k + 1]; ++i)
      for (std::size_t d = 0; d < 3; ++d) reference[3 * k + d] += c.x[3 * i + d] / count;
  }
  for (std::size_t k = 0; k < m; ++k)
    for (std::size_t i = c.offsets[k]; i < c.offsets[k + 1]; ++i)
      for (std::size_t d = 0; d < 3; ++d) shape[3 * i + d] = c.x[3 * i + d] - reference[3 * k + d];
  rpyfmm::rpy::DirectRpy op(rpyfmm::rpy::Geometry::open(), 1.0);
  rpyfmm::bd::BodyForceFunction load = [](const rpyfmm::bd::RigidBodyState&, std::span<double> w) {
    for (std::size_t k = 0; k < w.size(); k += 6) w[k + 2] = -1.0, w[k + 3] = 0.1;
  };
  rpyfmm::bd::RigidBodyDynamics sim(op, shape, {std::stod(std::to_string(c.radius))}, c.offsets, reference, {},
                                    {.dt = 0.02, .kT = 0.5, .seed = 9}, load);
  std::size_t frame = 0;
  const auto compare = [&] {
    for (std::size_t k = 0; k < m; ++k) {
      for (std::size_t d = 0; d < 3; ++d)
        EXPECT_NEAR(traj.data[(frame * m + k) * 7 + d], sim.positions()[3 * k + d], 1e-12) << frame;
      for (std::size_t d = 0; d < 4; ++d)
        EXPECT_NEAR(traj.data[(frame * m + k) * 7 + 3 + d], sim.orientations()[4 * k + d], 1e-12) << frame;
    }
    ++frame;
  };
  compare();
  for (int s = 1; s <= 7; ++s) {
    sim.step();
    if (s % 3 == 0 || s == 7) compare();
  }
  EXPECT_LE(rel_l2(beads.data, {sim.bead_positions().begin(), sim.bead_positions().end()}), 1e-13);
  EXPECT_NE(traj.data[7 * m * 3 + 2], traj.data[2]);  // it moved
}

// A restart from the last frame with --first-step continues the run bit for bit: 10 steps in one
// run equal 6 + 4 (noise keyed by the step; frames at multiples of --every in both).
TEST_F(Cli, RigidBdRestartContinuesBitForBit) {
  const RigidCase c = rigid_case();
  const std::size_t n = c.x.size() / 3, m = 3;
  write_npy(path("x.npy"), {n, 3}, c.x);
  std::ofstream(path("sizes.txt")) << "42 42 4\n";
  const std::string base = "rigid-bd --positions " + path("x.npy") + " --radius 0.5 --body-sizes " + path("sizes.txt") +
                           " --dt 0.02 --seed 5 --every 2 --body-force 0 0 -1 --pair soft";
  ASSERT_EQ(run(base + " --steps 10 --out " + path("full.npy")).code, 0);
  ASSERT_EQ(run(base + " --steps 6 --out " + path("first.npy")).code, 0);
  const Result r =
      run(base + " --steps 4 --restart " + path("first.npy") + " --first-step 6 --json --out " + path("second.npy"));
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"last_step\":10"), std::string::npos) << r.out;
  const Npy full = read_npy(path("full.npy")), first = read_npy(path("first.npy")),
            second = read_npy(path("second.npy"));
  ASSERT_EQ(full.shape, (std::vector<std::size_t>{6, m, 7}));    // steps 0, 2, 4, 6, 8, 10
  ASSERT_EQ(first.shape, (std::vector<std::size_t>{4, m, 7}));   // 0, 2, 4, 6
  ASSERT_EQ(second.shape, (std::vector<std::size_t>{3, m, 7}));  // 6 (restart), 8, 10
  for (std::size_t i = 0; i < 3 * m * 7; ++i) EXPECT_EQ(second.data[i], full.data[3 * m * 7 + i]) << i;
  // Without --first-step the noise restarts at step 0: a different continuation.
  ASSERT_EQ(run(base + " --steps 4 --restart " + path("first.npy") + " --out " + path("other.npy")).code, 0);
  EXPECT_NE(read_npy(path("other.npy")).data.back(), full.data.back());
  expect_failure(base + " --steps 2 --restart " + path("x.npy") + " --out " + path("bad.npy"), "--restart", "bad.npy");
}

// In a periodic box a body given wrapped into the box (beads on both sides of a face) keeps its
// shape: the bodies' frames come from minimum images, so the run equals the one from unwrapped
// beads (the same first bead) up to rounding.
TEST_F(Cli, RigidBdWrappedBodyKeepsItsShape) {
  const std::vector<double> shell = rpyfmm::rpy::icosphere_beads(1);
  const double L = 12.0, radius = 2.0 * rpyfmm::rpy::icosphere_bead_radius(1);
  std::vector<double> unwrapped, wrapped;
  std::size_t first = 0;
  while (shell[3 * first] < 0.5) ++first;  // start with a bead inside the box in both inputs
  for (std::size_t j = 0; j < shell.size() / 3; ++j) {
    const std::size_t i = (first + j) % (shell.size() / 3);
    const double p[3] = {0.5 + 2.0 * shell[3 * i], 6.0 + 2.0 * shell[3 * i + 1], 6.0 + 2.0 * shell[3 * i + 2]};
    for (double v : p) unwrapped.push_back(v), wrapped.push_back(v - L * std::floor(v / L));
  }
  ASSERT_NE(unwrapped, wrapped);
  write_npy(path("u.npy"), {42, 3}, unwrapped);
  write_npy(path("w.npy"), {42, 3}, wrapped);
  std::ofstream(path("sizes.txt")) << "42\n";
  const std::string options = " --radius " + std::to_string(radius) + " --body-sizes " + path("sizes.txt") +
                              " --method pse --box 12 --tolerance 1e-6 --kT 0 --dt 0.5 --steps 3 --every 1"
                              " --body-force 0.2 0 -1 --body-torque 0 0.5 0";
  ASSERT_EQ(run("rigid-bd --positions " + path("u.npy") + options + " --out " + path("tu.npy")).code, 0);
  const Result r = run("rigid-bd --positions " + path("w.npy") + options + " --out " + path("tw.npy"));
  ASSERT_EQ(r.code, 0) << r.err;
  const Npy tu = read_npy(path("tu.npy")), tw = read_npy(path("tw.npy"));
  ASSERT_EQ(tu.shape, tw.shape);
  EXPECT_LE(rel_l2(tw.data, tu.data), 1e-10);
  EXPECT_GT(std::abs(tu.data[tu.data.size() - 2] - tu.data[5]), 1e-3);  // it turned about y (quaternion y)
}

TEST_F(Cli, RigidBdBadInput) {
  const RigidCase c = rigid_case();
  const std::size_t n = c.x.size() / 3;
  write_npy(path("x.npy"), {n, 3}, c.x);
  std::ofstream(path("sizes.txt")) << "42 42 4\n";
  std::ofstream(path("bad_sizes.txt")) << "42 42 5\n";
  const std::string base = "rigid-bd --positions " + path("x.npy") + " --radius 0.5 --body-sizes ";
  const std::string sizes = path("sizes.txt"), O = " --out " + path("traj.npy");
  expect_failure(base + sizes + " --dt 0.01 --steps 0" + O, "--steps", "traj.npy");
  expect_failure(base + sizes + " --dt 0 --steps 2" + O, "dt", "traj.npy");
  expect_failure(base + sizes + " --dt 0.01 --steps 2 --kT -1" + O, "kT", "traj.npy");
  expect_failure(base + sizes + " --dt 0.01 --steps 2 --drift fixman" + O, "--drift", "traj.npy");
  expect_failure(base + sizes + " --dt 0.01 --steps 2 --rfd-delta 1" + O, "rfd_delta", "traj.npy");
  expect_failure(base + sizes + " --dt 0.01 --steps 2 --pair square" + O, "square", "traj.npy");
  expect_failure(base + path("bad_sizes.txt") + " --dt 0.01 --steps 2" + O, "add up to", "traj.npy");
  expect_failure(base + sizes + " --dt 0.01 --steps 2 --body-force 0 0 nan" + O, "--body-force", "traj.npy");
  // A blow-up mid-run: nothing is written.
  expect_failure(base + sizes + " --dt 1 --steps 5 --body-force 1e6 0 0" + O, "reduce dt", "traj.npy");
}

namespace {
std::string slurp_file(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}
}  // namespace

// An output naming an input (however spelled) or another output: exit 2 before any work, one
// line naming both options, the input unchanged.
TEST_F(Cli, OutputNamingAnInputOrAnotherOutputIsRefused) {
  const RigidCase c = rigid_case();
  const std::size_t n = c.x.size() / 3;
  write_npy(path("x.npy"), {n, 3}, c.x);
  write_npy(path("f.npy"), {n, 3}, random_vec(3 * n, 31, -1, 1));
  write_npy(path("q.npy"), {n}, random_vec(n, 32, -1, 1));
  write_npy(path("ft.npy"), {3, 6}, std::vector<double>(18, 1.0));
  std::ofstream(path("sizes.txt")) << "42 42 4\n";
  const std::string x = slurp_file(path("x.npy")), f = slurp_file(path("f.npy")), q = slurp_file(path("q.npy"));
  const auto refused = [&](const std::string& args, const std::string& out_option, const std::string& other) {
    const Result r = run(args);
    EXPECT_EQ(r.code, 2) << args << "\nstderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(out_option), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(other), std::string::npos) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
  };
  const std::string mob = "mobility --positions " + path("x.npy") + " --forces " + path("f.npy") + " --radius 0.5";
  refused(mob + " --out " + path("x.npy"), "--out", "--positions");
  refused(mob + " --out " + dir_.string() + "/./x.npy", "--out", "--positions");
  refused(mob + " --out " + path("f.npy"), "--out", "--forces");
  refused("laplace --sources " + path("x.npy") + " --charges " + path("q.npy") + " --direct --out " + path("q.npy"),
          "--out", "--charges");
  const std::string bodies = " --positions " + path("x.npy") + " --radius 0.5 --body-sizes " + path("sizes.txt");
  refused("rigid-bd" + bodies + " --dt 0.01 --steps 1 --out " + path("t.npy") + " --beads-out " + path("x.npy"),
          "--beads-out", "--positions");
  refused("rigid" + bodies + " --forces " + path("ft.npy") + " --out " + path("uw.npy") + " --bead-forces " +
              path("uw.npy"),
          "--bead-forces", "--out");
  EXPECT_EQ(slurp_file(path("x.npy")), x);
  EXPECT_EQ(slurp_file(path("f.npy")), f);
  EXPECT_EQ(slurp_file(path("q.npy")), q);
  EXPECT_FALSE(fs::exists(path("uw.npy")));
  EXPECT_FALSE(fs::exists(path("t.npy")));
}

// --out naming a FIFO, a directory or a symbolic link: exit 2, one line naming it, the target
// left as it was (a FIFO stays a FIFO; the link's target keeps its content).
TEST_F(Cli, OutputThatIsNotARegularFileIsRefused) {
  write_npy(path("x.npy"), {2, 3}, {0, 0, 0, 3, 0, 0});
  write_npy(path("f.npy"), {2, 3}, {1, 0, 0, 0, 1, 0});
  ASSERT_EQ(::mkfifo(path("fifo").c_str(), 0600), 0);
  fs::create_directory(path("sub"));
  std::ofstream(path("precious")) << "keep me\n";
  fs::create_symlink(path("precious"), path("link.npy"));
  const std::string mob = "mobility --positions " + path("x.npy") + " --forces " + path("f.npy") + " --radius 0.5";
  for (const std::string target : {"fifo", "sub", "link.npy"}) {
    const Result r = run(mob + " --out " + path(target));
    EXPECT_EQ(r.code, 2) << target << "\nstderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find(path(target)), std::string::npos) << r.err;
  }
  EXPECT_TRUE(fs::is_fifo(fs::symlink_status(path("fifo"))));
  EXPECT_TRUE(fs::is_directory(path("sub")));
  EXPECT_TRUE(fs::is_symlink(path("link.npy")));
  EXPECT_EQ(slurp_file(path("precious")), "keep me\n");
  for (const auto& e : fs::directory_iterator(dir_))  // no temporary left behind
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
}

// `rpyfmm bd` with two outputs in one file: exit 2 at start-up, one line naming both keys, no
// output directory. A --restart that is a directory: one line naming it.
TEST_F(Cli, BdRefusesCollidingOutputsAndBadCheckpointPaths) {
  const std::string base =
      "[[types]]\nname = \"A\"\nradius = 1.0\n[particles]\nsource = \"random\"\ncount = 10\n"
      "volume_fraction = 0.01\n[integrator]\ndt = 0.001\nsteps = 2\n[mobility]\nmethod = \"none\"\n[output]\n";
  for (const auto& [line, key] : {std::pair<std::string, std::string>{"log = \"trajectory.xyz\"\n", "output.log"},
                                  {"checkpoint = \"trajectory.xyz\"\n", "output.checkpoint"}}) {
    std::ofstream(path("run.toml")) << base << line;
    const Result r = run("bd --config " + path("run.toml") + " --out-dir " + path("out") + " --quiet");
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find("output.trajectory"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(key), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(path("out")));
  }
  const Result r = run("bd --restart " + dir_.string() + " --quiet");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(dir_.string()), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("directory"), std::string::npos) << r.err;
}

// `rpyfmm bd --restart` of run A's checkpoint with run B's directory as --out-dir: exit 2, one line
// naming B's trajectory, and B's files left byte for byte.
TEST_F(Cli, BdRestartRefusesAnotherRunsFiles) {
  const std::string base =
      "[[types]]\nname = \"A\"\nradius = 1.0\n[particles]\nsource = \"random\"\ncount = 10\n"
      "volume_fraction = 0.01\n[mobility]\nmethod = \"none\"\n[output]\ntrajectory_every = 2\nlog_every = 2\n"
      "[integrator]\ndt = 0.001\nsteps = 8\n";
  std::ofstream(path("a.toml")) << base;
  std::ofstream(path("b.toml")) << base << "seed = 2\n";
  ASSERT_EQ(run("bd --config " + path("a.toml") + " --steps 4 --out-dir " + path("a") + " --quiet").code, 0);
  ASSERT_EQ(run("bd --config " + path("b.toml") + " --out-dir " + path("b") + " --quiet").code, 0);
  const std::string traj = slurp_file(path("b/trajectory.xyz")), log = slurp_file(path("b/log.csv"));
  const Result r = run("bd --restart " + path("a/checkpoint.bin") + " --out-dir " + path("b") + " --quiet");
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(path("b/trajectory.xyz")), std::string::npos) << r.err;
  EXPECT_EQ(slurp_file(path("b/trajectory.xyz")), traj);
  EXPECT_EQ(slurp_file(path("b/log.csv")), log);
  // Its own directory continues.
  EXPECT_EQ(run("bd --restart " + path("a/checkpoint.bin") + " --steps 8 --quiet").code, 0);
}

TEST_F(Cli, SimdLevelIsReportedAndItsOverrideChecked) {
  // --json names the instruction-set level in use; RPYFMM_SIMD lowers it (scalar runs
  // everywhere) and a value that names no level is one line and exit 2, before any work.
  const std::size_t n = 40;
  write_npy(path("s.npy"), {n, 3}, random_vec(3 * n, 61, -1, 1));
  write_npy(path("q.npy"), {n}, random_vec(n, 62, -1, 1));
  const std::string args =
      "laplace --sources " + path("s.npy") + " --charges " + path("q.npy") + " --direct --out " + path("r.npy");
  const Result native = run(args + " --json");
  ASSERT_EQ(native.code, 0) << native.err;
  EXPECT_NE(native.out.find("\"simd\":\"" + std::string(rpyfmm::simd_level_name(rpyfmm::simd_level())) + "\""),
            std::string::npos)
      << native.out;
  const Result scalar = run_with_env("RPYFMM_SIMD=scalar", args + " --json");
  ASSERT_EQ(scalar.code, 0) << scalar.err;
  EXPECT_NE(scalar.out.find("\"simd\":\"scalar\""), std::string::npos) << scalar.out;
  fs::remove(path("r.npy"));
  const Result typo = run_with_env("RPYFMM_SIMD=avx3", args);
  EXPECT_EQ(typo.code, 2) << typo.err;
  EXPECT_EQ(std::count(typo.err.begin(), typo.err.end(), '\n'), 1) << typo.err;
  EXPECT_NE(typo.err.find("RPYFMM_SIMD"), std::string::npos) << typo.err;
  EXPECT_FALSE(fs::exists(path("r.npy")));
}

// Under an MPI launcher (apps/rpyfmm/mpi_session.hpp): a build without MPI would run the serial
// command once per process over one output file, so a launch on several processes and --mpi are
// refused with one line and exit status 2; a launcher's single process runs as usual. (Builds
// with MPI are tested under mpiexec: tests/mpi/cli_mobility.cmake.)
#if !defined(RPYFMM_CLI_HAS_MPI)
TEST_F(Cli, BuildWithoutMpiRefusesSeveralRanksAndTheMpiFlag) {
  write_npy(path("x.npy"), {2, 3}, {0, 0, 0, 3, 0, 0});
  write_npy(path("f.npy"), {2, 3}, {1, 0, 0, 0, 1, 0});
  const std::string args =
      "mobility --positions " + path("x.npy") + " --forces " + path("f.npy") + " --radius 1 --out " + path("u.npy");
  for (const std::string env : {"OMPI_COMM_WORLD_SIZE=2", "PMI_SIZE=3"}) {
    const Result r = run_with_env(env, args);
    EXPECT_EQ(r.code, 2) << env << "\nstderr: " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_NE(r.err.find("built without MPI"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(path("u.npy")));
  }
  expect_failure("--mpi " + args, "--mpi: this rpyfmm was built without MPI", "u.npy");
  const Result one = run_with_env("OMPI_COMM_WORLD_SIZE=1", args);
  EXPECT_EQ(one.code, 0) << one.err;
  EXPECT_TRUE(fs::exists(path("u.npy")));
}
#endif
