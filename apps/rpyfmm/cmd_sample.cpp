// rpyfmm CLI — `rpyfmm sample`: Brownian displacements w = M^{1/2} z of N
// spheres under the Rotne-Prager-Yamakawa mobility (docs/theory/samplers.md).
//
//   rpyfmm sample --positions X.npy (--radius a | --radii R.npy)
//                 [--noise Z.npy | --seed S [--step K]]
//                 [--method auto|lanczos|chebyshev|cholesky|eigen|split|pse]
//                 [--operator direct|fmm|pse] [--box L | --box Lx Ly Lz]
//                 [--sqrt-tolerance 1e-3] [--max-iterations M] [--tolerance E]
//                 [--wave-precision auto|single|double]
//                 [--device cpu|cuda] [--preconditioner none|block|auto [--preconditioner-block B]]
//                 [--viscosity 1] [--angular]
//                 --out W.npy [--threads N] [--json]
//
// W has shape (N,3). Without --noise, z is drawn with the counter-based
// generator (rpy/random.hpp) keyed by (seed, step, particle): the same on any
// thread count. --angular samples the grand mobility with rotation instead
// (MobilityOperator::apply_sqrt_rotation; operators with supports_rotation()): W and the noise
// Z then have shape (N,6), rows w_t (x y z) then w_r (x y z), as `rpyfmm mobility --angular`
// writes U then W; the drawn z_t is the one without --angular (stream 0) and z_r comes from
// the rotational stream of BD (rpyfmm/bd/rotation_sampling.hpp), so that --seed S --step K
// gives the noise of BD step K. --tolerance is the operator's (fmm: default 1e-6); keep it below
// --sqrt-tolerance, since the square root cannot be more accurate than M. With --json, one line reports the iterations,
// the error estimate and the number of operator products. --preconditioner block (Lanczos, Chebyshev) gives w = B z
// with B B^T = M instead of M^{1/2} z, in fewer products (rpy/block_preconditioner.hpp).
#include <CLI/CLI.hpp>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "array_io.hpp"
#include "cli_common.hpp"
#include "commands.hpp"
#include "mpi_session.hpp"
#include "rpyfmm/bd/rotation_sampling.hpp"
#include "rpyfmm/core/cpu_features.hpp"
#include "rpyfmm/core/file_safety.hpp"
#include "rpyfmm/core/timer.hpp"
#include "rpyfmm/core/validate.hpp"
#include "rpyfmm/rpy/direct_operator.hpp"
#include "rpyfmm/rpy/fmm_operator.hpp"
#include "rpyfmm/rpy/mobility_factory.hpp"
#include "rpyfmm/rpy/pse/open_pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy.hpp"
#include "rpyfmm/rpy/pse/pse_rpy_cuda.hpp"
#include "rpyfmm/rpy/random.hpp"
#include "rpyfmm/rpy/sqrt.hpp"
#include "sqrt_report_json.hpp"

