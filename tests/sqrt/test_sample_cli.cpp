// `rpyfmm sample` end to end: runs the binary (RPYFMM_CLI) on text inputs
// written here, reads its .npy output, and compares with the library called
// directly; bad input gives exit code 2, one line on stderr and no output file.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "rpyfmm/bd/rotation_sampling.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "sqrt_test_util.hpp"

namespace fs = std::filesystem;
using namespace rpyfmm::rpy;

namespace {

fs::path scratch() {
  static const fs::path dir = [] {
    fs::path d = fs::temp_directory_path() / ("rpyfmm_sample_cli_" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

void write_text(const fs::path& p, const std::vector<double>& v, std::size_t cols) {
  std::ofstream f(p);
  f.precision(17);
  for (std::size_t i = 0; i < v.size(); ++i) f << v[i] << ((i + 1) % cols == 0 ? "\n" : " ");
}

/// Minimal reader of a little-endian float64 C-order .npy written by the CLI.
std::vector<double> read_npy(const fs::path& p, std::vector<std::size_t>& shape) {
  std::ifstream f(p, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_EQ(bytes.substr(1, 5), "NUMPY");
  const std::size_t hlen = static_cast<unsigned char>(bytes[8]) | (static_cast<unsigned char>(bytes[9]) << 8);
  const std::string header = bytes.substr(10, hlen);
  EXPECT_NE(header.find("<f8"), std::string::npos) << header;
  shape.clear();
  std::istringstream in(header.substr(header.find("'shape': (") + 10));
  std::size_t v;
  char c;
  while (in >> v) {
    shape.push_back(v);
    in >> c;
    if (c == ')') break;
  }
  std::vector<double> data((bytes.size() - 10 - hlen) / 8);
  std::memcpy(data.data(), bytes.data() + 10 + hlen, data.size() * 8);
  return data;
}

struct CliResult {
  int rc;
  std::string out, err;
};

CliResult run_cli(const std::string& args) {
  const fs::path o = scratch() / "stdout.txt", e = scratch() / "stderr.txt";
  const std::string cmd = std::string(RPYFMM_CLI) + " sample " + args + " > " + o.string() + " 2> " + e.string();
  const int status = std::system(cmd.c_str());
  CliResult r;
  r.rc = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream fo(o), fe(e);
  r.out.assign(std::istreambuf_iterator<char>(fo), {});
  r.err.assign(std::istreambuf_iterator<char>(fe), {});
  return r;
}

class SampleCli : public ::testing::Test {
 protected:
  static constexpr std::size_t N = 40;
  std::vector<double> x = sqrt_test::random_points(N, 0.1, 3u);
  std::vector<double> a = sqrt_test::radii(N, true, 4u);
  fs::path xp = scratch() / "x.txt", ap = scratch() / "a.txt", out = scratch() / "w.npy";
  void SetUp() override {
    write_text(xp, x, 3);
    write_text(ap, a, 1);
    fs::remove(out);
  }
  std::vector<double> expected(const std::vector<double>& z, const std::vector<double>& radii, SqrtMethod m,
                               double tol) {
    DirectRpy op(Geometry::open(), 1.0);
    op.set_positions(x, radii);
    std::vector<double> w(3 * N);
    SqrtOptions opt;
    opt.method = m;
    opt.tolerance = tol;
    op.apply_sqrt(z, w, opt);
    return w;
  }
};

double max_rel_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0, s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    d = std::max(d, std::abs(a[i] - b[i]));
    s = std::max(s, std::abs(b[i]));
  }
  return d / s;
}

TEST_F(SampleCli, SeedMatchesLibraryAndJsonReports) {
  const CliResult r = run_cli("--positions " + xp.string() +
                              " --radius 1 --seed 17 --step 4 --sqrt-tolerance 1e-5 --out " + out.string() + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  std::vector<std::size_t> shape;
  const auto w = read_npy(out, shape);
  EXPECT_EQ(shape, (std::vector<std::size_t>{N, 3}));
  std::vector<double> z(3 * N);
  fill_normal(z, 17u, 4u);
  EXPECT_LE(max_rel_diff(w, expected(z, std::vector<double>(N, 1.0), SqrtMethod::lanczos, 1e-5)), 1e-12);
  for (const char* key : {"\"iterations\":", "\"error_estimate\":", "\"method\":\"lanczos\"", "\"seed\":17"})
    EXPECT_NE(r.out.find(key), std::string::npos) << key << " in " << r.out;
}

TEST_F(SampleCli, NoiseFileRadiiAndMethods) {
  std::vector<double> z(3 * N);
  fill_normal(z, 5u, 0u);
  const fs::path zp = scratch() / "z.txt";
  write_text(zp, z, 3);
  for (SqrtMethod m : {SqrtMethod::lanczos, SqrtMethod::chebyshev, SqrtMethod::cholesky, SqrtMethod::eigen}) {
    fs::remove(out);
    const CliResult r =
        run_cli("--positions " + xp.string() + " --radii " + ap.string() + " --noise " + zp.string() + " --method " +
                to_string(m) + " --sqrt-tolerance 1e-6 --out " + out.string() + " --threads 1");
    ASSERT_EQ(r.rc, 0) << r.err;
    std::vector<std::size_t> shape;
    EXPECT_LE(max_rel_diff(read_npy(out, shape), expected(z, a, m, 1e-6)), 1e-12) << to_string(m);
  }
}

// The FMM operator gives the direct result to about its tolerance.
TEST_F(SampleCli, FmmOperatorMatchesDirect) {
  std::vector<double> z(3 * N);
  fill_normal(z, 8u, 0u);
  const CliResult r =
      run_cli("--positions " + xp.string() + " --radii " + ap.string() +
              " --seed 8 --operator fmm --tolerance 1e-9 --sqrt-tolerance 1e-8 --out " + out.string() + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("\"operator\":\"fmm\""), std::string::npos) << r.out;
  std::vector<std::size_t> shape;
  EXPECT_LE(max_rel_diff(read_npy(out, shape), expected(z, a, SqrtMethod::lanczos, 1e-8)), 1e-6);
}

// `--method pse` = the periodic PSE operator with its split sampler: it equals the library's
// PseRpy::apply_sqrt on the same Philox noise, bit for bit (same code, deterministic).
TEST_F(SampleCli, PseSplitSamplerMatchesLibrary) {
  const CliResult r = run_cli("--positions " + xp.string() + " --radius 1 --seed 9 --method pse --box 60 --out " +
                              out.string() + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("\"operator\":\"pse\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"method\":\"split\""), std::string::npos) << r.out;
  std::vector<double> z(3 * N), w(3 * N);
  fill_normal(z, 9u, 0u);
  rpyfmm::rpy::pse::PseRpy op(rpyfmm::rpy::Geometry::periodic(60.0), 1.0);
  op.set_positions(x, 1.0);
  op.apply_sqrt(z, w);
  std::vector<std::size_t> shape;
  EXPECT_LE(max_rel_diff(read_npy(out, shape), w), 1e-12);
}

// Without --box, `--method pse` is PSE with open boundaries (OpenPseRpy), equal to the library's.
TEST_F(SampleCli, OpenPseSplitSamplerMatchesLibrary) {
  const CliResult r =
      run_cli("--positions " + xp.string() + " --radius 1 --seed 9 --method pse --out " + out.string() + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("\"method\":\"split\""), std::string::npos) << r.out;
  std::vector<double> z(3 * N), w(3 * N);
  fill_normal(z, 9u, 0u);
  rpyfmm::rpy::pse::OpenPseRpy op(1.0);
  op.set_positions(x, 1.0);
  op.apply_sqrt(z, w);
  std::vector<std::size_t> shape;
  EXPECT_LE(max_rel_diff(read_npy(out, shape), w), 1e-12);
}

// --preconditioner block: the library's preconditioned sampler (B z, B B^T = M) on the same noise.
TEST_F(SampleCli, BlockPreconditionerMatchesLibrary) {
  for (const SqrtMethod method : {SqrtMethod::lanczos, SqrtMethod::chebyshev}) {
    const CliResult r = run_cli("--positions " + xp.string() + " --radius 1 --seed 6 --sqrt-tolerance 1e-6 --method " +
                                to_string(method) + " --preconditioner block --preconditioner-block 16 --out " +
                                out.string() + " --json");
    ASSERT_EQ(r.rc, 0) << r.err;
    std::vector<double> z(3 * N), w(3 * N);
    fill_normal(z, 6u, 0u);
    DirectRpy op(rpyfmm::rpy::Geometry::open(), 1.0);
    op.set_positions(x, 1.0);
    const SqrtReport rep = op.apply_sqrt(z, w,
                                         SqrtOptions{.method = method,
                                                     .tolerance = 1e-6,
                                                     .preconditioner = SqrtPreconditioner::block,
                                                     .preconditioner_block = 16});
    EXPECT_NE(r.out.find("\"preconditioner_blocks\":" + std::to_string(rep.preconditioner_blocks)), std::string::npos)
        << r.out;
    EXPECT_GT(rep.preconditioner_blocks, 1u);
    std::vector<std::size_t> shape;
    EXPECT_LE(max_rel_diff(read_npy(out, shape), w), 1e-12) << to_string(method);
  }
}

/// The library's grand-mobility sample on the (N, 6) noise rows z (z_t then z_r per particle), as
/// (N, 6) rows w_t then w_r.
std::vector<double> rotation_rows(const MobilityOperator& op, const std::vector<double>& z,
                                  const SqrtOptions& options) {
  const std::size_t n = op.size();
  std::vector<double> zt(3 * n), zr(3 * n), wt(3 * n), wr(3 * n), rows(6 * n);
  for (std::size_t k = 0; k < 3 * n; ++k) {
    zt[k] = z[6 * (k / 3) + k % 3];
    zr[k] = z[6 * (k / 3) + 3 + k % 3];
  }
  op.apply_sqrt_rotation(zt, zr, wt, wr, options);
  for (std::size_t k = 0; k < 3 * n; ++k) {
    rows[6 * (k / 3) + k % 3] = wt[k];
    rows[6 * (k / 3) + 3 + k % 3] = wr[k];
  }
  return rows;
}

// --angular: (N, 6) rows w_t then w_r, the library's apply_sqrt_rotation on the same noise (bit for
// bit: the same code); drawn noise is z_t = the translational draw without --angular and z_r from
// BD's rotational stream, so that --seed/--step give a BD step's noise.
TEST_F(SampleCli, AngularMatchesLibrary) {
  DirectRpy op(Geometry::open(), 1.0);
  op.set_positions(x, a);
  std::vector<double> z(6 * N), zt(3 * N), zr(3 * N);
  fill_normal(zt, 11u, 2u);
  fill_normal(zr, 11u, 2u, rpyfmm::bd::kRotationNoiseStream);
  for (std::size_t k = 0; k < 3 * N; ++k) {
    z[6 * (k / 3) + k % 3] = zt[k];
    z[6 * (k / 3) + 3 + k % 3] = zr[k];
  }
  const CliResult r = run_cli("--positions " + xp.string() + " --radii " + ap.string() +
                              " --seed 11 --step 2 --angular --sqrt-tolerance 1e-6 --out " + out.string() + " --json");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("\"angular\":true"), std::string::npos) << r.out;
  std::vector<std::size_t> shape;
  const auto w = read_npy(out, shape);
  EXPECT_EQ(shape, (std::vector<std::size_t>{N, 6}));
  EXPECT_LE(max_rel_diff(w, rotation_rows(op, z, {.tolerance = 1e-6})), 1e-12);

  // The FMM operator with rotation: the direct result to about its tolerance.
  const std::string fmm = " --angular --operator fmm --tolerance 1e-9 --sqrt-tolerance 1e-8 --out ";
  const CliResult fmm_run =
      run_cli("--positions " + xp.string() + " --radii " + ap.string() + " --seed 11 --step 2" + fmm + out.string());
  ASSERT_EQ(fmm_run.rc, 0) << fmm_run.err;
  EXPECT_LE(max_rel_diff(read_npy(out, shape), rotation_rows(op, z, {.tolerance = 1e-8})), 1e-6);

  // PSE (equal radii, periodic) with its split sampler on the 6N operator: the library's result on
  // the same noise, bit for bit.
  const CliResult pse_run =
      run_cli("--positions " + xp.string() + " --radius 1 --seed 11 --step 2 --angular --method pse --box 60 --out " +
              out.string());
  ASSERT_EQ(pse_run.rc, 0) << pse_run.err;
  rpyfmm::rpy::pse::PseRpy pse(Geometry::periodic(60.0), 1.0);
  pse.set_positions(x, 1.0);
  std::vector<double> pt(3 * N), pr(3 * N);
  pse.apply_sqrt_rotation(zt, zr, pt, pr, {.method = SqrtMethod::split});
  const auto pw = read_npy(out, shape);
  for (std::size_t i = 0; i < N; ++i)
    for (std::size_t c = 0; c < 3; ++c) {
      EXPECT_EQ(pw[6 * i + c], pt[3 * i + c]) << i;
      EXPECT_EQ(pw[6 * i + 3 + c], pr[3 * i + c]) << i;
    }

  const fs::path zp = scratch() / "z6.txt";
  write_text(zp, z, 6);
  for (const SqrtOptions& options :
       {SqrtOptions{.method = SqrtMethod::eigen}, SqrtOptions{.method = SqrtMethod::chebyshev, .tolerance = 1e-6},
        SqrtOptions{.method = SqrtMethod::lanczos,
        .tolerance = 1e-6,
        .preconditioner = SqrtPreconditioner::block,
        .preconditioner_block = 8}}) {
    fs::remove(out);
    const bool block = options.preconditioner == SqrtPreconditioner::block;
    const CliResult rf =
        run_cli("--positions " + xp.string() + " --radii " + ap.string() + " --noise " + zp.string() +
                " --angular --method " + to_string(options.method) + " --sqrt-tolerance 1e-6" +
                (block ? " --preconditioner block --preconditioner-block 8" : "") + " --out " + out.string());
    ASSERT_EQ(rf.rc, 0) << rf.err;
    EXPECT_LE(max_rel_diff(read_npy(out, shape), rotation_rows(op, z, options)), 1e-12) << to_string(options.method);
  }
}

TEST_F(SampleCli, BadInputExitTwoNoOutput) {
  const std::string base = "--positions " + xp.string() + " --out " + out.string() + " ";
  std::vector<double> zshort(3 * (N - 1), 0.5);
  const fs::path zs = scratch() / "zshort.txt";
  write_text(zs, zshort, 3);
  std::vector<double> xnan = x;
  xnan[10] = std::nan("");
  const fs::path xn = scratch() / "xnan.txt";
  write_text(xn, xnan, 3);
  const fs::path z3 = scratch() / "z3.txt", z6nan = scratch() / "z6nan.txt";
  write_text(z3, std::vector<double>(3 * N, 0.5), 3);
  std::vector<double> z6(6 * N, 0.5);
  z6[6 * 2 + 4] = std::nan("");
  write_text(z6nan, z6, 6);
  struct Bad {
    std::string args, needle;
  };
  for (const Bad& b : std::vector<Bad>{
           {base + "--radius 1 --sqrt-tolerance 0", "tolerance must lie in (0, 1)"},
           {base + "--radius 1 --sqrt-tolerance 1", "tolerance must lie in (0, 1)"},
           {base + "--radius 1 --sqrt-tolerance -1e-3", "tolerance"},
           {base + "--radius 1 --noise " + zs.string(), "noise"},
           {base + "--radius 1 --noise " + zs.string() + " --seed 3", "excludes"},
           {base + "--radius 1 --method krylov", "unknown method 'krylov'"},
           {base + "--radius 1 --operator fmm --tolerance 0.5", "--tolerance"},
           {base + "--radius 1 --operator magic", "unknown operator 'magic'"},
           {base + "--radius 1 --tolerance 1e-6", "--tolerance"},
           {base + "--radius -1", "radius"},
           {base, "exactly one of --radius"},
           {base + "--radius 1 --max-iterations -2", "max-iterations"},
           {base + "--radius 1 --preconditioner jacobi", "--preconditioner"},
           {base + "--radius 1 --preconditioner block --method eigen", "Lanczos and Chebyshev samplers only"},
           {base + "--radius 1 --preconditioner-block -3", "--preconditioner-block"},
           {base + "--radius 1 --box 50", "--operator pse"},
           {base + "--radius 1 --operator pse --box 30 40", "--box"},
           {base + "--radius 1 --operator pse --device cuda", "periodic box"},  // open PSE runs on the CPU
           {base + "--radius 1 --method split", "PSE"},
           {base + "--radius 1 --method pse --operator fmm", "cannot be combined"},
           {base + "--radius 1 --method pse --box 60 --wave-precision quad", "--wave-precision"},
           {base + "--radius 1 --wave-precision single", "pse operator only"},
           {base + "--radius 1 --method pse --box 60 --device gpu", "--device"},
           {base + "--radius 1 --device cuda", "pse operator only"},
           {base + "--radius 1 --angular --method split", "PSE"},
           {base + "--radius 1 --angular --noise " + zs.string(), "with --angular must have shape (40,6)"},
           {base + "--radius 1 --angular --noise " + z3.string(), "3 columns"},
           {base + "--radius 1 --angular --noise " + z6nan.string(), "noise entry (2, 4) is NaN"},
           {"--positions " + xn.string() + " --radius 1 --out " + out.string(), "NaN"},
           {"--positions " + (scratch() / "missing.txt").string() + " --radius 1 --out " + out.string(), "missing.txt"},
       }) {
    const CliResult r = run_cli(b.args);
    EXPECT_EQ(r.rc, 2) << b.args;
    EXPECT_NE(r.err.find(b.needle), std::string::npos) << b.args << " -> " << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_FALSE(fs::exists(out)) << b.args;
  }
}

}  // namespace