namespace rpyfmm::cli {
namespace {

struct SampleArgs {
  std::string positions, radii, noise, out;
  double radius = 0.0;
  double viscosity = 1.0;
  std::uint64_t seed = 0;
  std::uint64_t step = 0;
  std::string method = "auto";
  std::string op = "direct";
  std::vector<double> box;  // periodic box for --operator pse: L or Lx Ly Lz
  double sqrt_tolerance = 1e-3;
  double tolerance = 0.0;               // operator (fmm, pse) tolerance; 0 = not given
  std::string wave_precision = "auto";  // pse operator: auto | single | double
  std::string device = "cpu";           // pse operator: cpu | cuda
  int max_iterations = 0;
  std::string preconditioner = "none";  // none | block | auto
  int preconditioner_block = 0;
  bool angular = false;  // (N, 6): the grand mobility with rotation
  CommonOptions common;
  std::string io = "collective";  // --io, across MPI ranks
};

// ---- operators ----------------------------------------------------------
// One entry per --operator value; an entry with an empty factory is known but
// not built yet and is rejected with a clear message.
// "pse" is the PSE operator, periodic with --box and with open boundaries without; its own split sampler is
// used with --method auto (the default) or split.
struct OperatorEntry {
  const char* name;
  bool uses_tolerance;  // whether --tolerance means something for this operator
  std::function<std::unique_ptr<rpy::MobilityOperator>(const SampleArgs&)> make;
};

const std::vector<OperatorEntry>& operators() {
  static const std::vector<OperatorEntry> table = {
      {"direct", false,
       [](const SampleArgs& a) { return std::make_unique<rpy::DirectRpy>(rpy::Geometry::open(), a.viscosity); }},
      {"fmm", true,
       [](const SampleArgs& a) {
         rpy::FmmRpyOptions o;  // tolerance default 1e-6 unless --tolerance
         if (a.tolerance != 0.0) o.tolerance = a.tolerance;
         return std::make_unique<rpy::FmmRpy>(rpy::Geometry::open(), a.viscosity, o);
       }},
      {"pse", true,
       [](const SampleArgs& a) {
         require(a.box.empty() || a.box.size() == 1 || a.box.size() == 3, ErrorCode::invalid_argument, "--box",
                 "give one length L (cube) or three lengths Lx Ly Lz, got " + std::to_string(a.box.size()) + " values");
         rpy::pse::PseOptions o;  // tolerance default 1e-3 unless --tolerance
         if (a.tolerance != 0.0) o.tolerance = a.tolerance;
         o.wave_precision = rpy::pse::wave_precision_from_name(a.wave_precision, "--wave-precision");
         const bool cuda = rpy::compute_device_from_string(a.device, "--device") == rpy::ComputeDevice::cuda;
         if (a.box.empty()) {  // free space: PSE with open boundaries (CPU)
           require(!cuda, ErrorCode::not_supported, "--device",
                   "cuda needs a periodic box (--box); PSE with open boundaries runs on the CPU");
           return std::unique_ptr<rpy::MobilityOperator>(std::make_unique<rpy::pse::OpenPseRpy>(a.viscosity, o));
         }
         const rpy::Geometry g = a.box.size() == 1 ? rpy::Geometry::periodic(a.box[0])
                                                   : rpy::Geometry::periodic(a.box[0], a.box[1], a.box[2]);
         if (cuda) {
           require(rpy::pse::PseRpyCuda::device_available(), ErrorCode::not_supported, "--device",
                   "cuda: no usable CUDA device (or a build without CUDA)");
           return std::unique_ptr<rpy::MobilityOperator>(std::make_unique<rpy::pse::PseRpyCuda>(g, a.viscosity, o));
         }
         return std::unique_ptr<rpy::MobilityOperator>(std::make_unique<rpy::pse::PseRpy>(g, a.viscosity, o));
       }},
  };
  return table;
}

const OperatorEntry& find_operator(const std::string& name) {
  std::string known;
  for (const auto& e : operators()) {
    if (name == e.name) {
      if (!e.make) fail(ErrorCode::not_supported, "--operator", "operator '" + name + "' is not available yet");
      return e;
    }
    known += (known.empty() ? "" : ", ") + std::string(e.name);
  }
  fail(ErrorCode::invalid_argument, "--operator", "unknown operator '" + name + "' (known: " + known + ")");
}
// -------------------------------------------------------------------------

rpy::SqrtMethod parse_method(const std::string& name) {
  if (name == "auto") return rpy::SqrtMethod::automatic;
  for (auto m : {rpy::SqrtMethod::lanczos, rpy::SqrtMethod::chebyshev, rpy::SqrtMethod::cholesky,
                 rpy::SqrtMethod::eigen, rpy::SqrtMethod::split}) {
    if (name == rpy::to_string(m)) return m;
  }
  fail(ErrorCode::invalid_argument, "--method",
       "unknown method '" + name + "' (known: auto, lanczos, chebyshev, cholesky, eigen, split, pse)");
}

/// The arguments with `--method pse` expanded (the PSE operator with its split sampler), after the
/// checks of which options apply to which operator.
SampleArgs resolve_operator(const SampleArgs& given) {
  SampleArgs args = given;
  if (args.method == "pse") {
    require(args.op == "direct" || args.op == "pse", ErrorCode::invalid_argument, "--method",
            "pse selects the PSE operator; it cannot be combined with --operator " + args.op);
    args.op = "pse";
    args.method = "split";
  }
  require(args.box.empty() || args.op == "pse", ErrorCode::invalid_argument, "--box",
          "a periodic box needs --operator pse (direct and fmm are free-space operators)");
  require(args.wave_precision == "auto" || args.op == "pse", ErrorCode::invalid_argument, "--wave-precision",
          "applies to the pse operator only");
  const rpy::ComputeDevice device = rpy::compute_device_from_string(args.device, "--device");
  require(device == rpy::ComputeDevice::cpu || args.op == "pse", ErrorCode::invalid_argument, "--device",
          "cuda applies to the pse operator only");
  return args;
}

/// The square-root solver of --method, --sqrt-tolerance, --max-iterations and --preconditioner.
rpy::SqrtOptions sqrt_options_of(const SampleArgs& args) {
  ranges::require_in(ranges::kSolverTolerance, args.sqrt_tolerance, "--sqrt-tolerance", "tolerance");
  rpy::SqrtOptions options;
  options.method = parse_method(args.method);
  options.tolerance = args.sqrt_tolerance;
  options.max_iterations = args.max_iterations;
  require(args.preconditioner == "none" || args.preconditioner == "block" || args.preconditioner == "auto",
          ErrorCode::invalid_argument, "--preconditioner",
          "must be none, block or auto, got '" + args.preconditioner + "'");
  options.preconditioner = rpy::sqrt_preconditioner_from_string(args.preconditioner == "auto" ? std::string("automatic")
                                                                                              : args.preconditioner);
  options.preconditioner_block = args.preconditioner_block;
  const bool krylov = options.method == rpy::SqrtMethod::lanczos || options.method == rpy::SqrtMethod::chebyshev ||
                      (options.method == rpy::SqrtMethod::automatic && args.op != "pse");
  require(options.preconditioner != rpy::SqrtPreconditioner::block || krylov, ErrorCode::invalid_argument,
          "--preconditioner", "block serves the Lanczos and Chebyshev samplers only, not --method " + args.method);
  return options;
}

/// The operator's entry, with --tolerance checked against it.
const OperatorEntry& operator_of(const SampleArgs& args) {
  const OperatorEntry& entry = find_operator(args.op);
  if (args.tolerance != 0.0) {
    require(entry.uses_tolerance, ErrorCode::invalid_argument, "--tolerance",
            "applies to approximate operators only, not to --operator " + args.op);
    ranges::require_in(ranges::kMobilityTolerance, args.tolerance, "--tolerance", "operator tolerance");
  }
  return entry;
}

/// What `sample` reads: positions, radii (unless --radius) and the noise z (translational; with
/// --angular also z_r, rotational).
struct SampleInput {
  std::vector<double> x, radii, z, z_r;
};

SampleInput read_sample_input(const SampleArgs& args, bool radius_given) {
  SampleInput in;
  in.x = as_points(read_array(args.positions), "positions");
  const std::size_t n = in.x.size() / 3;
  if (!radius_given) in.radii = as_vector(read_array(args.radii), n, "radii");
  in.z.resize(3 * n);
  in.z_r.resize(args.angular ? 3 * n : 0);
  if (!args.noise.empty() && args.angular) {
    std::tie(in.z, in.z_r) = as_split_rows6(read_array(args.noise), n, "noise");
  } else if (!args.noise.empty()) {
    in.z = as_points(read_array(args.noise), "noise");
    require(in.z.size() == in.x.size(), ErrorCode::invalid_input, "noise",
            "has " + std::to_string(in.z.size() / 3) + " rows, expected " + std::to_string(n) + " (one per particle)");
  } else {
    rpy::fill_normal(in.z, args.seed, args.step);
    if (args.angular) rpy::fill_normal(in.z_r, args.seed, args.step, bd::kRotationNoiseStream);
  }
  return in;
}

void print_sample_json(const SampleArgs& args, const rpy::MobilityOperator& op, const rpy::SqrtReport& report,
                       std::size_t n, bool radius_given, const StageTimes& stages, double total_seconds) {
  JsonLine line;
  line.add("command", "sample")
      .add("operator", op.name())
      .add("method", rpy::to_string(report.method))
      .add("n", n)
      .add("sqrt_tolerance", args.sqrt_tolerance);
  add_sqrt_report(line, report);
  line.add("angular", args.angular)
      .add("noise", args.noise.empty() ? "philox" : args.noise)
      .add("viscosity", args.viscosity)
      .add("equal_radii", op.equal_radii())
      .add("threads", active_threads())
      .add("simd", simd_level_name(simd_level()))
      .add("out", args.out)
      .add("seconds", stages)
      .add("total_seconds", total_seconds);
  if (args.noise.empty()) {
    line.add("seed", args.seed).add("step", args.step);
  }
  add_chebyshev_bounds(line, report);
  if (radius_given) line.add("radius", args.radius);
  if (args.tolerance != 0.0) line.add("tolerance", args.tolerance);
  std::cout << line.str() << '\n';
}

/// Under MPI: whether this sample runs across the ranks (--operator direct or fmm with Lanczos or
/// Chebyshev, with or without the block preconditioner, or --operator pse with --box and the split
/// sampler on double wave grids on the CPU; with or without --angular); otherwise it runs on one
/// rank only and more ranks are refused.
bool across_ranks(const SampleArgs& args, const rpy::SqrtOptions& options) {
  const rpy::SqrtMethod method = options.method;
  const bool free_space = (args.op == "direct" || args.op == "fmm") &&
                          (method == rpy::SqrtMethod::lanczos || method == rpy::SqrtMethod::chebyshev ||
                           method == rpy::SqrtMethod::automatic);
  const bool pse = args.op == "pse" && !args.box.empty() && args.wave_precision != "single" && args.device == "cpu" &&
                   (method == rpy::SqrtMethod::split || method == rpy::SqrtMethod::automatic) &&
                   options.preconditioner != rpy::SqrtPreconditioner::block;
  const bool supported = free_space || pse;
  require(supported || mpi_size() == 1, ErrorCode::not_supported, "sample",
          "across " + std::to_string(mpi_size()) +
              " MPI ranks runs --operator direct or fmm with --method auto, lanczos or chebyshev, or --operator pse "
              "with --box and --method auto or split (double-precision wave grids, CPU, no --preconditioner block), "
              "with or without --angular (docs/mpi.md); run the others without mpirun");
  return supported;
}

void run_sample(const SampleArgs& given, bool radius_given, bool seed_given) {
  require_distinct_files(
      std::vector<NamedPath>{{"--positions", given.positions}, {"--radii", given.radii}, {"--noise", given.noise}},
      std::vector<NamedPath>{{"--out", given.out}});
  apply_threads(given.common);
  const SampleArgs args = resolve_operator(given);
  // Validate every option before reading or computing anything.
  require(radius_given != !args.radii.empty(), ErrorCode::invalid_argument, "sample",
          "give exactly one of --radius a or --radii R.npy");
  require(!(seed_given && !args.noise.empty()), ErrorCode::invalid_argument, "sample",
          "give at most one of --noise Z.npy or --seed S");
  if (radius_given) ranges::require_in(ranges::kRadius, args.radius, "--radius", "radius");
  ranges::require_in(ranges::kViscosity, args.viscosity, "--viscosity", "viscosity");
  const rpy::SqrtOptions options = sqrt_options_of(args);
  const OperatorEntry& entry = operator_of(args);
  if (under_mpi() && across_ranks(args, options)) {
    run_sample_across_ranks({args.positions, args.radii, args.noise, args.out, args.radius, radius_given,
                             args.viscosity, args.seed, args.step, options, args.common.json, args.op, args.box,
                             args.tolerance, args.angular, args.io});
    return;
  }

  StopWatch total;
  StopWatch watch;
  const SampleInput in = read_sample_input(args, radius_given);
  const std::size_t n = in.x.size() / 3;
  StageTimes stages;
  stages["read"] = watch.seconds();

  watch.restart();
  auto op = entry.make(args);
  require(!args.angular || op->supports_rotation(), ErrorCode::not_supported, "sample",
          "--angular needs an operator with rotation (torques and angular velocities); '" + op->name() + "' has none");
  if (radius_given) {
    op->set_positions(in.x, args.radius);
  } else {
    op->set_positions(in.x, in.radii);
  }
  stages["setup"] = watch.seconds();

  watch.restart();
  std::vector<double> w(3 * n), w_r(args.angular ? 3 * n : 0);
  const rpy::SqrtReport report =
      args.angular ? op->apply_sqrt_rotation(in.z, in.z_r, w, w_r, options) : op->apply_sqrt(in.z, w, options);
  stages["sample"] = watch.seconds();

  watch.restart();
  require_finite_output(w, "sample");
  if (args.angular) {
    require_finite_output(w_r, "sample");
    std::vector<double> rows(6 * n);  // w_t then w_r per particle
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t c = 0; c < 3; ++c) {
        rows[6 * i + c] = w[3 * i + c];
        rows[6 * i + 3 + c] = w_r[3 * i + c];
      }
    write_npy(args.out, {n, 6}, rows);
  } else {
    write_npy(args.out, {n, 3}, w);
  }
  stages["write"] = watch.seconds();

  if (args.common.json) print_sample_json(args, *op, report, n, radius_given, stages, total.seconds());
}

}  // namespace

void register_sample(CLI::App& app) {
  auto args = std::make_shared<SampleArgs>();
  CLI::App* cmd = app.add_subcommand("sample", "Brownian displacements M^{1/2} z of N spheres (RPY mobility)");
  cmd->add_option("--positions", args->positions, "positions, (N,3) .npy or text")->required();
  auto* radius = cmd->add_option("--radius", args->radius, "common sphere radius a, in " + ranges::kRadius.str());
  auto* radii = cmd->add_option("--radii", args->radii, "per-particle radii (N,)");
  radius->excludes(radii);
  auto* noise = cmd->add_option("--noise", args->noise,
                                "noise z, (N,3), or (N,6) z_t then z_r with --angular; default: Philox normals "
                                "from --seed");
  auto* seed = add_integer_option(*cmd, "--seed", args->seed, ranges::kSeed, "seed of the counter-based generator");
  noise->excludes(seed);
  add_integer_option(*cmd, "--step", args->step, ranges::kSeed, "time-step index (generator counter)");
  cmd->add_option("--method", args->method,
                  "auto (operator's choice: Lanczos, or PSE's split sampler), lanczos, chebyshev, cholesky or "
                  "eigen (dense, N <= 2000), split (PSE only); pse = --operator pse --method split")
      ->capture_default_str();
  cmd->add_option("--operator", args->op,
                  "mobility operator: direct, fmm, or pse (periodic with --box, open boundaries without)")
      ->capture_default_str();
  cmd->add_option("--box", args->box, "periodic box for --operator pse: L or Lx Ly Lz")->expected(1, 3);
  add_renamed_option(*cmd, "--sqrt-tolerance", "--tol", args->sqrt_tolerance,
                     "relative tolerance of the square root, in " + ranges::kSolverTolerance.str())
      .option->capture_default_str();
  add_integer_option(*cmd, "--max-iterations", args->max_iterations, ranges::kSqrtIterations,
                     "Lanczos iterations / Chebyshev degree (0 = auto)");
  add_renamed_option(*cmd, "--tolerance", "--eps", args->tolerance,
                     "tolerance of the fmm (default 1e-6) or pse (default 1e-3) operator, in " +
                         ranges::kMobilityTolerance.str() + " (pse: from 1e-8)");
  cmd->add_option("--wave-precision", args->wave_precision,
                  "pse operator: wave-space grids in single or double precision; auto = single for --tolerance >= 1e-5")
      ->capture_default_str();
  cmd->add_option("--device", args->device, "pse operator: cpu, or cuda (on a GPU, in a build with CUDA)")
      ->capture_default_str();
  cmd->add_option("--preconditioner", args->preconditioner,
                  "Lanczos/Chebyshev: none (w = M^{1/2} z), block (w = B z, B B^T = M, fewer products) or auto")
      ->capture_default_str();
  add_integer_option(*cmd, "--preconditioner-block", args->preconditioner_block, ranges::kPreconditionerBlock,
                     "particles per block of the block preconditioner (0 = automatic)");
  cmd->add_option("--viscosity", args->viscosity, "solvent viscosity eta, in " + ranges::kViscosity.str())
      ->capture_default_str();
  cmd->add_flag("--angular", args->angular,
                "sample the grand mobility with rotation (operators with rotation: direct, fmm, pse on the CPU, none): "
                "output (N,6), "
                "displacements then rotations, B z with B B^T = M (docs/theory/samplers.md)");
  cmd->add_option("--out", args->out, "output .npy, shape (N,3), or (N,6) with --angular")->required();
  add_common_options(*cmd, args->common);
  add_io_option(*cmd, args->io);
  cmd->callback([args, radius, seed] {
    print_pending_warnings();
    run_sample(*args, radius->count() > 0, seed->count() > 0);
  });
}

}  // namespace rpyfmm::cli
